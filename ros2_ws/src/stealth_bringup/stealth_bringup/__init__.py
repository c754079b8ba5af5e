"""stealth-nav bringup: a whole run (recorder, simulator, environment, agent) without launch,
and the experiment harness.

`stealth train` and `stealth eval` (orchestrate), which it adds to stealth_tools' `stealth`
command (commands), and `experiments`, the learners trained in-process against the planning
baselines (harness, harness_report). The modules without rclpy (run_plan, run_config,
episode_tracker, run_outputs, supervisor, ros_domain, harness, harness_report) are the
functional core; the node parameter files live in config/.
"""
