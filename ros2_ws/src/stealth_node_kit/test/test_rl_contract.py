"""The RL contract: the profiles each end of the loop uses, and names without rclpy."""

import subprocess
import sys

import pytest
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSCompatibility,
    ReliabilityPolicy,
    qos_check_compatible,
)
from stealth_node_kit import rl_contract


def test_lockstep_topics_are_reliable_volatile_and_bounded():
    qos = rl_contract.LOCKSTEP_QOS
    assert (qos.history, qos.depth) == (HistoryPolicy.KEEP_LAST, rl_contract.LOCKSTEP_DEPTH)
    assert qos.reliability == ReliabilityPolicy.RELIABLE
    assert qos.durability == DurabilityPolicy.VOLATILE


@pytest.mark.parametrize(
    ('writer', 'depth'),
    [
        ('DESCRIPTION_QOS', 1),
        ('OBSERVATION_STREAM_QOS', rl_contract.OBSERVATION_STREAM_HISTORY),
        ('SUMMARY_QOS', rl_contract.SUMMARY_HISTORY),
        ('STEP_INFO_QOS', rl_contract.STEP_HISTORY),
        ('AGENT_EPISODE_INFO_QOS', rl_contract.AGENT_REPORT_HISTORY),
    ],
)
def test_reports_keep_their_latest_messages_for_every_report_reader(writer, depth):
    offered = getattr(rl_contract, writer)
    assert (offered.history, offered.depth) == (HistoryPolicy.KEEP_LAST, depth)
    assert offered.durability == DurabilityPolicy.TRANSIENT_LOCAL
    reader = rl_contract.REPORT_READER_QOS
    assert reader.history == HistoryPolicy.KEEP_ALL
    compatibility, reason = qos_check_compatible(offered, reader)
    # WARNING only for system-default liveliness on both ends (unknown until matched).
    assert compatibility != QoSCompatibility.ERROR, reason


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match='NO_SUCH_QOS'):
        rl_contract.NO_SUCH_QOS  # noqa: B018


def test_the_loop_topics_in_order_and_their_absolute_names():
    assert rl_contract.RL_TOPICS[:2] == (rl_contract.STATE, rl_contract.ACTION)
    assert rl_contract.absolute(rl_contract.ACTION) == '/rl_agent/rl_action'
    assert rl_contract.absolute('/map') == '/map'


def test_the_names_import_without_rclpy():
    """Parameter tables and the recording comparison read the names in processes that do not
    load rclpy; only a profile's first use does."""
    code = (
        'import sys\n'
        'from stealth_node_kit import rl_contract\n'
        'assert rl_contract.STATE and "rclpy" not in sys.modules\n'
        'rl_contract.LOCKSTEP_QOS\n'
        'assert "rclpy" in sys.modules\n'
    )
    subprocess.run([sys.executable, '-c', code], check=True)


def test_the_agents_latched_reader_matches_the_streamed_grids_writer():
    """The agent reads every grid observation as it reads the description (latched, depth 1);
    the sensed phased grids' deeper writer history must still match it."""
    compatibility, reason = qos_check_compatible(
        rl_contract.OBSERVATION_STREAM_QOS, rl_contract.DESCRIPTION_QOS
    )
    assert compatibility != QoSCompatibility.ERROR, reason
