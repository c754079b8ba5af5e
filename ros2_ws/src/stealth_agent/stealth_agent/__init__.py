"""Tabular reinforcement learners (Q-learning, SARSA, Dyna-Q).

Also the agent node speaking the rl_msgs protocol of rl-texplore-ros-pkg.
"""
