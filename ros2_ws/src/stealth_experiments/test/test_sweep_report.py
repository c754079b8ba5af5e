"""A sweep's report states the success criterion its runs settled on (no Ray)."""

from stealth_experiments.sweep_report import best_configurations, markdown, row


def record(seed, settled, status='ok'):
    return {
        'trial': f't{seed}',
        'status': status,
        'settings': {
            'mode': 'gym', 'scenario': 'map1', 'goal': None, 'learner': 'dyna', 'episodes': 100,
            'eval_every': 10, 'slip': 0.0, 'params': {'alpha': 1.0},
        },
        'seed': seed,
        'optimum': 965.9,
        'greedy_return': 965.9,
        'score': 0.99,
        'episodes_to_within': settled,  # sweep_trials' name of episodes to the criterion
        'wall_seconds': 1.0,
        'host': 'h',
        'node': 'n',
        'error': '' if status == 'ok' else 'boom',
    }  # fmt: skip


def test_the_runs_and_the_best_configuration_say_episodes_to_the_criterion():
    records = [record(0, 40), record(1, None), record(2, 60)]
    rows = [row(r, ['alpha']) for r in records]
    assert [r['episodes_to_criterion'] for r in rows] == [40, None, 60]
    (best,) = best_configurations(records)
    assert (best['met_criterion'], best['episodes_to_criterion']) == ('2/3', 50)
    table, best_table = markdown(rows, ['alpha'], [best])
    assert '| episodes to criterion |' in table and '| not in 100 |' in table
    assert '| met criterion | episodes to criterion (median) |' in best_table
    assert '| 2/3 | 50 |' in best_table
