"""stealth-nav tools: what the project needs of ros2cli and rosbag2, which are not on PyPI.

MCAP recording in rosbag2's format, replay, recovery, and the ros2cli-shaped `stealth` command.
The modules without rclpy (interfaces, qos_text, bag_format, bag_reading, bag_recover,
message_yaml, clock_arithmetic, executables) are the functional core; recorder, player and
graph_tools are the thin ROS shell around it, and cli, with a module per command in commands, ties
everything to `stealth <verb>`. Nothing here knows the simulator, the environment or the agent:
other packages add their commands to `stealth` through the entry-point group that cli reads.
"""
