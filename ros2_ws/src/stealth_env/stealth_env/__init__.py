"""The RL environment node of stealth-nav, speaking the rl_msgs protocol (``env_node``): its
robots (the simulator's services or any robot's ``cmd_vel``/``odom``), the RL topics, the scene
it publishes, its messages and parameters. The world model it judges by is ``stealth_core``.

A ROS 2 package through and through: without rclpy, importing it says in one line what to
install instead of failing deep inside the first ROS import.
"""

from importlib.util import find_spec

if find_spec('rclpy') is None:
    raise ImportError(
        'stealth_env is the ROS 2 environment node and needs ROS 2 Jazzy (rclpy): in the '
        'repository, `make setup` and `source scripts/ros_env.sh`; for the world model without '
        'ROS (the Gym environment, planners, generator), `pip install ros2_ws/src/stealth_core`'
    )
