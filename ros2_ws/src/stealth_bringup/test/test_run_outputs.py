"""episodes.csv, summary.json and the two pictures of a run (no ROS)."""

import csv
import dataclasses
import errno
import json
import math
import os

import numpy as np
import pytest
from stealth_bringup import run_outputs
from stealth_bringup.episode_tracker import CSV_FIELDS, SCORE_FIELDS, EpisodeRecord
from stealth_bringup.run_config import RunConfigError
from stealth_bringup.run_outputs import (
    _replace_atomically,
    append_episode,
    moving_average,
    plot_learning_curve,
    plot_path,
    read_episodes_csv,
    replacing,
    write_episodes_csv,
    write_json,
)
from stealth_core.planners import optimal_path
from stealth_node_kit.full_disk import DiskFullError


def record(episode, outcome, greedy=False, reward=-100.0):
    return EpisodeRecord(
        episode=episode,
        outcome=outcome,
        steps=40 + episode,
        total_reward=reward,
        peak_visibility=0.1,
        accumulated_visibility=1.0,
        path_length=20.0,
        final_distance_to_goal=0.3,
        greedy=greedy,
        epsilon=0.0 if greedy else 0.1,
        alpha=0.0 if greedy else 0.3,
        learner_episodes=episode,
        learner_updates=10 * episode,
        table_states=50,
        wall_time=float(episode),
    )


RECORDS = [
    record(0, 'TIMEOUT'),
    record(1, 'DETECTED', reward=-1100.0),
    record(2, 'SUCCESS', greedy=True, reward=980.0),
    record(3, 'SUCCESS', reward=950.0),
    dataclasses.replace(record(4, 'ABORTED', reward=0.0), epsilon=math.nan),
]


def test_moving_average_uses_what_there_is_at_the_start():
    assert np.allclose(moving_average([1, 3, 5, 7], window=2), [1, 2, 4, 6])
    assert moving_average([]).size == 0


def test_episodes_csv_has_a_row_per_episode(tmp_path):
    path = write_episodes_csv(RECORDS, tmp_path / 'episodes.csv')
    rows = list(csv.DictReader(path.open()))
    assert tuple(rows[0]) == CSV_FIELDS
    assert [r['outcome'] for r in rows] == ['TIMEOUT', 'DETECTED', 'SUCCESS', 'SUCCESS', 'ABORTED']
    assert rows[2]['greedy'] == 'True' and rows[4]['epsilon'] == ''


def test_summary_json_is_strict_json(tmp_path):
    path = write_json({'a': math.nan, 'b': [1.0, math.inf], 'c': {'d': 2}}, tmp_path / 's.json')
    assert json.loads(path.read_text()) == {'a': None, 'b': [1.0, None], 'c': {'d': 2}}
    assert 'NaN' not in path.read_text()


def test_the_learning_curve_is_drawn(tmp_path):
    path = plot_learning_curve(
        RECORDS, tmp_path / 'curve.png', 'maze (easy)', streak_start=2, optimal_return=989.6
    )
    assert path.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert plot_learning_curve([], tmp_path / 'none.png', 'x') is None


@pytest.mark.parametrize('scenario_name', ['simple-maze'])
def test_the_path_picture_shows_the_learned_path_and_the_optimum(tmp_path, scenario_name):
    from stealth_core.scenario import load_scenario

    scenario = load_scenario(scenario_name)
    points, result = optimal_path(scenario, 'easy')
    assert result.outcome.name == 'SUCCESS' and len(points) == result.steps + 1
    learned = [tuple(scenario.start[:2]), (1.5, 2.0), (1.5, 2.5)]
    path = plot_path(
        scenario,
        'easy',
        tmp_path / 'path.png',
        learned,
        'learned',
        points,
        'optimum',
        'title',
        cache_dir=tmp_path / 'cache',
    )
    assert path.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert plot_path(scenario, 'easy', tmp_path / 'n.png', None, 'l', None, 'o', 't') is None


def test_episodes_appended_one_by_one_read_back_as_written(tmp_path):
    path = tmp_path / 'episodes.csv'
    for item in RECORDS:
        append_episode(item, path)
    assert path.read_text() == write_episodes_csv(RECORDS, tmp_path / 'whole.csv').read_text()
    back = read_episodes_csv(path)
    assert [r.episode for r in back] == [0, 1, 2, 3, 4] and back[2].greedy is True
    assert math.isnan(back[4].epsilon) and back[1].total_reward == -1100.0
    assert dataclasses.replace(back[0], wall_time=0.0) == dataclasses.replace(
        RECORDS[0], wall_time=0.0
    )


def test_an_unreadable_episodes_csv_names_the_line_and_the_field(tmp_path):
    path = write_episodes_csv(RECORDS, tmp_path / 'episodes.csv')
    path.write_text(path.read_text().replace('\n2,SUCCESS,42', '\nx,SUCCESS,42'))
    with pytest.raises(RunConfigError, match=r'episodes.csv, line 4: episode .x. is not an int'):
        read_episodes_csv(path)
    (tmp_path / 'other.csv').write_text('a,b\n1,2\n')
    with pytest.raises(RunConfigError, match='no column episode, outcome'):
        read_episodes_csv(tmp_path / 'other.csv')


def test_summary_json_is_replaced_whole(tmp_path):
    path = tmp_path / 'summary.json'
    write_json({'episodes': 1}, path)
    write_json({'episodes': 2}, path)
    assert json.loads(path.read_text()) == {'episodes': 2}
    assert [p.name for p in tmp_path.iterdir()] == ['summary.json']  # no partial file left


# --- a full disk ----------------------------------------------------------------------------


def no_space(*args, **kwargs):
    raise OSError(errno.ENOSPC, 'No space left on device')


def test_a_full_disk_keeps_the_old_file_and_leaves_no_partial(tmp_path):
    path = write_json({'episodes': 1}, tmp_path / 'summary.json')

    def half_then_full(stream):
        stream.write('{"episodes": ')
        stream.flush()
        no_space()

    with pytest.raises(DiskFullError, match=r'^the disk is full: could not write .*summary.json'):
        _replace_atomically(path, half_then_full)
    assert json.loads(path.read_text()) == {'episodes': 1}
    assert [p.name for p in tmp_path.iterdir()] == ['summary.json']


def test_a_picture_is_replaced_whole_or_not_at_all(tmp_path):
    path = tmp_path / 'learning_curve.png'
    path.write_bytes(b'the old picture')
    with pytest.raises(DiskFullError, match='learning_curve.png'), replacing(path) as temporary:
        assert temporary.suffix == '.png' and temporary.parent == tmp_path
        temporary.write_bytes(b'half a pic')
        no_space()
    assert path.read_bytes() == b'the old picture'
    assert [p.name for p in tmp_path.iterdir()] == ['learning_curve.png']
    with replacing(path) as temporary:
        temporary.write_bytes(b'the new picture')
    assert path.read_bytes() == b'the new picture'
    assert [p.name for p in tmp_path.iterdir()] == ['learning_curve.png']


def test_a_row_a_full_disk_cuts_short_is_undone(tmp_path, monkeypatch):
    path = tmp_path / 'episodes.csv'
    append_episode(RECORDS[0], path)
    before = path.read_bytes()
    real_write = os.write

    def half_then_full(descriptor, data):  # as the kernel does: part, then ENOSPC
        if len(data) > 10:
            return real_write(descriptor, bytes(data[:10]))
        no_space()

    monkeypatch.setattr(run_outputs.os, 'write', half_then_full)
    with pytest.raises(DiskFullError, match='could not write .*episodes.csv'):
        append_episode(RECORDS[1], path)
    assert path.read_bytes() == before  # the rows written before, never a torn one
    monkeypatch.setattr(run_outputs.os, 'write', no_space)
    with pytest.raises(DiskFullError):
        append_episode(RECORDS[1], tmp_path / 'new.csv')
    assert (tmp_path / 'new.csv').read_bytes() == b''
    monkeypatch.setattr(run_outputs.os, 'write', real_write)
    append_episode(RECORDS[1], path)
    assert [r.episode for r in read_episodes_csv(path)] == [0, 1]


def test_an_episodes_csv_from_before_the_scores_reads_with_them_unknown(tmp_path):
    """A run written before the score columns existed can still be continued (--resume)."""
    path = tmp_path / 'episodes.csv'
    write_episodes_csv([record(0, 'SUCCESS', greedy=True)], path)
    lines = path.read_text().splitlines()
    keep = [k for k, name in enumerate(lines[0].split(',')) if name not in SCORE_FIELDS]
    path.write_text('\n'.join(','.join(line.split(',')[k] for k in keep) for line in lines) + '\n')
    (old,) = read_episodes_csv(path)
    assert old.outcome == 'SUCCESS' and old.lattice_steps == -1 and not old.meets_criterion
    assert math.isnan(old.path_over_optimum)
    scored = dataclasses.replace(
        old, lattice_steps=5, path_over_optimum=1.05, meets_criterion=True
    )
    write_episodes_csv([scored], path)
    (again,) = read_episodes_csv(path)
    assert (again.lattice_steps, again.path_over_optimum, again.meets_criterion) == (5, 1.05, True)
