"""What a run leaves and says when it ends: the files (episodes.csv, the pictures and
summary.json, written through run_outputs) and the closing lines, from the facts the process
lifecycle gathered (RunFacts). No rclpy.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
from pathlib import Path
import time

from stealth_core.path_scores import Criterion, PathScores, describe
from stealth_node_kit.full_disk import EXIT_DISK_FULL, DiskFullError
from stealth_tools.bag_files import recording_files

from stealth_bringup.episode_scores import EpisodeScorer
from stealth_bringup.episode_tracker import EpisodeRecord, Tracker
from stealth_bringup.run_arguments import prog_of
from stealth_bringup.run_config import RunConfigError, relative_to_cwd
from stealth_bringup.run_plan import RunPlan

FRAMES_SAID_EVERY = 5.0  # s: how often drawing path.gif says how far it is


@dataclasses.dataclass
class RunFacts:
    """What orchestrating a run found out, for its report."""

    started: float  # monotonic s at the command's start
    status: str = 'failed'  # success, budget, interrupted or failed
    message: str = ''
    exit_code: int = 1
    startup_seconds: float = math.nan
    training_started: float | None = None  # when the orchestrator began following episodes
    stopped_at: float | None = None
    released: float | None = None  # when the environment could begin its first episode
    episode_ends: dict[int, float] = dataclasses.field(default_factory=dict)  # sent, by episode
    domain_id: int | None = None
    nodes: dict = dataclasses.field(default_factory=dict)  # supervised nodes by name
    node_exits: dict[str, str] = dataclasses.field(default_factory=dict)
    node_cpu: dict[str, float | None] = dataclasses.field(default_factory=dict)  # CPU s used
    paths: dict[int, list] = dataclasses.field(default_factory=dict)  # true (x, y) by episode
    late: list[dict] = dataclasses.field(default_factory=list)  # summaries after the end
    remote: dict[str, dict] = dataclasses.field(default_factory=dict)  # --remote nodes' summary
    restarts: list[dict] = dataclasses.field(default_factory=list)  # respawn.Restart.as_dict()
    disk_full: str = ''  # the line of the first write a full disk refused (the run stopped)
    incomplete: dict[Path, str] = dataclasses.field(default_factory=dict)  # file: what is amiss

    def stepping_seconds(self) -> float:
        """How long the episodes ran: from when the environment could begin (unheld, episodes
        run while the orchestrator still checks the nodes' parameters, before it follows them)
        to the last episode's end (else the stop, else now); 0 before that."""
        starts = [t for t in (self.released, self.training_started) if t is not None]
        if not starts:
            return 0.0
        end = max(self.episode_ends.values(), default=None) or self.stopped_at or time.monotonic()
        return max(0.0, end - min(starts))

    def steps_per_second(self, records) -> float | None:
        """The rate `records` (this command's episodes) were stepped at: between the ends of
        the first and the last whose summary's sending time is known, which holds however late
        the orchestrator took the reports in; else over stepping_seconds."""
        timed = sorted((self.episode_ends[r.episode], r.steps) for r in records
                       if r.episode in self.episode_ends)  # fmt: skip
        if len(timed) >= 2 and timed[-1][0] > timed[0][0]:
            return sum(steps for _, steps in timed[1:]) / (timed[-1][0] - timed[0][0])
        seconds = self.stepping_seconds()
        return sum(r.steps for r in records) / seconds if seconds > 0 and records else None


class RunReport:
    """The outputs of one run; `say` prints a line above the progress bar."""

    def __init__(self, plan: RunPlan, tracker: Tracker, facts: RunFacts, say):
        self.plan, self.tracker, self.facts, self.say = plan, tracker, facts, say
        self.prog = prog_of(plan.mode)

    def _policy_check(self) -> dict:
        """Where the policy is and, after training, whether it is the one last evaluated."""
        plan = self.plan
        info = {'path': relative_to_cwd(plan.policy_path)}
        if plan.mode != 'train':
            return info
        from stealth_agent.policy_store import PolicyFileError, load_policy

        if not plan.policy_path.is_file():
            info['saved'] = False
            return info
        try:
            saved = load_policy(plan.policy_path)
        except PolicyFileError as error:
            info.update(saved=False, error=str(error))
            return info
        info.update(
            saved=True,
            learner=saved.learner.name,
            episodes=saved.learner.episodes,
            updates=saved.learner.updates,
            states=len(saved.index),
        )
        last = self.tracker.last_greedy()
        if last is not None and last.learner_updates >= 0:
            info['as_last_evaluated'] = saved.learner.updates == last.learner_updates
            info['updates_since_last_evaluation'] = saved.learner.updates - last.learner_updates
        return info

    def write_progress(self) -> Path:
        """summary.json as the run stands (status 'running'), rewritten atomically: what a
        killed orchestrator leaves besides episodes.csv (no pictures: --resume draws them)."""
        from stealth_bringup.run_outputs import write_json

        records = sorted(self.tracker.records, key=lambda r: r.episode)
        summary = self._summary(records, None, self._existing_files(), status='running')
        return write_json(summary, self.plan.file('summary.json'))

    def _existing_files(self) -> dict[str, Path]:
        """The run's files that exist besides the pictures, summary.json and episodes.csv."""
        plan = self.plan
        files = {}
        recordings = recording_files(plan.directory)
        if recordings:  # several: the run directory reads as all of them (stealth bag ...)
            files['recording'] = recordings[0] if len(recordings) == 1 else plan.directory
        if plan.file('policy.npz').exists():
            files['policy'] = plan.file('policy.npz')
        files['params'] = plan.file('params')
        files['logs'] = plan.file('logs')
        return files

    def write(self) -> dict[str, Path]:
        """Every output file of the run, written; {key: path} of what exists afterwards."""
        from stealth_bringup.run_outputs import plot_learning_curve, plot_path

        plan, tracker, facts = self.plan, self.tracker, self.facts
        files = {}
        records = sorted(tracker.records, key=lambda r: r.episode)
        try:
            scorer = tracker.scorer or EpisodeScorer(plan.scenario, plan.goal, plan.criterion)
            optimum = scorer.optimum  # value iteration's path on the lattice
            optimum_points = optimum.points
        except Exception as error:  # noqa: BLE001 - a baseline must not cost the run its outputs
            self.say(f'{self.prog}: no value-iteration baseline: {error}')
            optimum_points, optimum = None, None
        if records:
            self._episodes_csv(records, files)
        if records and plan.mode == 'train':
            agent = plan.parameters['agent'].values
            title = f'{plan.title}: {agent.get("agent", "qlearning")}, {len(records)} episodes'
            curve = self._fitting(
                plot_learning_curve,
                records,
                plan.file('learning_curve.png'),
                title,
                streak_start=tracker.streak_start if facts.status == 'success' else None,
                optimal_return=None if optimum is None else optimum.total_reward,
            )
            if curve is not None:
                files['learning_curve'] = curve
        shown = tracker.last_greedy() or (records[-1] if records else None)
        learned = None
        if shown is not None and shown.episode in facts.paths:
            start = plan.scenario.start[:2]
            learned = [tuple(start), *facts.paths[shown.episode]]
        if shown is not None:
            label = path_label(shown, self.plan.criterion)
            optimum_label = (
                'value-iteration optimum on the lattice'
                if optimum is None
                else f'optimum on the lattice: {describe(PathScores.of_path(optimum))}'
            )
            try:
                picture = self._fitting(
                    plot_path,
                    plan.scenario,
                    plan.goal,
                    plan.file('path.png'),
                    learned,
                    label,
                    optimum_points,
                    optimum_label,
                    f'{plan.title}: the learned path (true pose) and the optimum',
                )
            except Exception as error:  # noqa: BLE001
                self.say(f'{self.prog}: could not draw path.png: {error}')
                picture = None
            if picture is not None:
                files['path'] = picture
            if getattr(plan.scenario, 'has_moving_lights', False):
                animation = self._animate(plan, learned, label, optimum_points, optimum_label)
                if animation is not None:
                    files['path_animation'] = animation
        belief = self._belief_picture() if plan.mode == 'train' else None
        if belief is not None:
            files['light_belief'] = belief
        files.update(self._existing_files())
        self._nodes_incomplete()
        summary = self._summary(records, optimum, files)
        written = {k: Path(v) for k, v in files.items()}
        try:
            self._write_summary(summary)
        except DiskFullError as error:
            self._refused(error)
            self._say_files(summary)
        else:
            written['summary'] = plan.file('summary.json')
        return written

    def _belief_picture(self) -> Path | None:
        """light_belief.png of a light-model run's saved belief (None for other learners)."""
        from stealth_bringup.belief_picture import plot_light_belief

        plan = self.plan
        title = f'{plan.title}: what light-model believes'
        try:
            return self._fitting(plot_light_belief, plan.scenario, plan.goal, plan.policy_path,
                                 plan.file('light_belief.png'), title)  # fmt: skip
        except FileNotFoundError:  # no policy saved: nothing to draw
            return None
        except Exception as error:  # noqa: BLE001 - a picture must not cost the run its outputs
            self.say(f'{self.prog}: could not draw light_belief.png: {error}')
            return None

    def _write_summary(self, summary: dict) -> None:
        """The final summary.json. Replacing the one written as the run went needs room for
        both: on a full disk the old one (status 'running', out of date) goes first, then the
        final one is tried again (DiskFullError if it does not fit either)."""
        from stealth_bringup.run_outputs import write_json

        path = self.plan.file('summary.json')
        try:
            write_json(summary, path)
        except DiskFullError:
            if not path.is_file():
                raise
            path.unlink()
            write_json(summary, path)

    def _refused(self, error: DiskFullError) -> None:
        """A file a full disk refused: noted as incomplete; the first such is the run's end
        (its one line said, exit EXIT_DISK_FULL)."""
        facts = self.facts
        facts.incomplete[error.path] = 'not written: the disk is full'
        if not facts.disk_full:
            facts.disk_full = str(error)
            facts.status, facts.message, facts.exit_code = 'failed', str(error), EXIT_DISK_FULL
            self.say(f'{self.prog}: {error}')

    def _fitting(self, write, *args, **kwargs):
        """write(*args, **kwargs) of a file that a full disk may refuse: then None (noted)."""
        try:
            return write(*args, **kwargs)
        except DiskFullError as error:
            self._refused(error)
            return None

    def _episodes_csv(self, records, files: dict) -> None:
        """episodes.csv rewritten whole; on a full disk the rows appended during the run stay
        (the file is only ever replaced by a complete one), counted as incomplete if short."""
        from stealth_bringup.run_outputs import read_episodes_csv, write_episodes_csv

        path = self.plan.file('episodes.csv')
        if self._fitting(write_episodes_csv, records, path) is not None:
            files['episodes'] = path
            return
        self.facts.incomplete.pop(path, None)
        if not path.is_file():
            return
        files['episodes'] = path
        try:
            kept = len(read_episodes_csv(path))
        except RunConfigError:
            kept = 0
        if kept < len(records):
            self.facts.incomplete[path] = f'{kept} of {len(records)} episodes: the disk is full'

    def _nodes_incomplete(self) -> None:
        """The files of nodes that stopped on a full disk: the policy saved before is kept, the
        recording is cut short."""
        plan, facts = self.plan, self.facts
        stopped = {
            name for name, node in facts.nodes.items()
            if node.process.returncode == EXIT_DISK_FULL
        }  # fmt: skip
        if 'agent' in stopped and plan.mode == 'train':
            what = 'not saved: the disk is full'
            if plan.policy_path.is_file():
                what = 'the last save failed (the disk is full): it holds the one saved before'
            facts.incomplete[plan.policy_path] = what
        recordings = recording_files(plan.directory)
        if 'recorder' in stopped and recordings:
            facts.incomplete.setdefault(recordings[-1], 'cut short: the disk is full')

    def _say_files(self, summary: dict) -> None:
        """summary.json could not be written: which files are complete, on the console."""
        shown = relative_to_cwd(self.plan.file('summary.json'))
        complete = ', '.join(n for n in summary['complete_files'] if n != shown) or 'none'
        self.say(f'{self.prog}: summary.json not written either; complete files: {complete}')
        for name, why in summary['incomplete_files'].items():
            self.say(f'  {name}: {why}')

    def _animate(self, plan, learned, label, optimum_points, optimum_label) -> Path | None:
        """path.gif: the lights moving with the learned path and the optimum, step by step."""
        from stealth_core.render import animate_scenario

        from stealth_bringup.run_outputs import replacing

        shown = ((learned, label), (optimum_points, optimum_label))
        paths = [(points, name) for points, name in shown if points is not None]
        frames = None  # a learned path that loops to the step limit: twice the optimum's steps
        if optimum_points is not None:
            frames = min(max(len(points) for points, _ in paths), 2 * len(optimum_points))
        try:
            with replacing(plan.file('path.gif')) as temporary:
                animate_scenario(
                    plan.scenario,
                    temporary,
                    [p for p, _ in paths],
                    [name for _, name in paths],
                    goal=plan.goal,
                    frames=frames,
                    progress=self._frames_said(),
                )
            return plan.file('path.gif')
        except DiskFullError as error:
            self._refused(error)
            return None
        except Exception as error:  # noqa: BLE001
            self.say(f'{self.prog}: could not draw path.gif: {error}')
            return None

    def _frames_said(self, every: float = FRAMES_SAID_EVERY):
        """animate_scenario's progress: a line every `every` s of drawing (none for a short
        one), and the frames and time at the end of one that had any."""
        started = last = time.monotonic()

        def said(done: int, total: int) -> None:
            nonlocal last
            now = time.monotonic()
            if now - last >= every or (done == total and last > started):
                last = now
                self.say(f'{self.prog}: path.gif: {done}/{total} frames in {now - started:.0f} s')

        return said

    def _summary(self, records, optimum, files, status: str | None = None) -> dict:
        plan, tracker, facts = self.plan, self.tracker, self.facts
        agent = plan.parameters['agent'].values
        training = [r for r in records if not r.greedy]
        greedy = [r for r in records if r.greedy]
        steps = sum(r.steps for r in records)
        first = plan.continued.first_episode if plan.continued is not None else 0
        run_seconds = facts.stepping_seconds()
        rate = facts.steps_per_second([r for r in records if r.episode >= first])
        last = tracker.last_greedy()
        seeds = {
            node: plan.parameters[node].values.get('seed')
            for node in ('simulator', 'environment', 'agent')
        }
        learner_keys = (
            'agent', 'gamma', 'alpha', 'epsilon', 'n', 'initialvalue', 'epsilon_schedule',
            'epsilon_final', 'epsilon_decay_episodes', 'alpha_schedule', 'alpha_final',
            'alpha_decay_episodes',
        )  # fmt: skip
        status = status or facts.status
        message = facts.message if status == facts.status else f'{len(records)} episodes so far'
        summary = {
            'status': status,
            'message': message,
            'mode': plan.mode,
            'command': plan.command_line,
            # Each part of a run continued with --resume: its command, episodes and ending.
            'parts': [*self._earlier_parts(), self._this_part(records, status, message)],
            'scenario': {
                'name': plan.scenario.name,
                'path': str(Path(plan.scenario.path).resolve()),
                'map': str(Path(plan.scenario.map_path).resolve()),
                **plan.hashes,
            },
            'goal': plan.goal,
            'seeds': seeds,
            'learner': {k: agent[k] for k in learner_keys if k in agent},
            'simulator': {
                k: plan.parameters['simulator'].values.get(k)
                for k in ('real_time_factor', 'particles', 'physics_dt')
            },
            'episode_budget': plan.episodes,
            'eval_every': plan.eval_every,
            'success_streak': plan.streak,
            'episodes': len(records),
            'training_episodes': len(training),
            'greedy_episodes': len(greedy),
            'steps': steps,
            'outcomes': tracker.outcome_counts(records),
            'success_rate': _rate(records),
            'training_success_rate': _rate(training),
            'greedy_success_rate': _rate(greedy),
            'streak': {
                'length': tracker.streak,
                'began_at_episode': tracker.streak_start,
                'first_success_episode': next((r.episode for r in records if r.success), None),
            },
            'final_greedy': None if last is None else last.brief(),
            # Episodes that ended after the end criterion, before the nodes were stopped (or
            # that the stop cut short: ABORTED): in the recording, not counted here.
            'not_counted': [
                {'episode': f['episode'], 'outcome': f['outcome'], 'steps': f['steps']}
                for f in facts.late
            ],
            'optimum_on_lattice': None
            if optimum is None
            else {
                'outcome': optimum.outcome.name if optimum.outcome is not None else None,
                'return': optimum.total_reward,
                'steps': optimum.steps,
                'path_length': optimum.path_length,
                'peak_visibility': optimum.peak_visibility,
                'accumulated_visibility': optimum.accumulated_visibility,
            },
            # The success criterion greedy episodes are judged by (and the streak counts).
            'criterion': {
                'max_path_ratio': plan.criterion.max_path_ratio,
                'exposure_tolerance': plan.criterion.exposure_tolerance,
                'text': plan.criterion.describe(),
            },
            'greedy_criterion_rate': _rate(greedy, 'meets_criterion'),
            # From the command's start to now (nodes stopped, pictures drawn).
            'wall_time_s': round(time.monotonic() - facts.started, 2),
            'startup_s': round(facts.startup_seconds, 2)
            if math.isfinite(facts.startup_seconds)
            else None,
            'run_s': round(run_seconds, 2),
            'steps_per_s': None if rate is None else round(rate, 2),
            'ros_domain_id': facts.domain_id,
            'discovery': plan.discovery,
            # --compose: the simulator ran in the environment's process (nodes.environment).
            'composed': plan.composed,
            'policy': self._policy_check(),
            'nodes': {
                name: {
                    'command': node.command,
                    'exit': facts.node_exits.get(name, ''),
                    'cpu_s': facts.node_cpu.get(name),
                    'log': relative_to_cwd(node.log_path),
                }
                for name, node in facts.nodes.items()
            },
            # Nodes on other hosts: the command printed for them and what the graph showed.
            'remote_nodes': facts.remote,
            # Each restart of a node that died (--respawn): cause, when, what it cost.
            'restarts': facts.restarts,
            'files': {key: relative_to_cwd(value) for key, value in files.items()},
        }
        summary['files']['summary'] = relative_to_cwd(plan.file('summary.json'))
        # After a full disk: which files hold everything, and what the others miss.
        incomplete = {relative_to_cwd(path): why for path, why in facts.incomplete.items()}
        if facts.disk_full and 'logs' in summary['files']:  # written as the disk filled
            incomplete.setdefault(summary['files']['logs'], 'may miss lines: the disk is full')
        summary['complete_files'] = [
            name
            for name in summary['files'].values()
            if isinstance(name, str) and name not in incomplete
        ]
        summary['incomplete_files'] = incomplete
        if 'recording' in files:
            summary['files']['recording_files'] = [
                relative_to_cwd(path) for path in recording_files(plan.directory)
            ]
        return summary

    def _earlier_parts(self) -> list[dict]:
        continued = self.plan.continued
        if continued is None:
            return []
        parts = continued.summary.get('parts')
        if isinstance(parts, list):
            return parts
        saved = continued.summary  # a run written before parts were kept: its one part
        return [{key: saved.get(key) for key in ('command', 'status', 'message', 'wall_time_s')}]

    def _this_part(self, records, status: str, message: str) -> dict:
        first = self.plan.continued.first_episode if self.plan.continued is not None else 0
        mine = [r.episode for r in records if r.episode >= first]
        return {
            'command': self.plan.command_line,
            'status': status,
            'message': message,
            'episodes': [first, max(mine)] if mine else [],
            'wall_time_s': round(time.monotonic() - self.facts.started, 2),
        }

    def print_closing(self, files: dict[str, Path], out) -> None:
        """The closing lines on `out`: how it ended, the episodes, the files, what to do next."""
        plan, tracker, facts = self.plan, self.tracker, self.facts
        records = tracker.records
        lines = []
        elapsed = time.monotonic() - facts.started
        verdict = {'success': 'done', 'budget': 'done', 'interrupted': 'stopped'}.get(facts.status)
        if facts.status != 'failed':  # a failure's one line is on stderr already
            lines.append(f'{self.prog}: {verdict} after {_duration(elapsed)}: {facts.message}')
        if records:
            counts = tracker.outcome_counts()
            mix = ', '.join(f'{k.lower()} {v}' for k, v in counts.items() if v)
            steps = sum(r.steps for r in records)
            first = plan.continued.first_episode if plan.continued is not None else 0
            per_second = facts.steps_per_second([r for r in records if r.episode >= first])
            rate = '' if per_second is None else f' at {per_second:.0f}/s'
            greedy = sum(r.greedy for r in records)
            lines.append(
                f'  {len(records)} episodes ({len(records) - greedy} training, {greedy} greedy): '
                f'{mix}; {steps} steps{rate}'
            )
            last = tracker.last_greedy()
            if last is not None:
                lines.append(
                    f'  last greedy episode {last.episode}: {last.outcome.lower()} in '
                    f'{last.steps} steps, return {last.total_reward:.1f}, path '
                    f'{last.path_length:.1f} m, peak visibility {last.peak_visibility:.3f}'
                )
                lines.append(f'    {criterion_line(last, plan.criterion)}')
        for restart in facts.restarts:
            back = restart['back_after']
            lines.append(
                f'  restarted {restart["node"]} after episode {restart["episode"]}'
                + (f', back in {back:.1f} s' if back is not None else '')
                + f': {restart["cause"]}'
            )
        directory = relative_to_cwd(plan.directory)
        lines.append(f'Files in {directory}/:')
        described = (
            ('recording', 'recording.mcap', 'every topic of the run (MCAP, rosbag2 layout)'),
            ('policy', 'policy.npz', 'the learned Q-table with its settings (resumable)'),
            ('summary', 'summary.json', 'settings, outcomes, timings, file list'),
            ('episodes', 'episodes.csv', 'one row per episode'),
            ('learning_curve', 'learning_curve.png', 'return per episode, outcomes, epsilon'),
            ('path', 'path.png', 'the learned path over the scenario, with the optimum'),
            ('path_animation', 'path.gif', 'the same as the lights move, step by step'),
            ('light_belief', 'light_belief.png', "light-model's belief beside the true field"),
            ('params', 'params/', 'the parameter file each node ran with'),
            ('logs', 'logs/', "each node's log"),
        )
        for key, name, what in described:
            if key in files and files[key].exists():
                lines.append(f'  {name:<20}{what}')
        recordings = recording_files(plan.directory)
        if len(recordings) > 1:
            lines.append(f'  {"recording_<n>.mcap":<20}its continuation: one more file per part')
        if 'recording' in files and files['recording'].exists():
            bag = relative_to_cwd(files['recording'])
            lines.append(f'Replay:    stealth bag play {bag}   (details: stealth bag info {bag})')
        if plan.mode == 'train' and 'policy' in files and records and facts.status != 'failed':
            lines.append(f'Evaluate:  stealth rollout --run {directory}')
        with contextlib.suppress(OSError, ValueError):
            print('\n'.join(lines), file=out, flush=True)


def _rate(records, what: str = 'success') -> float | None:
    return sum(getattr(r, what) for r in records) / len(records) if records else None


def _verdict(record: EpisodeRecord) -> str:
    return 'meets the criterion' if record.meets_criterion else 'does not meet the criterion'


def path_label(record: EpisodeRecord, criterion: Criterion) -> str:
    """path.png's legend line of the learned path: the true pose's figures, then the lattice
    path's against the optimum's and the verdict."""
    kind = 'greedy' if record.greedy else 'last'
    text = (
        f'learned: {kind} episode {record.episode}, true pose ({record.outcome.lower()}, '
        f'{record.steps} steps, {record.path_length:.1f} m)'
    )
    if record.lattice_steps < 0:
        return text + '; lattice scores unknown'
    return (
        f'{text};\non the lattice: {record.lattice_path_length:.1f} m '
        f'({record.path_over_optimum:.2f}x), exposure {record.lattice_accumulated_visibility:.2f} '
        f'({record.exposure_over_optimum:+.2f}): {_verdict(record)} ({criterion.short()})'
    )


def criterion_line(record: EpisodeRecord, criterion: Criterion) -> str:
    """The closing lines' verdict on the last greedy episode."""
    if record.lattice_steps < 0:
        return 'on the lattice: scores unknown (steps missing)'
    return (
        f"on the lattice: path {record.path_over_optimum:.2f}x the optimum's, exposure "
        f"{record.exposure_over_optimum:+.3f} against it (true pose's path "
        f'{record.true_path_over_optimum:.2f}x): {_verdict(record)} ({criterion.short()})'
    )


def _duration(seconds: float) -> str:
    if seconds < 60:
        return f'{seconds:.1f} s'
    minutes, rest = divmod(int(round(seconds)), 60)
    return f'{minutes} min {rest:02d} s'
