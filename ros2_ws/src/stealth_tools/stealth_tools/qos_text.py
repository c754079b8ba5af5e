"""QoS profiles as rosbag2 writes them into a bag, and the profiles it derives from them.

rosbag2 stores the publishers' offered profiles of every topic in the channel metadata
`offered_qos_profiles`, as the YAML that yaml-cpp dumps (metadata version 9: policy names as
strings, durations as {sec, nsec}). The recorder subscribes with what every offer satisfies and
the player offers what the recorded publishers offered. Plain data here; rclpy conversion lives
in ros_session.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import yaml

INFINITE_NS = 2**63 - 1  # RMW_DURATION_INFINITE: {sec: 9223372036, nsec: 854775807}
# {sec, nsec} that mean "infinite": the rmw value, and what Foxy-era Fast DDS and Connext reported.
_INFINITIES = {(INFINITE_NS // 10**9, INFINITE_NS % 10**9), (0x7FFFFFFF, 0xFFFFFFFF)}
_INFINITIES.add((0x7FFFFFFF, 0x7FFFFFFF))
# Metadata versions before 9 stored the rmw enum values as integers.
_HISTORY_BY_INT = ('system_default', 'keep_last', 'keep_all', 'unknown')
_RELIABILITY_BY_INT = ('system_default', 'reliable', 'best_effort', 'unknown', 'best_available')
_DURABILITY_BY_INT = ('system_default', 'transient_local', 'volatile', 'unknown', 'best_available')
_LIVELINESS_BY_INT = (
    'system_default',
    'automatic',
    'manual_by_node',
    'manual_by_topic',
    'unknown',
    'best_available',
)
DEFAULT_DEPTH = 10  # rmw_qos_profile_default.depth, rosbag2's fallback
VOLATILE_PLAYBACK_DEPTH = 1000


@dataclass(frozen=True)
class QosDescription:
    """One endpoint's QoS profile, policies by their rmw short names, durations in ns."""

    history: str = 'keep_last'
    depth: int = DEFAULT_DEPTH
    reliability: str = 'reliable'
    durability: str = 'volatile'
    deadline_ns: int = INFINITE_NS
    lifespan_ns: int = INFINITE_NS
    liveliness: str = 'automatic'
    liveliness_lease_duration_ns: int = INFINITE_NS
    avoid_ros_namespace_conventions: bool = False


def _duration_node(nanoseconds: int) -> dict[str, int]:
    return {'sec': nanoseconds // 10**9, 'nsec': nanoseconds % 10**9}


def _duration_ns(node: dict) -> int:
    sec, nsec = int(node['sec']), int(node['nsec'])
    if (sec, nsec) in _INFINITIES:
        return INFINITE_NS
    return sec * 10**9 + nsec


def qos_node(profile: QosDescription) -> dict:
    """The mapping rosbag2 encodes for one profile, keys in its order."""
    return {
        'history': profile.history,
        'depth': profile.depth,
        'reliability': profile.reliability,
        'durability': profile.durability,
        'deadline': _duration_node(profile.deadline_ns),
        'lifespan': _duration_node(profile.lifespan_ns),
        'liveliness': profile.liveliness,
        'liveliness_lease_duration': _duration_node(profile.liveliness_lease_duration_ns),
        'avoid_ros_namespace_conventions': profile.avoid_ros_namespace_conventions,
    }


def offered_qos_yaml(profiles: list[QosDescription]) -> str:
    """The `offered_qos_profiles` channel metadata text, as rosbag2's yaml-cpp dump of it."""
    if not profiles:
        return '[]'
    nodes = [qos_node(p) for p in profiles]
    return yaml.safe_dump(nodes, sort_keys=False, default_flow_style=False).rstrip('\n')


def _policy(value, names_by_int: tuple[str, ...]) -> str:
    if isinstance(value, int) and not isinstance(value, bool):
        return names_by_int[value] if 0 <= value < len(names_by_int) else 'unknown'
    return str(value)


def profile_from_node(node: dict) -> QosDescription:
    """One profile from its YAML mapping (metadata version 9 names or older integers)."""
    return QosDescription(
        history=_policy(node['history'], _HISTORY_BY_INT),
        depth=int(node['depth']),
        reliability=_policy(node['reliability'], _RELIABILITY_BY_INT),
        durability=_policy(node['durability'], _DURABILITY_BY_INT),
        deadline_ns=_duration_ns(node['deadline']),
        lifespan_ns=_duration_ns(node['lifespan']),
        liveliness=_policy(node['liveliness'], _LIVELINESS_BY_INT),
        liveliness_lease_duration_ns=_duration_ns(node['liveliness_lease_duration']),
        avoid_ros_namespace_conventions=bool(node['avoid_ros_namespace_conventions']),
    )


def parse_offered_qos_yaml(text: str) -> list[QosDescription]:
    """The profiles of an `offered_qos_profiles` text; empty text means none were recorded."""
    if not text or not text.strip():
        return []
    nodes = yaml.safe_load(text)
    if not isinstance(nodes, list):
        raise ValueError('offered_qos_profiles is not a YAML sequence')
    return [profile_from_node(node) for node in nodes]


def subscription_policies(offers: list[QosDescription]) -> tuple[str, str]:
    """(reliability, durability) that connect to every offer (rosbag2's adapt_request_to_offers).

    Reliable only if all publishers are, so a best-effort one is still heard; transient local
    only if all are, so latched messages (/map, rl_env/rl_env_description) are received.
    """
    if not offers:
        return 'reliable', 'volatile'
    reliable = all(p.reliability == 'reliable' for p in offers)
    transient_local = all(p.durability == 'transient_local' for p in offers)
    return (
        'reliable' if reliable else 'best_effort',
        'transient_local' if transient_local else 'volatile',
    )


def _compatibility_key(profile: QosDescription) -> tuple:
    return (
        profile.reliability,
        profile.durability,
        profile.deadline_ns,
        profile.liveliness,
        profile.liveliness_lease_duration_ns,
    )


def _playback_history(profile: QosDescription) -> QosDescription:
    """A known history as recorded; discovery reports none (unknown, 0), so choose one.

    Transient local keeps rosbag2's KEEP_LAST 10: late joiners get what they would have got
    from a typical latched publisher. Volatile topics get VOLATILE_PLAYBACK_DEPTH, so a
    reliable replay never overwrites a step its subscribers have not acknowledged yet.
    """
    if profile.history == 'keep_all' or (profile.history == 'keep_last' and profile.depth):
        return profile
    depth = DEFAULT_DEPTH if profile.durability == 'transient_local' else VOLATILE_PLAYBACK_DEPTH
    return replace(profile, history='keep_last', depth=depth)


def playback_profile(offers: list[QosDescription]) -> tuple[QosDescription, bool]:
    """The profile to replay a topic with, and whether the recorded offers agreed.

    rosbag2's adapt_offer_to_recorded_offers (the common offer if all publishers offered
    the same reliability, durability, deadline and liveliness, else the default), with the
    history chosen by _playback_history instead of always KEEP_LAST 10.
    """
    if not offers:
        return _playback_history(QosDescription(history='unknown')), True
    if len({_compatibility_key(p) for p in offers}) == 1:
        return _playback_history(offers[0]), True
    return _playback_history(QosDescription(history='unknown')), False
