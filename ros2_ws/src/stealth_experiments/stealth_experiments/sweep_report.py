"""A sweep's results in one directory, kept as trials end (so a stopped sweep can be resumed) and
summarised at the end. No rclpy, no Ray.

    DIR/sweep.yaml              the sweep file as given (what --resume reruns)
    DIR/sweep_base.txt          the directory its relative scenario paths are relative to,
                                then the sweep's name
    DIR/status.json             complete, failed (every run) or interrupted (by which signal),
                                and how many of the sweep's trials are done and failed
    DIR/trials/<trial>.json     each finished trial's records (sweep_trials), one per seed
    DIR/policies/<trial>-seed<k>.npz   each run's final policy (stealth_agent policy file)
    DIR/results.csv             one row per run: settings, parameters, episodes until every
                                greedy evaluation meets the success criterion
                                (stealth_core.path_scores), final greedy return / optimum,
                                score, wall time, host
    DIR/results.md              headed by the status line (complete, failed, interrupted); the
                                same as a table, the best configuration per scenario, curves
    DIR/curves_<scenario>.png   greedy return against episodes, each learner's best configuration
                                (mean over seeds with a min-max band; harness_report.plot_curves)
"""

from __future__ import annotations

import base64
from collections.abc import Iterable
import json
from pathlib import Path

from matplotlib.figure import Figure
import numpy as np
from stealth_bringup.run_outputs import write_csv, write_json
from stealth_core.path_scores import DEFAULT_CRITERION

from stealth_experiments.harness import scenario_label
from stealth_experiments.harness_report import plot_curves
from stealth_experiments.sweep_trials import record_result, replace_spec

BASE_FIELDS = (
    'trial', 'status', 'mode', 'scenario', 'goal', 'learner', 'seed', 'episodes', 'eval_every',
    'slip',
)  # fmt: skip
RESULT_FIELDS = (
    'optimal_return', 'greedy_return', 'greedy_over_optimum', 'score',
    'episodes_to_criterion', 'wall_seconds', 'host', 'node', 'error',
)  # fmt: skip


class SweepStore:
    """The directory of one sweep: records as they come, what is done, the final report."""

    def __init__(self, out: Path):
        self.out = Path(out)
        self.trials_dir = self.out / 'trials'
        self.policies_dir = self.out / 'policies'

    def add(self, records: list[dict]) -> None:
        """Keep a trial's records (its policies as files beside them)."""
        if not records:
            return
        self.trials_dir.mkdir(parents=True, exist_ok=True)
        kept = []
        for record in records:
            record = dict(record)
            encoded = record.pop('policy', None)
            if encoded:
                self.policies_dir.mkdir(parents=True, exist_ok=True)
                path = self.policies_dir / f'{record["trial"]}-seed{record["seed"]}.npz'
                path.write_bytes(base64.b64decode(encoded))
                record['policy_file'] = str(path.relative_to(self.out))
            kept.append(record)
        write_json({'records': kept}, self.trials_dir / f'{records[0]["trial"]}.json')

    def records(self) -> list[dict]:
        found = []
        for path in sorted(self.trials_dir.glob('*.json')):
            found += json.loads(path.read_text(encoding='utf-8'))['records']
        return found

    def finished(self) -> set[str]:
        """Ids of trials whose every run succeeded (failed ones run again on --resume)."""
        by_trial: dict[str, list[dict]] = {}
        for record in self.records():
            by_trial.setdefault(record['trial'], []).append(record)
        return {t for t, rs in by_trial.items() if all(r['status'] == 'ok' for r in rs)}


def row(record: dict, param_names: Iterable[str]) -> dict:
    settings = record['settings']
    ok = record['status'] == 'ok'
    optimum = record.get('optimum')
    return {
        'trial': record['trial'],
        'status': record['status'],
        'mode': settings['mode'],
        'scenario': scenario_label(settings['scenario']),
        'goal': settings['goal'] or '',
        'learner': settings['learner'],
        'seed': record['seed'],
        'episodes': settings['episodes'],
        'eval_every': settings['eval_every'],
        'slip': settings['slip'],
        **{name: settings['params'].get(name, '') for name in param_names},
        'optimal_return': optimum if ok else '',
        'greedy_return': record['greedy_return'] if ok else '',
        'greedy_over_optimum': record['greedy_return'] / optimum if ok else '',
        'score': record['score'] if ok else '',
        'episodes_to_criterion': _episodes_to_criterion(record) if ok else '',
        'wall_seconds': record.get('wall_seconds'),
        'host': record.get('host', ''),
        'node': (record.get('node') or '')[:12],
        'error': record.get('error', ''),
    }


def _episodes_to_criterion(record: dict) -> int | None:
    """A run's episodes until every greedy evaluation met the success criterion (sweep_trials
    keeps it under the record's older name)."""
    return record.get('episodes_to_criterion', record.get('episodes_to_within'))


def _config_key(record: dict) -> tuple:
    s = record['settings']
    return (scenario_label(s['scenario']), s['goal'] or '', s['mode'], s['learner'],
            json.dumps(s['params'], sort_keys=True))  # fmt: skip


def _params_text(params: dict) -> str:
    return (
        ', '.join(f'{k} {v:g}' if isinstance(v, float) else f'{k} {v}' for k, v in params.items())
        or 'harness defaults'
    )


def best_configurations(records: list[dict]) -> list[dict]:
    """Per scenario (and goal): the configuration with the highest mean score over its seeds."""
    groups: dict[tuple, list[dict]] = {}
    for record in records:
        if record['status'] == 'ok':
            groups.setdefault(_config_key(record), []).append(record)
    best: dict[tuple, dict] = {}
    for key, runs in groups.items():
        scores = [r['score'] for r in runs]
        reached = [_episodes_to_criterion(r) for r in runs]
        reached = [episodes for episodes in reached if episodes is not None]
        candidate = {
            'scenario': key[0],
            'goal': key[1],
            'mode': key[2],
            'learner': key[3],
            'params': runs[0]['settings']['params'],
            'seeds': len(runs),
            'score': float(np.mean(scores)),
            'of_optimum': float(np.mean([r['greedy_return'] / r['optimum'] for r in runs])),
            'met_criterion': f'{len(reached)}/{len(runs)}',
            'episodes_to_criterion': int(np.median(reached)) if reached else None,
        }
        where = key[:2]
        if where not in best or candidate['score'] > best[where]['score']:
            best[where] = candidate
    return list(best.values())


def markdown(rows: list[dict], param_names: list[str], best: list[dict]) -> str:
    columns = ['trial', 'status', 'mode', 'scenario', 'learner', 'seed', *param_names,
               'episodes to criterion', 'greedy / optimum', 'wall (s)', 'host',
               'node']  # fmt: skip
    lines = ['| ' + ' | '.join(columns) + ' |', '|' + ' --- |' * len(columns)]
    for r in rows:
        ok = r['status'] == 'ok'
        within = r['episodes_to_criterion']
        cells = [
            r['trial'], r['status'] if ok else f'failed: {r["error"]}', r['mode'], r['scenario'],
            r['learner'], str(r['seed']), *(str(r[name]) for name in param_names),
            (f'not in {r["episodes"]}' if within is None else str(within)) if ok else '',
            f'{r["greedy_over_optimum"]:.3f}' if ok else '',
            '' if r['wall_seconds'] is None else f'{r["wall_seconds"]:.1f}', r['host'],
            r['node'][:8],
        ]  # fmt: skip
        lines.append('| ' + ' | '.join(cells) + ' |')
    table = '\n'.join(lines)
    best_lines = [
        '| scenario | best configuration | seeds | score | greedy / optimum | met criterion '
        '| episodes to criterion (median) |',
        '| --- | --- | --- | --- | --- | --- | --- |',
    ]
    for b in best:
        goal = f' ({b["goal"]})' if b['goal'] else ''
        best_lines.append(
            f'| {b["scenario"]}{goal} | {b["learner"]} ({b["mode"]}): {_params_text(b["params"])} '
            f'| {b["seeds"]} | {b["score"]:.3f} | {b["of_optimum"]:.3f} | {b["met_criterion"]} '
            f'| {b["episodes_to_criterion"] if b["episodes_to_criterion"] is not None else "-"} |'
        )
    return table + '\n', '\n'.join(best_lines) + '\n'


def write_curves(out: Path, records: list[dict], best: list[dict]) -> list[Path]:
    """Per scenario: each learner's best configuration's greedy curve with its seed band."""
    written = []
    for scenario in dict.fromkeys(b['scenario'] for b in best):
        chosen: dict[str, tuple[float, tuple]] = {}
        groups: dict[tuple, list[dict]] = {}
        for record in records:
            if record['status'] == 'ok' and _config_key(record)[0] == scenario:
                groups.setdefault(_config_key(record), []).append(record)
        for key, runs in groups.items():
            score = float(np.mean([r['score'] for r in runs]))
            learner = f'{key[3]} ({key[2]})'
            if learner not in chosen or score > chosen[learner][0]:
                chosen[learner] = (score, key)
        results = []
        for learner, (_, key) in chosen.items():
            runs = [record_result(r) for r in groups[key]]
            length = min(len(r.eval_at) for r in runs)  # ROS runs may stop early
            for r in runs:
                trimmed = replace_spec(r, learner=f'{learner}: {_params_text(json.loads(key[4]))}')
                trimmed.eval_at, trimmed.eval_returns = r.eval_at[:length], r.eval_returns[:length]
                results.append(trimmed)
        figure = Figure(figsize=(8, 5), dpi=100)
        ax = figure.add_subplot()
        plot_curves(ax, results, results[0].optimum, f'{scenario}: best configuration per learner')
        ax.legend(fontsize=7, loc='lower right')
        figure.tight_layout()
        written.append(out / f'curves_{scenario}.png')
        figure.savefig(written[-1])
    return written


def sweep_status(store: SweepStore, total: int, signal_name: str | None = None) -> dict:
    """What status.json says: the trials done (every one with records) and failed of ``total``,
    and complete, failed (every run did) or interrupted."""
    by_trial: dict[str, list[dict]] = {}
    for record in store.records():
        by_trial.setdefault(record['trial'], []).append(record)
    failed = sum(any(r['status'] != 'ok' for r in rs) for rs in by_trial.values())
    runs = [r for rs in by_trial.values() for r in rs]
    status = 'complete'
    if signal_name:
        status = 'interrupted'
    elif runs and all(r['status'] != 'ok' for r in runs):
        status = 'failed'
    return {
        'status': status,
        'signal': signal_name,
        'trials': max(total, len(by_trial)),
        'trials_done': len(by_trial),
        'trials_failed': failed,
    }


def status_line(status: dict, out: Path) -> str:
    """The sweep's outcome in one line (results.md, and the console when it is not complete)."""
    counts = f'{status["trials_done"]} of {status["trials"]} trials done'
    failed = f', {status["trials_failed"]} failed' if status['trials_failed'] else ''
    if status['status'] == 'interrupted':
        return (
            f'interrupted by {status["signal"]}: {counts}{failed}; `stealth sweep --resume '
            f'{out}` runs the rest'
        )
    if status['status'] == 'failed':
        return f'failed: every run failed ({counts}); the error column of results.md says why'
    return f'complete: {counts}{failed}'


def write_report(
    store: SweepStore, title: str, settings: str, plots: bool = True, status: dict | None = None
) -> Path:
    """results.csv, results.md (headed by the ``status`` line) and the curves from every
    record kept so far; status.json."""
    if status is not None:
        write_json(status, store.out / 'status.json')
    records = store.records()
    param_names = sorted({name for r in records for name in r['settings']['params']})
    rows = [row(r, param_names) for r in records]
    write_csv(rows, (*BASE_FIELDS, *param_names, *RESULT_FIELDS), store.out / 'results.csv')
    best = best_configurations(records)
    table, best_table = markdown(rows, param_names, best)
    failed = sum(r['status'] != 'ok' for r in records)
    hosts = sorted({r['host'] for r in records if r.get('host')})
    nodes = sorted({r['node'] for r in records if r.get('node')})
    headline = f'**Sweep {status_line(status, store.out)}.**\n\n' if status else ''
    text = (
        f'# Sweep {title}\n\n{headline}{settings}\n\n{len(records)} runs ({failed} failed) on '
        f'{len(nodes)} Ray node(s), host(s) {", ".join(hosts) or "-"}.\n\n'
        f'## Best configuration per scenario\n\nscore: greedy return relative to the optimum '
        f'(1 = optimal) minus 0.01 x the fraction of the budget spent before every greedy '
        f'evaluation met the success criterion ({DEFAULT_CRITERION.describe()}; a ROS run: '
        f'as its episodes.csv says), mean over seeds. met criterion: '
        f'runs that settled on it.\n\n{best_table}\n## Runs\n\n{table}'
    )
    if plots and best:
        images = write_curves(store.out, records, best)
        text += '\n' + '\n'.join(f'![{p.stem}]({p.name})' for p in images) + '\n'
    (store.out / 'results.md').write_text(text, encoding='utf-8')
    return store.out / 'results.md'
