"""stealth-nav bringup: a whole run (recorder, simulator, environment, agent) without launch.

`stealth train` and `stealth rollout` (orchestrate), which it adds to stealth_tools' `stealth`
command (commands). The modules without rclpy (run_arguments, run_plan, run_resume,
rollout_source, run_config, episode_tracker, run_outputs, supervisor, respawn, remote_nodes,
ros_domain) are the functional core; the node parameter files live in config/.
"""
