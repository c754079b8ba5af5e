"""Tabular reinforcement learners (Q-learning, SARSA, Dyna-Q, prioritized sweeping) and the
light model (a learner that infers the searchlights).

Also the agent node speaking the rl_msgs protocol of rl-texplore-ros-pkg.
"""

# Register their learners with learners.make_learner (they import learners, not the reverse).
from . import light_model, prioritized_sweeping  # noqa: E402, F401
