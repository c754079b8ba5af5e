"""The commands stealth_env adds to stealth_tools' `stealth` command.

setup.py registers COMMANDS in the entry-point group `stealth.commands`, which `stealth` reads
to build its command line (see stealth_bringup's commands); the function is imported only when
its command runs, so `stealth --help` stays fast.
"""

COMMANDS = {
    'render': (
        'stealth_env.render',
        'main',
        'Render a scenario (walls, visibility heatmap, cones, goals, paths) to PNG.',
    ),
    'scenarios': (
        'stealth_env.scenario_commands',
        'main',
        'Generate proven scenarios in generated buildings, and draw contact sheets of them.',
    ),
}
