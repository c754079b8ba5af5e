"""stealth-nav experiments: many runs compared, on top of the running system (stealth_bringup).

`experiments` (`make compare`): the learners trained in-process on the Gymnasium environment
against A*, Dark Path and value iteration (harness, harness_report); `stealth sweep`, which it
adds to stealth_tools' `stealth` command (commands): scenarios x learners x seeds x
hyperparameters on Ray (sweep, sweep_plan, sweep_engine, sweep_trials, sweep_report), each trial
in-process or a `stealth train` run through ROS. No rclpy of its own.
"""
