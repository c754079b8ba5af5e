"""Benchmark: how many messages a second the MCAP recorder keeps up with, and what it loses.

A publisher process blasts COUNT StepInfo messages (the per-step RL record, ~150 bytes of CDR)
as fast as rclpy publishes, reliable with a history as deep as the burst, so DDS never drops
one; the recorder (default settings: zstd chunks closed every 0.5 s or 256 KiB) records them
in a private ROS domain. Reported per compression: publish rate, recording rate (messages over
the span of their log times), messages missing, file size. Then SIGKILL trials: the recorder
is killed during 100 Hz traffic and `bag recover` salvages the file; reported is the span of
messages lost before the kill. And the recorder's CPU per message when messages trickle in one
at a time, as in training (TRICKLE at 1 kHz), taking each as it arrives (batch_period 0) and in
batches (the default): the ratio is what batching saves.
Run: source scripts/ros_env.sh && python bench/bench_recorder.py
"""

from __future__ import annotations

import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import time

from mcap.reader import make_reader

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / 'tests'))
from ros_support import (  # noqa: E402
    REPO_ROOT,
    NodeProcesses,
    remove_orphaned_shm,
    reserved_domain_id,
    shm_segments,
    wait_for_output,
)

COUNT = 20000
KILL_TRIALS = 3
TRICKLE = 5000  # messages, one every millisecond
WAIT = 120.0  # s: how long a process may take to say it is ready (on a loaded machine)
BIN = REPO_ROOT / 'ros2_ws' / 'install' / 'stealth_tools' / 'lib' / 'stealth_tools'

# argv: count (0: endless at 100 Hz), optionally seconds between messages (default: none)
PUBLISHER = """
import sys, time
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.qos import QoSProfile, ReliabilityPolicy
from stealth_interfaces.msg import StepInfo

count = int(sys.argv[1])
period = float(sys.argv[2]) if len(sys.argv) > 2 else (0.01 if count == 0 else 0.0)
rclpy.init()
node = rclpy.create_node('bench_publisher')
publisher = node.create_publisher(
    StepInfo, 'bench', QoSProfile(depth=max(count, 100), reliability=ReliabilityPolicy.RELIABLE))
try:
    while publisher.get_subscription_count() == 0:
        time.sleep(0.05)
    time.sleep(0.5)
    message = StepInfo(state=[1.5, 2.5])
    message.header.frame_id = 'map'
    started = time.monotonic()
    i = 0
    while count == 0 or i < count:
        message.step = i
        publisher.publish(message)
        i += 1
        if period:
            time.sleep(period)
    print(f'published {count} in {time.monotonic() - started:.3f} s', flush=True)
    rclpy.spin(node)
except (KeyboardInterrupt, ExternalShutdownException):
    pass
finally:
    node.destroy_node()
    rclpy.try_shutdown()
"""


def bench_log_times(path: Path) -> list[int]:
    with open(path, 'rb') as stream:
        return [m.log_time for _, _, m in make_reader(stream).iter_messages(topics=['/bench'])]


def throughput(processes: NodeProcesses, work: Path, compression: str, report) -> None:
    output = work / f'throughput_{compression}.mcap'
    recorder = processes.start(
        [str(BIN / 'recorder'), '--ros-args', '-p', f'output:={output}',
         '-p', f'compression:={compression}', '-p', 'topics:=[/bench]'],
        f'recorder_{compression}',
    )  # fmt: skip
    publisher = processes.start_python(PUBLISHER, f'publisher_{compression}', str(COUNT))
    published = wait_for_output(publisher, 'published', WAIT).strip().splitlines()[-1]
    publish_seconds = float(published.split(' in ')[1].split()[0])
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:  # until the recorder has caught up (chunks flushed)
        time.sleep(1.0)
        size = output.stat().st_size
        time.sleep(1.0)
        if output.stat().st_size == size:
            break
    os.killpg(recorder.pid, signal.SIGINT)
    recorder.wait(60)
    times = bench_log_times(output)
    span = (max(times) - min(times)) / 1e9
    publish_rate, record_rate = COUNT / publish_seconds, len(times) / span
    report(
        f'{compression:>5}: published {COUNT} at {publish_rate:,.0f} msg/s; recorded '
        f'{len(times)} at {record_rate:,.0f} msg/s (ratio {record_rate / publish_rate:.2f}, '
        f'missing {COUNT - len(times)}); file {output.stat().st_size / 1024:.0f} KiB'
    )
    os.killpg(publisher.pid, signal.SIGINT)
    publisher.wait(30)
    return {
        f'recorder_{compression}_publish_msgs_per_s': round(publish_rate),
        f'recorder_{compression}_record_msgs_per_s': round(record_rate),
        f'recorder_{compression}_ratio': round(record_rate / publish_rate, 3),
        f'recorder_{compression}_missing': COUNT - len(times),
    }


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process so far (/proc/<pid>/stat)."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def trickle_cpu(processes: NodeProcesses, work: Path, batch_period: float) -> float:
    """The recorder's CPU seconds per message over TRICKLE messages arriving one at a time."""
    output = work / f'trickle_{batch_period:g}.mcap'
    recorder = processes.start(
        [str(BIN / 'recorder'), '--ros-args', '-p', f'output:={output}', '-p', 'topics:=[/bench]',
         '-p', f'batch_period:={batch_period}'],
        f'trickle_recorder_{batch_period:g}',
    )  # fmt: skip
    publisher = processes.start_python(
        PUBLISHER, f'trickle_{batch_period:g}', str(TRICKLE), '0.001'
    )
    wait_for_output(recorder, "Subscribed to topic '/bench'", WAIT)
    before = cpu_seconds(recorder.pid)
    wait_for_output(publisher, 'published', WAIT)
    time.sleep(1.0)  # the last batch is taken
    used = cpu_seconds(recorder.pid) - before
    os.killpg(recorder.pid, signal.SIGINT)
    recorder.wait(60)
    os.killpg(publisher.pid, signal.SIGINT)
    publisher.wait(30)
    recorded = len(bench_log_times(output))
    if recorded != TRICKLE:
        raise RuntimeError(f'batch_period {batch_period}: recorded {recorded} of {TRICKLE}')
    return used / TRICKLE


def kill_trial(processes: NodeProcesses, work: Path, trial: int) -> float:
    output = work / f'killed_{trial}.mcap'
    recorder = processes.start(
        [str(BIN / 'recorder'), '--ros-args', '-p', f'output:={output}', '-p', 'topics:=[/bench]'],
        f'killed_{trial}',
    )
    publisher = processes.start_python(PUBLISHER, f'steady_{trial}', '0')
    wait_for_output(recorder, "Subscribed to topic '/bench'", WAIT)
    time.sleep(2.0 + 0.37 * trial)  # different phases of the 0.5 s chunk cycle
    killed_ns = time.time_ns()
    os.killpg(recorder.pid, signal.SIGKILL)
    recorder.wait(10)
    recovered = work / f'recovered_{trial}.mcap'
    subprocess.run(
        [str(BIN / 'stealth'), 'bag', 'recover', str(output), '-o', str(recovered)],
        env=processes.env,
        check=True,
        capture_output=True,
    )
    os.killpg(publisher.pid, signal.SIGINT)
    publisher.wait(30)
    return (killed_ns - max(bench_log_times(recovered))) / 1e6


def run(report=print) -> dict:
    """Recorder throughput against its publisher, per compression, and the SIGKILL loss."""
    figures = {}
    before = shm_segments()
    with reserved_domain_id() as domain_id, tempfile.TemporaryDirectory() as work_dir:
        work = Path(work_dir)
        processes = NodeProcesses(domain_id, work)
        try:
            report(f'recorder throughput, {COUNT} StepInfo messages in a burst:')
            for compression in ('zstd', 'none'):
                figures.update(throughput(processes, work, compression, report))
            each, batched = (trickle_cpu(processes, work, period) for period in (0.0, 0.05))
            report(
                f'{TRICKLE} messages at 1 kHz, recorder CPU per message: {each * 1e6:.0f} us '
                f'taking each, {batched * 1e6:.0f} us in 0.05 s batches (ratio '
                f'{each / batched:.1f})'
            )
            figures.update(
                recorder_trickle_us_per_msg_each=round(each * 1e6, 1),
                recorder_trickle_us_per_msg_batched=round(batched * 1e6, 1),
                recorder_trickle_batching_ratio=round(each / batched, 2),
            )
            losses = [kill_trial(processes, work, trial) for trial in range(KILL_TRIALS)]
            figures['recorder_sigkill_lost_ms'] = [round(loss) for loss in losses]
            report(
                f'SIGKILL during 100 Hz traffic, {KILL_TRIALS} trials: lost the last '
                + ', '.join(f'{loss:.0f}' for loss in losses)
                + ' ms'
            )
        finally:
            processes.stop_all()
            remove_orphaned_shm(before)  # what the SIGKILLed recorders left
    return figures


if __name__ == '__main__':
    run()
