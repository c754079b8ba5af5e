"""stealth-nav bringup: MCAP recording in rosbag2's format, replay, and a ros2cli-shaped CLI.

The modules without rclpy (interfaces, qos_text, bag_format, bag_reading, bag_recover,
message_yaml, timing, executables) are the functional core; recorder, player and graph_tools
are the thin ROS shell around it, and cli ties everything to `stealth <verb>`.
"""
