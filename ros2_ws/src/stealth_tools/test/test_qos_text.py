"""offered_qos_profiles as rosbag2 writes and reads it; the profiles derived from offers."""

import pytest
from stealth_tools.qos_text import (
    INFINITE_NS,
    VOLATILE_PLAYBACK_DEPTH,
    QosDescription,
    offered_qos_yaml,
    parse_offered_qos_yaml,
    playback_profile,
    subscription_policies,
)

# What rosbag2 (yaml-cpp, metadata version 9) writes for one transient-local publisher.
ROSBAG2_TEXT = """- history: keep_last
  depth: 1
  reliability: reliable
  durability: transient_local
  deadline:
    sec: 9223372036
    nsec: 854775807
  lifespan:
    sec: 9223372036
    nsec: 854775807
  liveliness: automatic
  liveliness_lease_duration:
    sec: 9223372036
    nsec: 854775807
  avoid_ros_namespace_conventions: false"""

LATCHED = QosDescription(depth=1, durability='transient_local')


def test_yaml_text_is_what_rosbag2_writes():
    assert offered_qos_yaml([LATCHED]) == ROSBAG2_TEXT
    assert offered_qos_yaml([]) == '[]'


def test_yaml_round_trips():
    profiles = [LATCHED, QosDescription(reliability='best_effort', deadline_ns=1_500_000_000)]
    assert parse_offered_qos_yaml(offered_qos_yaml(profiles)) == profiles
    assert parse_offered_qos_yaml('') == []


def test_older_bags_with_integer_policies_and_foxy_infinities_are_read():
    text = """- history: 1
  depth: 5
  reliability: 2
  durability: 1
  deadline: {sec: 2147483647, nsec: 4294967295}
  lifespan: {sec: 0, nsec: 0}
  liveliness: 1
  liveliness_lease_duration: {sec: 2147483647, nsec: 2147483647}
  avoid_ros_namespace_conventions: false"""
    (profile,) = parse_offered_qos_yaml(text)
    assert profile == QosDescription(
        history='keep_last',
        depth=5,
        reliability='best_effort',
        durability='transient_local',
        deadline_ns=INFINITE_NS,
        lifespan_ns=0,
        liveliness='automatic',
        liveliness_lease_duration_ns=INFINITE_NS,
    )


@pytest.mark.parametrize(
    ('offers', 'expected'),
    [
        ([], ('reliable', 'volatile')),
        ([LATCHED, LATCHED], ('reliable', 'transient_local')),
        ([LATCHED, QosDescription()], ('reliable', 'volatile')),
        ([LATCHED, QosDescription(reliability='best_effort')], ('best_effort', 'volatile')),
    ],
)
def test_subscription_connects_to_every_offer(offers, expected):
    assert subscription_policies(offers) == expected


def test_playback_offers_what_was_recorded():
    profile, agreed = playback_profile([LATCHED])
    assert agreed and profile == LATCHED


def test_playback_history_when_discovery_reported_none():
    unknown = QosDescription(history='unknown', depth=0)
    profile, _ = playback_profile([unknown])
    assert (profile.history, profile.depth) == ('keep_last', VOLATILE_PLAYBACK_DEPTH)
    latched = QosDescription(history='unknown', depth=0, durability='transient_local')
    profile, _ = playback_profile([latched])
    assert (profile.history, profile.depth, profile.durability) == (
        'keep_last',
        10,
        'transient_local',
    )


def test_playback_falls_back_to_the_default_when_offers_disagree():
    profile, agreed = playback_profile([LATCHED, QosDescription(reliability='best_effort')])
    assert not agreed
    assert (profile.reliability, profile.durability) == ('reliable', 'volatile')
