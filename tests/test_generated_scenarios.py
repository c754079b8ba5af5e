"""System test: a scenario made by `stealth scenarios generate` trains through ROS."""

import csv
import json

from test_system import system  # noqa: F401 - the fixture: stealth commands, nothing left over


def test_a_generated_scenario_trains_through_ros(system, tmp_path):  # noqa: F811
    generated = system.run(
        'scenarios', 'generate', '--seed', '11', '--out', str(tmp_path / 'gen'),
        '--width', '20', '--height', '20', '--lights', '3',
    )  # fmt: skip
    assert generated.returncode == 0, generated.stderr
    scenario = tmp_path / 'gen' / 'gen-0000011.yaml'
    assert scenario.is_file() and (tmp_path / 'gen' / 'maps' / 'gen-0000011.pgm').is_file()
    result = system.run(
        'train', '--scenario', str(scenario), '--episodes', '2', '--no-record', timeout=400
    )
    assert result.returncode == 0, result.stderr
    (run,) = (tmp_path / 'runs').iterdir()
    summary = json.loads((run / 'summary.json').read_text())
    assert summary['episodes'] >= 2, summary  # the budget's episodes ran, greedy ones too
    assert 'gen-0000011' in json.dumps(summary)
    # Every episode scored on the lattice: no step was built before the monitor could read it.
    with (run / 'episodes.csv').open() as rows:
        scored = [int(row['lattice_steps']) >= 0 for row in csv.DictReader(rows)]
    assert len(scored) == summary['episodes'] and all(scored), scored


def test_the_harness_trains_on_a_generated_scenario(tmp_path):
    from stealth_core.scenario_generator import Options, generate
    from stealth_experiments.harness import RunSpec, run

    path = generate(12, Options(width=20, height=20, lights=2)).write(tmp_path)
    result = run(RunSpec(str(path), 'qlearning', seed=0, episodes=4, eval_every=2))
    assert result.optimum > 0 and len(result.train_returns) == 4
