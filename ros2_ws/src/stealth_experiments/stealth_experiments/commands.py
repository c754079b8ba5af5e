"""The commands stealth_experiments adds to stealth_tools' `stealth` command.

setup.py registers COMMANDS in the entry-point group `stealth.commands`, which `stealth` reads
to build its command line (see stealth_bringup's commands); the function is imported only when
its command runs, so `stealth --help` stays fast.
"""

COMMANDS = {
    'sweep': (
        'stealth_experiments.sweep',
        'main',
        'Sweep learners x scenarios x seeds x hyperparameters on Ray (local or a cluster).',
    ),
    'benchmark': (
        'stealth_experiments.benchmark',
        'main',
        'Benchmark planners, replanners, learners and a policy on a test set, both tracks.',
    ),
    'generalist': (
        'stealth_experiments.generalist_benchmark',
        'main',
        'Evaluate the generalist beside the oracle, its hand-set and untrained twins and the '
        'replanners.',
    ),
}
