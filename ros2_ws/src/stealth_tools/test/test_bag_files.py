"""A recording split over several files (a run continued or its recorder restarted): named in
order, read as one bag by info, play and recover (no ROS graph)."""

import time

import pytest
from sample_bags import START_NS, Sample, write_bag
from stealth_tools.bag_files import bag_files, next_recording_file, recording_files
from stealth_tools.bag_format import BagError
from stealth_tools.bag_reading import format_bag_info, read_bag_info


def chatter(first, count, topic='/chatter'):
    return [
        Sample(topic, 'std_msgs/msg/String', {'data': f'{i}'}, START_NS + i * 10_000_000)
        for i in range(first, first + count)
    ]


def test_the_files_of_a_run_are_numbered_as_rosbag2_splits(tmp_path):
    assert recording_files(tmp_path) == []
    assert next_recording_file(tmp_path) == tmp_path / 'recording.mcap'
    for name in ('recording.mcap', 'recording_1.mcap', 'recording_10.mcap', 'recording_2.mcap'):
        write_bag(tmp_path / name, chatter(0, 1))
    (tmp_path / 'policy.npz').write_bytes(b'')
    names = [p.name for p in recording_files(tmp_path)]
    assert names == ['recording.mcap', 'recording_1.mcap', 'recording_2.mcap', 'recording_10.mcap']
    assert next_recording_file(tmp_path) == tmp_path / 'recording_11.mcap'


def test_a_recovered_copy_stands_for_its_file(tmp_path):
    write_bag(tmp_path / 'recording.mcap', chatter(0, 5), close=False)
    write_bag(tmp_path / 'recording.recovered.mcap', chatter(0, 5))
    write_bag(tmp_path / 'recording_1.mcap', chatter(5, 5))
    names = [p.name for p in recording_files(tmp_path)]
    assert names == ['recording.recovered.mcap', 'recording_1.mcap']
    assert [p.name for p in bag_files(tmp_path)] == names
    assert next_recording_file(tmp_path).name == 'recording_2.mcap'


def test_a_split_bag_reads_as_one(tmp_path, monkeypatch):
    write_bag(tmp_path / 'recording.mcap', chatter(0, 20))
    write_bag(tmp_path / 'recording_1.mcap', chatter(20, 10) + chatter(20, 3, '/other'))
    info = read_bag_info(tmp_path)
    assert info.message_count == 33 and info.indexed and not info.unindexed
    assert {t.name: t.count for t in info.topics} == {'/chatter': 30, '/other': 3}
    assert info.start_ns == START_NS and info.end_ns == START_NS + 29 * 10_000_000
    sizes = sum(p.stat().st_size for p in tmp_path.iterdir())
    assert info.size == sizes
    monkeypatch.setenv('TZ', 'UTC')
    time.tzset()
    try:
        text = format_bag_info(info, 'runs/a')
    finally:
        monkeypatch.delenv('TZ')
        time.tzset()
    assert (
        'Files:             runs/a/recording.mcap\n' + ' ' * 19 + 'runs/a/recording_1.mcap\n'
        in text
    )
    assert 'Messages:          33\n' in text


def test_an_unclosed_file_of_a_split_bag_is_named(tmp_path):
    write_bag(tmp_path / 'recording.mcap', chatter(0, 20))
    write_bag(tmp_path / 'recording_1.mcap', chatter(20, 10), close=False)
    info = read_bag_info(tmp_path)
    assert not info.indexed and info.unindexed == (tmp_path / 'recording_1.mcap',)


def test_a_directory_of_several_recordings_is_refused(tmp_path):
    write_bag(tmp_path / 'recording.mcap', chatter(0, 1))
    write_bag(tmp_path / 'other.mcap', chatter(0, 1))
    with pytest.raises(BagError, match='files of several recordings .other.mcap, recording.mcap'):
        bag_files(tmp_path)
