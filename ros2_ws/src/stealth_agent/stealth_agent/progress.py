"""What the agent tells about its run in its log, as plain Python (no rclpy).

A progress line every log_every episodes (returns, steps, outcome mix, epsilon), a line for
each greedy evaluation episode of a learning run, out-of-range states warned about sparingly
(the first few, then one in a thousand: a scenario that keeps leaving its ranges must not flood
the log), and the totals at exit, where a lost or doubled message would show.
"""

from collections import Counter
from collections.abc import Mapping, Sequence

import numpy as np

from .protocol import EpisodeResult

# Out-of-range states: the first this many are each warned about, then every OUT_OF_RANGE_EVERY.
OUT_OF_RANGE_FIRST = 5
OUT_OF_RANGE_EVERY = 1000


def outcome_mix(results: Sequence[EpisodeResult]) -> Counter:
    """Outcomes told apart by the terminal reward's sign (all the rl_msgs protocol carries)."""
    mix = Counter()
    for result in results:
        if result.aborted:
            mix['aborted'] += 1
        elif result.truncated or result.terminal_reward is None:
            mix['truncated'] += 1
        elif result.terminal_reward > 0:
            mix['positive end'] += 1
        elif result.terminal_reward < 0:
            mix['negative end'] += 1
        else:
            mix['zero end'] += 1
    return mix


def format_progress(
    results: Sequence[EpisodeResult],
    *,
    table_rows: int,
    named_outcomes: Mapping[str, int] | None = None,
) -> str:
    """One log line about a window of episodes: returns, steps, outcome mix, epsilon."""
    if not results:
        return 'no episodes yet'
    returns = np.array([r.reward for r in results], dtype=np.float64)
    steps = np.array([r.actions for r in results], dtype=np.float64)
    mix = named_outcomes if named_outcomes else outcome_mix(results)
    mix_text = ', '.join(f'{name} {count}' for name, count in sorted(mix.items()))
    first, last = results[0], results[-1]
    mode = f'learner total {last.learner_episode + 1}' if last.learning else 'evaluation'
    return (
        f'episodes {first.episode}-{last.episode} ({mode}): '
        f'return mean {returns.mean():.3f} [min {returns.min():.3f}, max {returns.max():.3f}], '
        f'last {last.reward:.3f}; steps mean {steps.mean():.1f}, last {last.actions}; '
        f'outcomes: {mix_text}; epsilon {last.epsilon:.4f}; table {table_rows} states'
    )


class ProgressLog:
    """The agent's log lines about its episodes; each method returns a line to log, or None."""

    def __init__(self):
        self._window: list[EpisodeResult] = []
        self._named_outcomes = Counter()  # the environment's names for the window's outcomes
        self._out_of_range = 0

    def outcome(self, name: str) -> None:
        """The environment named how an episode of the current window ended."""
        self._named_outcomes[name] += 1

    def episode(self, result: EpisodeResult, *, table_rows: int, log_every: int) -> str | None:
        """A finished episode: the progress line when it completes a window of log_every
        (0: never), which then starts afresh."""
        self._window.append(result)
        if not log_every or len(self._window) < log_every:
            return None
        line = format_progress(
            self._window, table_rows=table_rows, named_outcomes=self._named_outcomes
        )
        self._window = []
        self._named_outcomes = Counter()
        return line

    def out_of_range(self, note: str) -> str | None:
        """A state outside the description's ranges: the warning, when this one is told."""
        self._out_of_range += 1
        count = self._out_of_range
        if count <= OUT_OF_RANGE_FIRST or count % OUT_OF_RANGE_EVERY == 0:
            return f'{note} ({count} so far); it gets its own table row'
        return None


def evaluation_line(result: EpisodeResult, reward: float, learner_episodes: int) -> str:
    """A greedy evaluation episode of a learning run (reward: as reported, see
    agent_messages.reported_reward)."""
    return (
        f'greedy evaluation, episode {result.episode} (after {learner_episodes} '
        f'learning episodes): return {reward:.3f} in {result.actions} steps'
    )


def totals_line(
    states_received: int,
    actions_sent: int,
    decision_seconds=(),
    decision_cpu_seconds=(),
    plan_seconds=(),
) -> str:
    """At exit, as the environment logs its own: a lost or doubled message shows here; and the
    decision time per action (from a state's arrival in the node's callback to its action
    published: ``decision_seconds``, one per action, wall time; ``decision_cpu_seconds``, the
    thread's CPU time of the same: wall minus CPU is waiting for a core on a loaded machine;
    bench/bench_generalist_ros.py reads it); and a policy plugin's time to plan on each grid
    observation as it arrives (``plan_seconds``: once on the full track, per new belief on the
    sensed track; not in the decision time, unless a state waited for its grid)."""
    line = f'totals: {states_received} states received, {actions_sent} actions sent'
    if len(decision_seconds):
        ms = np.asarray(decision_seconds, dtype=float) * 1e3
        line += (
            f'; decision time per action: mean {ms.mean():.3f} ms, median '
            f'{np.median(ms):.3f} ms, p95 {np.percentile(ms, 95):.3f} ms, max {ms.max():.3f} ms'
        )
        if len(decision_cpu_seconds):
            cpu = np.asarray(decision_cpu_seconds, dtype=float) * 1e3
            line += f' (CPU mean {cpu.mean():.3f} ms, p95 {np.percentile(cpu, 95):.3f} ms)'
    if len(plan_seconds):
        ms = np.asarray(plan_seconds, dtype=float) * 1e3
        line += (
            f'; {ms.size} grid observations planned on (the first includes compiling): mean '
            f'{ms.mean():.1f} ms, median {np.median(ms):.1f} ms, max {ms.max():.1f} ms'
        )
    return line
