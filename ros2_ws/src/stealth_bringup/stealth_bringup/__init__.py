"""stealth-nav bringup: a whole run (recorder, simulator, environment, agent) without launch.

`stealth train` and `stealth eval` (orchestrate), which it adds to stealth_tools' `stealth`
command, and the experiment harness; the node parameter files live in config/. The modules
without rclpy (run_plan, run_config, experiment, run_outputs, supervisor, ros_domain) are the
functional core.
"""
