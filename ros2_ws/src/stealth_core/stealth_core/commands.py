"""The commands stealth_core adds to stealth_tools' `stealth` command (where it is installed).

setup.py registers COMMANDS in the entry-point group `stealth.commands`, which `stealth` reads
to build its command line (see stealth_bringup's commands); the function is imported only when
its command runs, so `stealth --help` stays fast.
"""

COMMANDS = {
    'render': (
        'stealth_core.render',
        'main',
        'Render a scenario (walls, visibility heatmap, cones, goals, paths) to PNG.',
    ),
    'scenarios': (
        'stealth_core.scenario_commands',
        'main',
        'Generate proven scenarios in generated buildings, and draw contact sheets of them.',
    ),
}
