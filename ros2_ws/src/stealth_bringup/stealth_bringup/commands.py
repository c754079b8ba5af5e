"""The commands stealth_bringup adds to stealth_tools' `stealth` command.

setup.py registers COMMANDS in the entry-point group `stealth.commands`, which `stealth` reads
to build its command line (as ros2cli's extension points add verbs), so the tools below need
not import anything of this package. Each function takes the command's argv; it is imported
only when its command runs, so `stealth --help` stays fast.
"""

COMMANDS = {
    'train': (
        'stealth_bringup.orchestrate',
        'train_main',
        'Train the agent on a scenario: start the system, record it, save the policy.',
    ),
    'rollout': (
        'stealth_bringup.orchestrate',
        'rollout_main',
        "Run a saved policy's greedy episodes through ROS, without learning.",
    ),
    'eval': (
        'stealth_bringup.orchestrate',
        'eval_main',
        'The old name of `stealth rollout` (says so on stderr, then runs it).',
    ),
    'doctor': (
        'stealth_bringup.doctor',
        'main',
        'Check and tidy what earlier runs left: /dev/shm files, domains, processes, the build.',
    ),
}
