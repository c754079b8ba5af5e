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
    'eval': (
        'stealth_bringup.orchestrate',
        'eval_main',
        'Evaluate a saved policy on a scenario without learning.',
    ),
    'render': (
        'stealth_env.render',
        'main',
        'Render a scenario (walls, visibility heatmap, cones, goals, paths) to PNG.',
    ),
    'sweep': (
        'stealth_bringup.sweep',
        'main',
        'Sweep learners x scenarios x seeds x hyperparameters on Ray (local or a cluster).',
    ),
    'doctor': (
        'stealth_bringup.doctor',
        'main',
        'Check and tidy what earlier runs left: /dev/shm files, domains, processes, the build.',
    ),
}
