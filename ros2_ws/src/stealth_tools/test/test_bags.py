"""Writing bags in rosbag2's MCAP layout, reading their info, recovering truncated ones."""

import os
import time

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import pytest
from sample_bags import (
    START_NS,
    FakeClock,
    Sample,
    chatter_samples,
    encoder,
    odometry_sample,
    write_bag,
)
from stealth_tools.bag_format import BagError
from stealth_tools.bag_reading import format_bag_info, open_indexed_reader, read_bag_info
from stealth_tools.bag_recover import recover
from stealth_tools.interfaces import definition_text
from stealth_tools.qos_text import parse_offered_qos_yaml
import yaml


def decoded(path):
    """(topic, log time, decoded message) of every message, via mcap_ros2's decoder."""
    with open(path, 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        return [
            (channel.topic, message.log_time, ros)
            for _, channel, message, ros in reader.iter_decoded_messages()
        ]


def raw_messages(path):
    """(topic, log time, publish time, CDR bytes) of every message."""
    with open(path, 'rb') as stream:
        return [
            (channel.topic, message.log_time, message.publish_time, bytes(message.data))
            for _, channel, message in make_reader(stream).iter_messages()
        ]


def summary_of(path):
    with open(path, 'rb') as stream:
        return make_reader(stream).get_summary()


def rosbag2_metadata(path) -> list[dict]:
    with open(path, 'rb') as stream:
        return [
            yaml.safe_load(record.metadata['serialized_metadata'])
            for record in make_reader(stream).iter_metadata()
            if record.name == 'rosbag2'
        ]


def mixed_samples():
    chatter = chatter_samples(20)
    odometry = [odometry_sample(i, START_NS + 50_000_000 + i * 200_000_000) for i in range(5)]
    latched = Sample(
        '/rl_env/rl_env_description',
        'stealth_interfaces/msg/RLEnvDescription',
        {'num_actions': 4.0, 'min_state_range': [0.0, 0.0], 'title': 'lgfloor'},
        START_NS,
    )
    return sorted([latched, *chatter, *odometry], key=lambda s: s.log_time)


def test_bag_is_laid_out_as_rosbag2s_mcap_storage(tmp_path):
    path = tmp_path / 'run.mcap'
    write_bag(path, mixed_samples())
    with open(path, 'rb') as stream:
        reader = make_reader(stream)
        assert reader.get_header().profile == 'ros2'
        summary = reader.get_summary()
    assert summary.statistics.message_count == 26
    assert summary.chunk_indexes and all(c.message_index_offsets for c in summary.chunk_indexes)
    assert all(c.compression == 'zstd' for c in summary.chunk_indexes)
    schemas = {s.name: s for s in summary.schemas.values()}
    assert schemas['nav_msgs/msg/Odometry'].encoding == 'ros2msg'
    odometry_text = schemas['nav_msgs/msg/Odometry'].data.decode()
    assert odometry_text == definition_text('nav_msgs/msg/Odometry')
    channels = {c.topic: c for c in summary.channels.values()}
    assert {c.message_encoding for c in channels.values()} == {'cdr'}
    (latched,) = parse_offered_qos_yaml(
        channels['/rl_env/rl_env_description'].metadata['offered_qos_profiles']
    )
    assert latched.durability == 'transient_local'
    assert channels['/chatter'].metadata['topic_type_hash'].startswith('RIHS01_')


def test_every_message_decodes_back(tmp_path):
    path = tmp_path / 'run.mcap'
    write_bag(path, mixed_samples())
    messages = decoded(path)
    chatter = [m.data for topic, _, m in messages if topic == '/chatter']
    assert chatter == [f'hello {i}' for i in range(20)]
    odometry = [m for topic, _, m in messages if topic == '/odom']
    assert [m.pose.pose.position.x for m in odometry] == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert odometry[0].header.frame_id == 'odom'
    (description,) = [m for topic, _, m in messages if topic == '/rl_env/rl_env_description']
    assert description.title == 'lgfloor'


def test_rosbag2_metadata_is_written_at_open_and_close(tmp_path):
    path = tmp_path / 'run.mcap'
    write_bag(path, mixed_samples())
    first, last = rosbag2_metadata(path)
    assert first['message_count'] == 0 and first['topics_with_message_count'] == []
    assert last['version'] == 9 and last['storage_identifier'] == 'mcap'
    assert last['message_count'] == 26
    assert last['starting_time']['nanoseconds_since_epoch'] == START_NS
    assert last['duration']['nanoseconds'] == 19 * 100_000_000
    counts = {
        t['topic_metadata']['name']: t['message_count'] for t in last['topics_with_message_count']
    }
    assert counts == {'/rl_env/rl_env_description': 1, '/chatter': 20, '/odom': 5}
    assert last['relative_file_paths'] == ['run.mcap']


def test_a_bag_directory_gets_metadata_yaml(tmp_path):
    write_bag(tmp_path / 'run', chatter_samples(3))
    assert sorted(p.name for p in (tmp_path / 'run').iterdir()) == ['metadata.yaml', 'run_0.mcap']
    metadata = yaml.safe_load((tmp_path / 'run' / 'metadata.yaml').read_text())
    info = metadata['rosbag2_bagfile_information']
    assert info['relative_file_paths'] == ['run_0.mcap'] and info['message_count'] == 3
    assert read_bag_info(tmp_path / 'run').message_count == 3


def test_existing_output_is_never_overwritten(tmp_path):
    (tmp_path / 'run.mcap').write_bytes(b'precious')
    with pytest.raises(BagError, match='already exists'):
        write_bag(tmp_path / 'run.mcap', chatter_samples(1))
    with pytest.raises(BagError, match='cannot create'):
        write_bag(tmp_path / 'missing_dir' / 'run.mcap', chatter_samples(1))


def test_chunks_are_closed_once_they_are_old(tmp_path):
    """What a SIGKILL loses is bounded by max_chunk_duration, not by the chunk size."""
    clock = FakeClock()
    path = tmp_path / 'run.mcap'
    writer = write_bag(path, [], close=False, clock=clock, max_chunk_duration=0.5)
    writer.add_topic('/chatter', 'std_msgs/msg/String', definition_text('std_msgs/msg/String'), [])
    for i in range(10):
        writer.write('/chatter', b'\x00\x01\x00\x00\x01\x00\x00\x00\x00', START_NS + i, 0)
        clock.now += 0.2  # the write that finds the chunk 0.5 s old closes it: 4 a chunk
    size_before_quiet = path.stat().st_size
    clock.now += 1.0
    writer.flush_if_due()  # the timer's job when no message comes
    assert path.stat().st_size > size_before_quiet
    writer.close()
    chunks = summary_of(path).chunk_indexes
    assert [c.message_end_time - c.message_start_time + 1 for c in chunks] == [4, 4, 2]


def test_info_text_is_ros2_bag_infos(tmp_path, monkeypatch):
    monkeypatch.setenv('TZ', 'UTC')
    time.tzset()
    try:
        write_bag(tmp_path / 'run.mcap', mixed_samples(), ros_distro='jazzy')
        info = read_bag_info(tmp_path / 'run.mcap')
        text = format_bag_info(info, 'run.mcap')
    finally:
        monkeypatch.delenv('TZ')
        time.tzset()
    size = (tmp_path / 'run.mcap').stat().st_size
    pad = ' ' * 19
    assert text == (
        '\n'
        'Files:             run.mcap\n'
        f'Bag size:          {size / 1024:.1f} KiB\n'
        'Storage id:        mcap\n'
        'ROS Distro:        jazzy\n'
        'Duration:          1.900000000s\n'
        'Start:             Nov 14 2023 22:13:20.000000000 (1700000000.000000000)\n'
        'End:               Nov 14 2023 22:13:21.900000000 (1700000001.900000000)\n'
        'Messages:          26\n'
        'Topic information: Topic: /rl_env/rl_env_description | Type: '
        'stealth_interfaces/msg/RLEnvDescription | Count: 1 | Serialization Format: cdr\n'
        f'{pad}Topic: /chatter | Type: std_msgs/msg/String | Count: 20 | '
        'Serialization Format: cdr\n'
        f'{pad}Topic: /odom | Type: nav_msgs/msg/Odometry | Count: 5 | '
        'Serialization Format: cdr\n'
        'Service:           0\n'
        'Service information: \n'
    )


def test_bad_bag_paths_say_why(tmp_path):
    with pytest.raises(BagError, match='no such file'):
        read_bag_info(tmp_path / 'missing.mcap')
    (tmp_path / 'notes.txt').write_text('not a bag')
    with pytest.raises(BagError, match='not an MCAP file'):
        read_bag_info(tmp_path / 'notes.txt')
    (tmp_path / 'empty_dir').mkdir()
    with pytest.raises(BagError, match='without an .mcap'):
        read_bag_info(tmp_path / 'empty_dir')


# --- recovery ------------------------------------------------------------------------------


def many_samples(count=600):
    """Chatter every 10 ms, with a long-ish payload so it spans several 4 KiB chunks."""
    return [
        Sample(
            '/chatter',
            'std_msgs/msg/String',
            {'data': f'{i:06d} ' + 'x' * 100},
            START_NS + i * 10_000_000,
        )
        for i in range(count)
    ]


def assert_complete_and_indexed(path):
    summary = summary_of(path)
    assert summary is not None and summary.statistics is not None
    assert summary.chunk_indexes and all(c.message_index_offsets for c in summary.chunk_indexes)
    return summary


def chatter_numbers(path) -> list[int]:
    return [int(m.data.split()[0]) for topic, _, m in decoded(path) if topic == '/chatter']


def test_recovering_a_complete_file_keeps_everything(tmp_path):
    write_bag(tmp_path / 'run.mcap', mixed_samples())
    output, report = recover(tmp_path / 'run.mcap')
    assert output == tmp_path / 'run.recovered.mcap'
    assert report.salvage.complete and report.messages == 26
    assert_complete_and_indexed(output)
    assert raw_messages(output) == raw_messages(tmp_path / 'run.mcap')
    assert len(rosbag2_metadata(output)) == 2


def test_a_recording_left_open_is_recovered_up_to_its_last_chunk(tmp_path):
    """As after SIGKILL: the writer never finished, the last chunk was flushed by age."""
    clock = FakeClock()
    writer = write_bag(
        tmp_path / 'killed.mcap', [], close=False, clock=clock, max_chunk_duration=0.5
    )
    samples = many_samples(300)
    encode = encoder('std_msgs/msg/String')
    writer.add_topic('/chatter', 'std_msgs/msg/String', definition_text('std_msgs/msg/String'), [])
    for sample in samples:
        writer.write('/chatter', encode(sample.fields), sample.log_time, sample.log_time)
        clock.now += 0.01
    # Killed here: whatever the last age-based flush wrote is on disk, the rest is lost.
    with open(tmp_path / 'killed.mcap', 'rb') as stream, pytest.raises(BagError):
        open_indexed_reader(stream)
    output, report = recover(tmp_path / 'killed.mcap', tmp_path / 'out.mcap')
    assert not report.salvage.complete
    assert_complete_and_indexed(output)
    numbers = chatter_numbers(output)
    assert numbers == list(range(len(numbers)))
    assert len(numbers) >= 300 - 0.5 / 0.01 - 1  # at most max_chunk_duration of messages lost


@pytest.mark.parametrize('compression', ['zstd', 'lz4', 'none'])
@pytest.mark.parametrize('cut_fraction', [0.3, 0.55, 0.8, 0.97])
def test_truncated_files_are_recovered_to_a_gapless_prefix(tmp_path, compression, cut_fraction):
    source = tmp_path / 'run.mcap'
    write_bag(source, many_samples(), compression=compression, chunk_size=4096, clock=FakeClock())
    data = source.read_bytes()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(data[: int(len(data) * cut_fraction)])
    info = read_bag_info(cut)
    assert not info.indexed and info.message_count > 0
    output, report = recover(cut, compression=compression)
    assert_complete_and_indexed(output)
    numbers = chatter_numbers(output)
    assert numbers == list(range(len(numbers)))  # a prefix, in order, nothing skipped
    assert report.messages == len(numbers) == info.message_count
    # The cut loses at most the part of the file after the cut, give or take one chunk.
    assert len(numbers) >= 600 * cut_fraction - 60


def test_a_chunk_cut_in_the_middle_still_gives_its_complete_messages(tmp_path):
    source = tmp_path / 'run.mcap'
    write_bag(source, many_samples(200), compression='none', chunk_size=1 << 20, clock=FakeClock())
    data = source.read_bytes()
    with open(source, 'rb') as stream:
        (chunk,) = make_reader(stream).get_summary().chunk_indexes
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(data[: chunk.chunk_start_offset + chunk.chunk_length // 2])
    output, report = recover(cut)
    assert 80 <= report.messages < 200
    assert report.salvage.cut_chunk_records >= report.messages
    assert chatter_numbers(output) == list(range(report.messages))


def test_recover_refuses_to_overwrite_and_rejects_non_mcap(tmp_path):
    write_bag(tmp_path / 'run.mcap', chatter_samples(2))
    (tmp_path / 'run.recovered.mcap').write_bytes(b'x')
    with pytest.raises(BagError, match='already exists'):
        recover(tmp_path / 'run.mcap')
    (tmp_path / 'notes.txt').write_text('hello')
    with pytest.raises(BagError, match='not an MCAP file'):
        recover(tmp_path / 'notes.txt', tmp_path / 'x.mcap')
    assert not (tmp_path / 'x.mcap').exists()
    os.truncate(tmp_path / 'run.mcap', 4)
    with pytest.raises(BagError, match='not an MCAP file'):
        recover(tmp_path / 'run.mcap', tmp_path / 'y.mcap')
