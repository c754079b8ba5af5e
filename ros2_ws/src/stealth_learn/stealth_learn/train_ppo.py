"""Train the generalist for the static lights-sensed track by reinforcement learning: PPO
(``ppo``) on the JAX environment, generated buildings (training seeds only) stepped together,
starting from the lights-known weights; the checkpoint picked by greedy episodes on validation
seeds only; the weights file (track 'sensed', the never-sensed input) and the curve written.

    python -m stealth_learn.train_ppo --out /tmp/ppo.npz                 # ~1 h on 2 cores
    python -m stealth_learn.train_ppo --train 4 --validation 2 --updates 2 --out /tmp/p.npz

``--hardest-of N``: the training buildings are the ``--train`` of N training seeds where the
starting weights do worst (greedy, on the sensed Gym env: the shortfall of their return from
value iteration's), screened once before training: prioritized level replay's idea (Jiang et
al. 2021) without the replay, so the rollouts hold the failures there are to learn from.

Environment steps a second are counted over the whole training (rollouts and learning, not
the validation) and stored in the weights file with the wall time.
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path
import sys
import tempfile
import time

import numpy as np
from stealth_core.scenario_generator import GenerationError, Options

from stealth_learn import generalist_data as data
from stealth_learn import policy_file

DEFAULT_SIZE = (30, 30, 4)  # width, height (m), lights: the size the network is measured on


def parse_args(argv=None) -> argparse.Namespace:
    from stealth_learn.ppo import PpoConfig

    defaults = PpoConfig()
    parser = argparse.ArgumentParser(
        prog='python -m stealth_learn.train_ppo', description=__doc__.split('\n\n')[0]
    )
    parser.add_argument('--out', type=Path, required=True, help='the weights file (.npz); '
                        'the curve beside it (.png)')  # fmt: skip
    parser.add_argument(
        '--init', type=Path, default=policy_file.SHIPPED,
        help='the weights to start from (static, lights known; default the shipped '
        'generalist-full.npz), the never-sensed input at 0',
    )  # fmt: skip
    parser.add_argument('--size', type=_size, default=DEFAULT_SIZE,
                        help='the buildings: WIDTHxHEIGHTxLIGHTS (default 30x30x4)')  # fmt: skip
    parser.add_argument('--train', type=int, default=32,
                        help='training buildings, one environment each')  # fmt: skip
    parser.add_argument(
        '--hardest-of', type=int, default=0, metavar='N',
        help='train on the --train of N training seeds where the starting weights do worst '
        '(module docstring; 0: the first --train seeds)',
    )  # fmt: skip
    parser.add_argument('--validation', type=int, default=16, help='validation buildings')
    parser.add_argument('--updates', type=int, default=200, help='PPO updates')
    parser.add_argument('--num-steps', type=int, default=defaults.num_steps,
                        help='steps per environment in each rollout')  # fmt: skip
    parser.add_argument('--epochs', type=int, default=defaults.update_epochs)
    parser.add_argument('--minibatches', type=int, default=defaults.num_minibatches)
    parser.add_argument('--lr', type=float, default=defaults.lr, help="the actor's Adam rate")
    parser.add_argument('--ent-coef', type=float, default=defaults.ent_coef)
    parser.add_argument('--iterations', type=int, default=defaults.iterations,
                        help='Bellman backups in training')  # fmt: skip
    parser.add_argument('--gradient-backups', type=int, default=defaults.gradient_backups,
                        help='of them, the last N differentiated (0: all)')  # fmt: skip
    parser.add_argument('--eval-iterations', type=int, default=240,
                        help='Bellman backups at decision time, stored in the file')  # fmt: skip
    parser.add_argument('--every', type=int, default=10, help='validate every N updates')
    parser.add_argument('--seed', type=int, default=0, help='the rollouts and minibatches')
    args = parser.parse_args(argv)
    for name in ('train', 'validation', 'updates', 'num_steps', 'epochs', 'minibatches',
                 'iterations', 'eval_iterations', 'every'):  # fmt: skip
        if getattr(args, name) < 1:
            parser.error(f'--{name.replace("_", "-")}: expected a positive whole number')
    if args.hardest_of and args.hardest_of < args.train:
        parser.error('--hardest-of: expected 0 or at least --train')
    if (args.train * args.num_steps) % args.minibatches:
        parser.error('--minibatches: expected a divisor of --train x --num-steps')
    if not 0 <= args.gradient_backups <= args.iterations:
        parser.error('--gradient-backups: expected 0..--iterations')
    if max(args.iterations, args.eval_iterations) > policy_file.MAX_ITERATIONS:
        parser.error(f'--iterations: expected at most {policy_file.MAX_ITERATIONS}')
    for name in ('lr', 'ent_coef'):
        value = getattr(args, name)
        if not (math.isfinite(value) and value >= 0) or (name == 'lr' and value == 0):
            parser.error(f'--{name.replace("_", "-")}: expected a finite number > 0')
    if args.seed < 0:
        parser.error('--seed: expected a whole number >= 0')
    return args


def _size(text: str) -> tuple[int, int, int]:
    try:
        width, height, lights = (int(part) for part in text.lower().split('x'))
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected WIDTHxHEIGHTxLIGHTS, got {text!r}') from None
    if min(width, height, lights) < 1:
        raise argparse.ArgumentTypeError(f'expected whole numbers >= 1, got {text!r}')
    return width, height, lights


def _buildings(range_name: str, count: int, options: Options, directory: Path, log) -> list:
    seeds = data.seeds_of(range_name, count)
    return [scenario for _, scenario in data.scenarios_of(seeds, options, directory, log)]


def hardest(scenarios, policy, count: int, log, progress: bool) -> list:
    """The ``count`` of ``scenarios`` where ``policy`` (a ``GeneralistPolicy``) does worst,
    greedy on the sensed Gym env: the shortfall of its return from value iteration's."""
    from stealth_core.gym_env import StealthNavEnv
    from stealth_core.planners import value_iteration
    from stealth_core.replanning import play
    from tqdm import tqdm

    from stealth_learn.generalist_agent import GeneralistAgent

    shortfall = []
    for scenario in tqdm(scenarios, desc='screening', unit='building', disable=not progress):
        env = StealthNavEnv(scenario, track='sensed')
        played = play(env, GeneralistAgent(policy, env).act, seed=0)
        optimum = value_iteration(env.model).optimal_return
        shortfall.append(optimum - played['total_reward'])
    order = sorted(range(len(scenarios)), key=lambda i: -shortfall[i])[:count]
    lost = sum(shortfall[i] > 1000 for i in order)  # the goal lost: caught or out of steps
    low, high = shortfall[order[-1]], shortfall[order[0]]
    log(f'screened {len(scenarios)} buildings: kept the {len(order)} hardest (shortfall '
        f'{low:.1f} to {high:.1f}; {lost} without the goal)')  # fmt: skip
    return [scenarios[i] for i in order]


def train(args, log=print, progress: bool = False) -> dict:
    """Generate, train, validate, select; the run's record (curve, selection, throughput)."""
    from tqdm import tqdm

    from stealth_learn import jax_env
    from stealth_learn.jax_deps import jax
    from stealth_learn.ppo import PpoConfig, Trainer, greedy_episodes

    started = time.monotonic()
    init, header = policy_file.load(args.init, None)
    architecture = dict(header['architecture'])
    if architecture.get('layers', 1) > 1:
        raise policy_file.PolicyFileError(
            f'{args.init}: --init: time-aware weights; PPO here trains the static network'
        )
    width, height, lights = args.size
    options = Options(width=width, height=height, lights=lights)
    directory = Path(tempfile.mkdtemp(prefix='ppo-'))
    train_set = _buildings('train', args.hardest_of or args.train, options, directory, log)
    if args.hardest_of:
        from stealth_learn.generalist import GeneralistPolicy

        start = GeneralistPolicy(init, architecture, header, source=args.init)
        train_set = hardest(train_set, start, args.train, log, progress)
    validation_set = _buildings('validation', args.validation, options, directory, log)
    env, params = jax_env.build(train_set, track='sensed', layout='grid')
    val_env, val_params = jax_env.build(validation_set, track='sensed', layout='grid')
    log(f'{len(train_set)} training and {len(validation_set)} validation buildings, '
        f'{width}x{height} m, {lights} lights; grid {env.dims.rows}x{env.dims.cols}')  # fmt: skip
    config = PpoConfig(
        num_steps=args.num_steps, update_epochs=args.epochs, num_minibatches=args.minibatches,
        lr=args.lr, ent_coef=args.ent_coef, iterations=args.iterations,
        gradient_backups=args.gradient_backups,
    )  # fmt: skip
    trainer = Trainer(env, params, init, architecture, config, seed=args.seed)
    limit = int(np.max(np.asarray(val_params.step_limit)))
    greedy = jax.jit(lambda p, k: greedy_episodes(trainer.net, p, val_env, val_params, k, limit))
    curve = {key: [] for key in ('env_steps', 'success', 'detected', 'mean_return',
                                 'train_success')}  # fmt: skip
    best = {'mean_return': -np.inf}
    learning_seconds = 0.0
    recent = []

    def validate(update: int) -> None:
        outcome, total = jax.device_get(greedy(trainer.params, jax.random.PRNGKey(0)))
        row = {'env_steps': trainer.env_steps, 'success': float(np.mean(outcome == 0)),
               'detected': float(np.mean(outcome == 1)), 'mean_return': float(np.mean(total)),
               'train_success': float(np.mean(recent)) if recent else float('nan')}  # fmt: skip
        for key, value in row.items():
            curve[key].append(value)
        elapsed = time.monotonic() - started
        log(f'update {update}: validation success {row["success"]:.0%}, detected '
            f'{row["detected"]:.0%}, mean return {row["mean_return"]:.1f}; training episodes '
            f'{row["train_success"]:.0%} at the goal ({elapsed:.0f} s)')  # fmt: skip
        if row['mean_return'] > best['mean_return']:
            actor = jax.tree.map(np.asarray, trainer.params['actor'])
            best.update(mean_return=row['mean_return'], params=actor, update=update)

    validate(0)
    bar = tqdm(range(1, args.updates + 1), desc='PPO', unit='update', disable=not progress)
    for update in bar:
        metrics = trainer.update()
        learning_seconds += metrics['seconds']
        if metrics['episodes']:
            recent.append(float(metrics['successes'] / metrics['episodes']))
            recent = recent[-args.every :]
        bar.set_postfix(steps_per_s=f'{trainer.env_steps / learning_seconds:.0f}',
                        entropy=f'{float(metrics["entropy"]):.3f}', refresh=False)  # fmt: skip
        if update % args.every == 0 or update == args.updates:
            validate(update)
    return {
        'params': best['params'],
        'selected_update': best['update'],
        'validation_return': best['mean_return'],
        'curve': curve,
        'architecture': {**architecture, 'iterations': args.eval_iterations, 'uncertain': 1},
        'env_steps': trainer.env_steps,
        'env_steps_per_second': trainer.env_steps / max(learning_seconds, 1e-9),
        'train_seconds': learning_seconds,
        'seconds': time.monotonic() - started,
        'train_scenarios': len(train_set),
    }


def plot_curve(curve: dict, path: Path) -> Path:
    """Validation success, detections and mean return against environment steps (PNG)."""
    import matplotlib

    matplotlib.use('Agg')
    from matplotlib import pyplot as plt
    from matplotlib.ticker import FuncFormatter

    figure, (left, right) = plt.subplots(1, 2, figsize=(9, 3.5))
    for axis in (left, right):  # thousands of steps: full numbers run into each other
        axis.xaxis.set_major_formatter(FuncFormatter(lambda value, _: f'{value / 1000:g}k'))
    left.plot(curve['env_steps'], curve['success'], label='validation: at the goal')
    left.plot(curve['env_steps'], curve['detected'], label='validation: detected')
    left.plot(curve['env_steps'], curve['train_success'], label='training episodes: at the goal')
    left.set(xlabel='environment steps', ylabel='share of episodes', ylim=(0, 1.05))
    left.legend(fontsize=8)
    right.plot(curve['env_steps'], curve['mean_return'], color='C3')
    right.set(xlabel='environment steps', ylabel='validation: mean return (greedy)')
    figure.suptitle('Generalist (VIN), lights sensed: PPO on the JAX environment')
    figure.tight_layout()
    figure.savefig(path, dpi=90)
    plt.close(figure)
    return path


def main(argv=None) -> int:
    args = parse_args(argv)
    print(f'training on {os.cpu_count()} cores; load {os.getloadavg()[0]:.1f}', flush=True)
    from tqdm import tqdm

    try:
        record = train(args, log=tqdm.write, progress=True)
    except (GenerationError, data.DataError, policy_file.PolicyFileError) as error:
        print(f'train_ppo: {error}', file=sys.stderr)
        return 2
    training = {
        'train_iterations': args.iterations,
        'steps': args.updates * args.epochs * args.minibatches,
        'batch': args.train * args.num_steps // args.minibatches,
        'lr': args.lr,
        'seed': args.seed,
        'train_scenarios': record['train_scenarios'],
        'seconds': round(record['seconds'], 1),
        'train_seconds': round(record['train_seconds'], 1),
        'env_steps': record['env_steps'],
        'env_steps_per_second': round(record['env_steps_per_second'], 1),
        'selected_update': record['selected_update'],
        'sizes': [list(args.size)],
    }
    try:
        path = policy_file.save(
            args.out, record['params'], 'sensed', record['architecture'], training
        )
    except (OSError, policy_file.PolicyFileError) as error:
        print(f'train_ppo: {args.out}: not written ({error})', file=sys.stderr)
        return 2
    picture = plot_curve(record['curve'], args.out.with_suffix('.png'))
    print(
        f'wrote {path} (update {record["selected_update"]}: validation mean return '
        f'{record["validation_return"]:.1f}) and {picture}; {record["env_steps"]} env steps at '
        f'{record["env_steps_per_second"]:.0f} a second, {record["seconds"]:.0f} s in all'
    )
    return 0


if __name__ == '__main__':
    sys.exit(main())
