"""The run's private domain id and the clean-up of a killed node's shared memory (no ROS)."""

import itertools
import os

from stealth_bringup import ros_domain
from stealth_bringup.ros_domain import (
    dead_shm_files,
    private_environment,
    remove_dead_shm,
    remove_orphaned_shm,
    reserved_domain_id,
    segment_base,
)


def test_domain_ids_are_exclusive_while_held(tmp_path):
    with reserved_domain_id(tmp_path) as first, reserved_domain_id(tmp_path) as second:
        assert first != second and 1 <= first <= 101 and 1 <= second <= 101
    with reserved_domain_id(tmp_path) as again:
        assert 1 <= again <= 101


def test_the_node_environment_is_private_and_local(monkeypatch):
    monkeypatch.setenv('ROS_LOCALHOST_ONLY', '1')
    env = private_environment(42)
    assert env['ROS_DOMAIN_ID'] == '42'
    assert env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
    assert 'ROS_LOCALHOST_ONLY' not in env and env['PYTHONUNBUFFERED'] == '1'
    assert os.environ['ROS_LOCALHOST_ONLY'] == '1'  # the orchestrator's own is left alone


def test_only_new_unmapped_segments_are_removed_with_their_lock_files(tmp_path, monkeypatch):
    monkeypatch.setattr(ros_domain, 'clean_shm', lambda: None)
    names = ('fastrtps_old', 'fastrtps_dead', 'fastrtps_dead_el', 'sem.fastrtps_dead_mutex',
             'fastrtps_live', 'fastrtps_live_el', 'sem.fastrtps_live_mutex', 'other')  # fmt: skip
    before = {'fastrtps_old'}
    for name in names:
        (tmp_path / name).write_bytes(b'')
    monkeypatch.setattr(ros_domain, 'mapped_shm_names', lambda: {'fastrtps_live'})
    removed = remove_orphaned_shm(before, tmp_path)
    assert removed == ['fastrtps_dead', 'fastrtps_dead_el', 'sem.fastrtps_dead_mutex']
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        'fastrtps_live',
        'fastrtps_live_el',
        'fastrtps_old',
        'other',
        'sem.fastrtps_live_mutex',
    ]
    assert segment_base('sem.fastrtps_port7411_mutex') == 'fastrtps_port7411'


def test_files_of_dead_processes_are_removed_when_twice_unmapped(tmp_path, monkeypatch):
    monkeypatch.setattr(ros_domain, 'clean_shm', lambda: None)
    looks = itertools.cycle([{'fastrtps_live'}, {'fastrtps_live', 'fastrtps_new'}])
    monkeypatch.setattr(ros_domain, 'mapped_shm_names', lambda: next(looks))
    names = ('fastrtps_dead', 'fastrtps_dead_el', 'sem.fastrtps_dead_mutex', 'fastrtps_live',
             'sem.fastrtps_live_mutex', 'fastrtps_new', 'other')  # fmt: skip
    for name in names:
        (tmp_path / name).write_bytes(b'')
    # fastrtps_new was unmapped at the first look only: a participant mapping its new segment.
    dead = ['fastrtps_dead', 'fastrtps_dead_el', 'sem.fastrtps_dead_mutex']
    assert dead_shm_files(tmp_path, confirm=0) == dead
    assert remove_dead_shm(tmp_path, confirm=0) == dead
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        'fastrtps_live',
        'fastrtps_new',
        'other',
        'sem.fastrtps_live_mutex',
    ]


def test_doctor_names_the_node_and_run_of_a_process_and_both_of_a_composed_one():
    from stealth_bringup.doctor import run_node_of

    params = '/work/runs/r1/params'
    single = f'/ws/lib/stealth_agent/agent_node --ros-args --params-file {params}/agent.yaml'
    assert run_node_of(single) == ('agent', '/work/runs/r1')
    composed = (
        f'/ws/lib/stealth_bringup/sim_env --ros-args --params-file {params}/simulator.yaml '
        f'--params-file {params}/environment.yaml -p start_delay:=0.5'
    )
    assert run_node_of(composed) == ('simulator and environment', '/work/runs/r1')
    assert run_node_of('python other.py --params-file /tmp/params/mine.yaml') is None
