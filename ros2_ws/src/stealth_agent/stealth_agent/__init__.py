"""Tabular reinforcement learners (Q-learning, SARSA, Dyna-Q, prioritized sweeping).

Also the agent node speaking the rl_msgs protocol of rl-texplore-ros-pkg.
"""

# Registers its learner with learners.make_learner (it imports learners, not the reverse).
from . import prioritized_sweeping  # noqa: E402, F401
