"""Respawn decisions and records (no ROS)."""

from stealth_bringup.respawn import RESPAWN_DELAYS, RespawnPolicy


def test_restarts_are_bounded_per_node_with_growing_delays():
    policy = RespawnPolicy(2)
    assert policy.refusal('agent', -9) == ''
    first = policy.begin('agent', 'agent was killed by SIGKILL', episode=4, died_at=20.0)
    assert (first.number, first.delay, first.episode) == (1, RESPAWN_DELAYS[0], 4)
    assert policy.delay('agent') == RESPAWN_DELAYS[1]
    policy.begin('agent', 'again', episode=5, died_at=30.0)
    assert policy.refusal('agent', 1) == (
        'not restarted again: it already was 2 times (--respawn 2)'
    )
    assert policy.refusal('simulator', 1) == ''  # counted per node
    assert [r.as_dict()['node'] for r in policy.restarts] == ['agent', 'agent']


def test_what_is_never_restarted():
    assert RespawnPolicy(0).refusal('agent', 1) == 'not restarted (--respawn 0)'
    policy = RespawnPolicy(3, never=('agent',))
    assert policy.refusal('agent', 1) == 'not restarted: it does not run on this host'
    # Exit code 2: the node said it cannot start with these parameters; they have not changed.
    assert policy.refusal('simulator', 2) == 'not restarted: it cannot start with these parameters'
    # Its file would not fit the next time either (stealth_node_kit.full_disk.EXIT_DISK_FULL).
    assert policy.refusal('recorder', 4) == 'not restarted: the disk is full'


def test_the_delay_stops_growing():
    policy = RespawnPolicy(100)
    for _ in range(len(RESPAWN_DELAYS) + 3):
        policy.begin('recorder', 'x', 0, 0.0)
    assert policy.delay('recorder') == RESPAWN_DELAYS[-1]


def test_only_deaths_within_the_dds_lease_may_still_linger_on_the_graph():
    policy = RespawnPolicy(5)
    policy.begin('agent', 'killed', episode=1, died_at=10.0)
    policy.begin('agent', 'killed', episode=2, died_at=50.0)
    policy.begin('simulator', 'killed', episode=2, died_at=55.0)
    assert policy.died_recently('agent', 60.0) == 1
    assert policy.died_recently('agent', 30.0) == 2
    assert policy.died_recently('agent', 100.0) == 0
