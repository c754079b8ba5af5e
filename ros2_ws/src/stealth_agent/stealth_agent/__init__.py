"""Tabular reinforcement learners (Q-learning, SARSA, Dyna-Q, prioritized sweeping).

Also the agent node speaking the rl_msgs protocol of rl-texplore-ros-pkg.
"""
