"""Train the lights-known generalist from nothing: generate the training scenarios (training seed
range only), imitate value iteration's optimal moves on every cell (``generalist_data``), pick
the checkpoint by validation seeds only, and write the weights and the training curve.

    python -m stealth_learn.train_generalist   # the shipped weights: ~4-7 min, 2 cores
    python -m stealth_learn.train_generalist --train 8 --steps 40 --out /tmp/g.npz  # a smoke run
    python -m stealth_learn.train_generalist --moving mixed   # the time-aware weights

Curriculum: the first half of the steps on the smallest buildings only, then all sizes. With
``--moving`` the buildings have sweeping and/or patrolling lights (the generator's ``moving``),
the network is the time-aware one (``vin.Vin`` with the buildings' phase layers and step) and
the targets are the layered value iteration's optimal actions at every cell of every layer.
"""

from __future__ import annotations

import argparse
import functools
import math
import os
from pathlib import Path
import sys
import tempfile
import time

import numpy as np
from stealth_core.scenario_generator import MOVING, THRESHOLD, GenerationError, Options

from stealth_learn import generalist_data as data
from stealth_learn import policy_file, sensed_data
from stealth_learn.obs_layout import LayoutError

DEFAULT_OUT = Path(__file__).resolve().parent / 'policies' / 'generalist-full.npz'
MOVING_OUT = DEFAULT_OUT.with_name('generalist-moving.npz')  # the time-aware weights
SENSED_OUT = DEFAULT_OUT.with_name('generalist-sensed.npz')  # time-aware, lights sensed
SIZES = ((20, 20, 3), (30, 30, 4), (40, 40, 6))  # width, height (m), lights: the curriculum


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='python -m stealth_learn.train_generalist', description=__doc__.split('\n\n')[0]
    )
    parser.add_argument(
        '--out',
        type=Path,
        default=None,
        help='the weights file (.npz; default policies/generalist-full.npz, with --moving '
        'policies/generalist-moving.npz); the curve beside it (.png)',
    )
    parser.add_argument(
        '--moving',
        choices=MOVING,
        default='none',
        help="the lights of the buildings (the generator's --moving): not 'none' trains the "
        'time-aware network',
    )
    parser.add_argument(
        '--train', type=int, default=48, help='training scenarios per size (training seeds)'
    )
    parser.add_argument(
        '--validation',
        type=int,
        default=10,
        help='validation scenarios per size (validation seeds)',
    )
    parser.add_argument(
        '--sizes',
        type=_sizes,
        default=SIZES,
        help='the curriculum: WIDTHxHEIGHTxLIGHTS (m, m, lights), comma-separated, smallest '
        'first (default 20x20x3,30x30x4,40x40x6)',
    )
    parser.add_argument('--steps', type=int, default=2000, help='optimiser steps')
    parser.add_argument('--batch', type=int, default=6, help='scenarios per step')
    parser.add_argument(
        '--iterations', type=int, default=150, help='Bellman backups while training (tied weights)'
    )
    parser.add_argument(
        '--eval-iterations',
        type=int,
        default=240,
        help='Bellman backups at decision time (covers 30 x 30 m paths)',
    )
    parser.add_argument('--hidden', type=int, default=32, help="the reward network's width")
    parser.add_argument('--features', type=int, default=8, help='convolution channels')
    parser.add_argument('--lr', type=float, default=5e-3, help='peak learning rate (cosine)')
    parser.add_argument('--every', type=int, default=50, help='validate every N steps')
    parser.add_argument(
        '--lit-weight',
        type=float,
        default=1.0,
        help='the loss weight of a cell with a lit step among its own (where the choice '
        'is to be seen or not), relative to 1 for the others',
    )
    parser.add_argument(
        '--distance-cap',
        type=float,
        default=None,
        help="the most goal distance the reward reads, tens of lattice steps (vin.Vin's "
        'distance_cap; 0: uncapped; default: uncapped, with --sensed that of the --init '
        'weights), stored in the weights file',
    )
    parser.add_argument('--seed', type=int, default=0, help='the initialisation and batches')
    sensed = parser.add_argument_group(
        'the sensed track (moving lights): DAgger on belief snapshots (stealth_learn.sensed_data)'
    )
    sensed.add_argument(
        '--sensed',
        action='store_true',
        help='train the time-aware network for the lights-sensed track (needs --moving): it '
        'reads the phased belief and whether each layer was sensed',
    )
    sensed.add_argument(
        '--rounds', type=int, default=2, help="DAgger rounds: the first's episodes played by "
        "the hand-set twin, each next one's by the network being trained"
    )  # fmt: skip
    sensed.add_argument(
        '--snapshot-every', type=int, default=8, help='steps between two snapshots of an episode'
    )
    sensed.add_argument(
        '--robot-weight', type=float, default=20.0,
        help="the loss weight added at the robot's own layer and cell (1 + this)",
    )  # fmt: skip
    sensed.add_argument(
        '--labels', choices=('all', 'robot'), default='all',
        help="where a snapshot is labelled: every cell of every layer (the robot's weighing "
        "--robot-weight more), or the robot's own (layer, cell) alone",
    )  # fmt: skip
    sensed.add_argument(
        '--init', type=Path, default=MOVING_OUT,
        help='the weights to start from (time-aware, lights known; default the shipped '
        'generalist-moving.npz), the never-sensed input at 0',
    )  # fmt: skip
    args = parser.parse_args(argv)
    for name in (
        'train',
        'validation',
        'steps',
        'batch',
        'iterations',
        'eval_iterations',
        'hidden',
        'features',
        'every',
        'rounds',
        'snapshot_every',
    ):
        if getattr(args, name) < 1:
            parser.error(f'--{name.replace("_", "-")}: expected a positive whole number')
    # the weights file's ranges (policy_file), so the file written is one load accepts
    for name, highest in (
        ('iterations', policy_file.MAX_ITERATIONS),
        ('eval_iterations', policy_file.MAX_ITERATIONS),
        ('hidden', policy_file.MAX_HIDDEN),
        ('features', policy_file.MAX_FEATURES),
    ):
        if getattr(args, name) > highest:
            parser.error(f'--{name.replace("_", "-")}: expected at most {highest}')
    if not (math.isfinite(args.lr) and args.lr > 0):
        parser.error('--lr: expected a finite number > 0')
    if args.distance_cap is not None and not (
        math.isfinite(args.distance_cap) and args.distance_cap >= 0
    ):
        parser.error('--distance-cap: expected a finite number >= 0 (0: uncapped)')
    if not (math.isfinite(args.lit_weight) and args.lit_weight >= 1):
        parser.error('--lit-weight: expected a finite number >= 1')
    if args.seed < 0:
        parser.error('--seed: expected a whole number >= 0')
    if args.sensed and args.moving == 'none':
        parser.error("--sensed: expected --moving (the sensed track's network is time-aware)")
    if not (math.isfinite(args.robot_weight) and args.robot_weight >= 0):
        parser.error('--robot-weight: expected a finite number >= 0')
    if args.out is None:
        args.out = DEFAULT_OUT if args.moving == 'none' else MOVING_OUT
        args.out = SENSED_OUT if args.sensed else args.out
    return args


def _sizes(text: str) -> tuple[tuple[int, int, int], ...]:
    """``--sizes``' value: '20x20x3,30x30x4' -> ((20, 20, 3), (30, 30, 4))."""
    try:
        sizes = tuple(tuple(int(v) for v in item.split('x')) for item in text.split(','))
    except ValueError:
        sizes = ()
    if not sizes or any(len(size) != 3 or min(size) < 1 for size in sizes):
        raise argparse.ArgumentTypeError(
            f'expected WIDTHxHEIGHTxLIGHTS, comma-separated (e.g. 20x20x3,30x30x4), got {text!r}'
        )
    return sizes


def loss_fn(model, variables, grid, optimal, weight):
    """Weighted cross-entropy of the optimal set: -log P(any optimal move), per loss cell."""
    from stealth_learn.jax_deps import jax, jnp
    from stealth_learn.vin import logits_of_cells

    logits = logits_of_cells(model, variables, grid)
    log_p = jax.nn.log_softmax(logits, axis=-1)
    picked = jax.nn.logsumexp(jnp.where(optimal, log_p, -1e9), axis=-1)
    return -(picked * weight).sum() / jnp.maximum(weight.sum(), 1.0)


def lit_weighted(model, grid, weight, factor: float):
    """``weight`` times ``factor`` on the cells (and layers) with a lit step among their own
    (``--lit-weight``): the decisions where being seen is at stake, rare among all cells."""
    from stealth_learn.jax_deps import jnp

    _, lights, exists = model.inputs(grid)
    lit = (exists & (lights >= model.threshold)).any(axis=-1)
    lit = lit if model.phased else lit[:, 0]
    return weight * jnp.where(lit, factor, 1.0)


def accuracy(model, variables, grid, optimal, weight) -> float:
    """Fraction of loss cells whose argmax is an optimal move."""
    from stealth_learn.vin import logits_of_cells

    logits = np.asarray(logits_of_cells(model, variables, grid))
    chosen = np.take_along_axis(optimal, logits.argmax(-1)[..., None], -1)[..., 0]
    return float((chosen * weight).sum() / max(weight.sum(), 1.0))


def train(args, log=print, progress: bool = False) -> dict:
    """Generate, train, select; returns the run's record (curve, selection, timing).
    ``progress``: a bar over the optimiser steps (``log`` then writes above it)."""
    import optax
    from tqdm import tqdm

    from stealth_learn.generalist import GeneralistPolicy
    from stealth_learn.jax_deps import jax, jnp
    from stealth_learn.vin import Vin

    started = time.monotonic()
    # --init is read first: a file that cannot be one stops the run before any work
    initial, header = (None, {})
    if args.sensed and args.init:
        initial, header = policy_file.load(args.init, None)
    distance_cap = _distance_cap(args, header)
    directory = Path(tempfile.mkdtemp(prefix='generalist-'))
    sets = {'train': [], 'validation': []}
    buildings = {'train': [], 'validation': []}  # --sensed: [(scenario, Sample)] per size
    for index, (width, height, lights) in enumerate(args.sizes):
        options = Options(width=width, height=height, lights=lights, moving=args.moving)
        for name, count in (('train', args.train), ('validation', args.validation)):
            seeds = data.seeds_of(name, count, offset=index * 3_000)
            if args.sensed:
                buildings[name].append(sensed_data.load_buildings(seeds, options, directory, log))
                sets[name].append([sample for _, sample in buildings[name][-1]])
            else:
                sets[name].append(_of_lights(data.load_samples(seeds, options, directory, log),
                                             args.moving, log))  # fmt: skip
            log(f'{name} {width}x{height} m: {len(sets[name][-1])} scenarios')
    layers, advance = _cycle(sum(sets['train'] + sets['validation'], []))
    model = Vin(
        args.iterations, args.hidden, args.features, THRESHOLD, layers, advance, int(args.sensed),
        distance_cap,
    )  # fmt: skip
    architecture = _architecture(args, layers, advance, distance_cap)
    if args.sensed:  # the first round: the hand-set twin's episodes
        twin = functools.partial(_hand_set_twin, architecture)
        for name in sets:
            sets[name] = _snapshots(buildings[name], twin, args, f'{name}: round 1', progress)
        unknown = sensed_data.unknown_share(sum(sets['train'], []))
        log(f'round 1: {sum(map(len, sets["train"]))} training snapshots, {unknown:.0%} unknown')
    generated = time.monotonic() - started
    rng = np.random.default_rng(args.seed)
    small, every_size = sets['train'][0], sum(sets['train'], [])
    # one padded size per phase: a new batch shape would compile the step again
    shapes = [_shape(small), _shape(every_size)]
    validation = [data.batch(samples) for samples in sets['validation']]
    variables = model.init(jax.random.PRNGKey(args.seed), jnp.asarray(validation[0][0][:1]))
    if initial is not None:
        variables = {'params': _initial(initial, variables['params'], args.init)}
    round_starts = {1 + r * args.steps // args.rounds: r + 1 for r in range(1, args.rounds)}
    optimiser = optax.chain(
        optax.clip_by_global_norm(1.0),
        optax.adam(optax.cosine_decay_schedule(args.lr, args.steps, alpha=0.1)),
    )
    state = optimiser.init(variables)

    @jax.jit
    def update(variables, state, grid, optimal, weight):
        weight = lit_weighted(model, grid, weight, args.lit_weight)
        loss, grads = jax.value_and_grad(lambda v: loss_fn(model, v, grid, optimal, weight))(
            variables
        )
        updates, state = optimiser.update(grads, state, variables)
        return optax.apply_updates(variables, updates), state, loss

    evaluate = jax.jit(
        lambda v, g, o, w: loss_fn(model, v, g, o, lit_weighted(model, g, w, args.lit_weight))
    )
    curve = {'step': [], 'train_loss': [], 'validation_loss': [], 'validation_accuracy': []}
    best = (np.inf, None, -1)
    losses = []
    loop_started = time.monotonic()
    bar = tqdm(range(1, args.steps + 1), desc='training', unit='step', disable=not progress)
    for step in bar:
        if args.sensed and step in round_starts:  # DAgger: the network's own episodes join
            learned = GeneralistPolicy(variables['params'], architecture, source='training')
            label = f'train: round {round_starts[step]}'
            more = _snapshots(buildings['train'], lambda _, p=learned: p, args, label, progress)
            sets['train'] = [old + new for old, new in zip(sets['train'], more, strict=True)]
            small, every_size = sets['train'][0], sum(sets['train'], [])
            elapsed = time.monotonic() - started
            log(f'{label}: {sum(map(len, more))} snapshots more ({elapsed:.0f} s)')
        phase = int(step > args.steps // 2)
        pool = (small, every_size)[phase]
        picked = [pool[i] for i in rng.choice(len(pool), min(args.batch, len(pool)), False)]
        grid, optimal, weight = data.batch(picked, shapes[phase])
        variables, state, loss = update(variables, state, grid, optimal, weight)
        losses.append(float(loss))
        bar.set_postfix(loss=f'{losses[-1]:.4f}', refresh=False)
        if step % args.every == 0 or step == args.steps:
            v_loss = float(np.mean([evaluate(variables, *b) for b in validation]))
            v_acc = float(np.mean([accuracy(model, variables, *b) for b in validation]))
            curve['step'].append(step)
            curve['train_loss'].append(float(np.mean(losses[-args.every :])))
            curve['validation_loss'].append(v_loss)
            curve['validation_accuracy'].append(v_acc)
            log(
                f'step {step}: train loss {curve["train_loss"][-1]:.4f}, validation loss '
                f'{v_loss:.4f}, accuracy {v_acc:.4f} ({time.monotonic() - started:.0f} s)'
            )
            if v_loss < best[0]:
                best = (v_loss, jax.tree_util.tree_map(np.asarray, variables['params']), step)
    trained = time.monotonic() - loop_started
    return {
        'params': best[1],
        'selected_step': best[2],
        'validation_loss': best[0],
        'curve': curve,
        'generate_seconds': generated,
        'seconds': time.monotonic() - started,
        'train_scenarios': len(every_size),
        'architecture': architecture,
        'samples_per_second': args.steps * args.batch / max(trained, 1e-9),
        'train_seconds': trained,
    }


def _architecture(args, layers: int, advance: int, distance_cap: float) -> dict:
    """The weights file's architecture (decision-time backups; the goal distance capped at
    ``distance_cap``, 0 uncapped)."""
    return {
        'iterations': args.eval_iterations,
        'hidden': args.hidden,
        'features': args.features,
        'threshold': THRESHOLD,
        **({'layers': layers, 'advance': advance} if layers > 1 else {}),
        **({'uncertain': 1} if args.sensed else {}),
        **({'distance_cap': distance_cap} if distance_cap else {}),
    }


def _hand_set_twin(architecture: dict, scenario):
    from stealth_learn.generalist import GeneralistPolicy
    from stealth_learn.hand_set import ScenarioReward

    return GeneralistPolicy.hand_set(architecture, ScenarioReward.of(scenario))


def _snapshots(groups, policy_of, args, label: str, progress: bool) -> list:
    """Per size, the belief snapshots of its buildings' episodes (``sensed_data``)."""
    from tqdm import tqdm

    with tqdm(
        total=sum(map(len, groups)), desc=label, unit='episode', disable=not progress
    ) as bar:
        return [
            sensed_data.snapshots(
                group,
                policy_of,
                args.snapshot_every,
                args.robot_weight,
                bar,
                robot_only=args.labels == 'robot',
            )
            for group in groups
        ]


def _distance_cap(args, init_header: dict) -> float:
    """The cap to train with: --distance-cap, else the --init weights' own (0: uncapped);
    PolicyFileError naming the file if the two differ (the weights learned another input)."""
    own = float(init_header.get('architecture', {}).get('distance_cap', 0.0))
    if args.distance_cap is None:
        return own
    if init_header and float(args.distance_cap) != own:
        raise policy_file.PolicyFileError(
            f'{args.init}: --init: its weights read the goal distance with distance_cap {own:g} '
            f'(0: uncapped), --distance-cap is {args.distance_cap:g}; give --distance-cap {own:g}'
        )
    return float(args.distance_cap)


def _initial(loaded: dict, params, path: Path) -> dict:
    """``params`` (the network's, initialised) replaced by the time-aware weights ``loaded``
    from ``path`` (--init), the never-sensed input's weights 0 where they have none;
    PolicyFileError naming the path if they do not fit the network."""
    kernel = loaded['reward_hidden']['kernel']
    if kernel.shape[0] == np.shape(params['reward_hidden']['kernel'])[0] - 1:
        loaded['reward_hidden']['kernel'] = np.concatenate([kernel, np.zeros_like(kernel[:1])])
    if _shapes(loaded) != _shapes(params):
        raise policy_file.PolicyFileError(
            f'{path}: --init: its parameters are {_shapes(loaded)}, the network being trained '
            f'has {_shapes(params)} (--hidden, --features)'
        )
    return loaded


def _shapes(tree) -> dict:
    return {key: _shapes(v) if isinstance(v, dict) else np.shape(v) for key, v in tree.items()}


def _of_lights(samples, moving: str, log) -> list:
    """The samples whose lights are as asked: a building generated with moving lights may have
    none that move (then it is static: skipped, and said)."""
    wanted, kept = moving != 'none', []
    for s in samples:
        if (s.grid.ndim == 4) == wanted:
            kept.append(s)
        else:
            log(f'seed {s.seed}: skipped (its lights are {"not " * wanted}moving)')
    return kept


def _cycle(samples) -> tuple[int, int]:
    """(phase layers, layers a step advances) every sample shares ((1, 0): static);
    DataError if they differ (one network reads one cycle)."""
    cycles = {(s.grid.shape[0] if s.grid.ndim == 4 else 1, s.advance) for s in samples}
    if len(cycles) != 1:
        raise data.DataError(
            f'the buildings have {len(cycles)} different light cycles (phase layers, step): '
            f'{sorted(cycles)}; one time-aware network reads one'
        )
    return cycles.pop()


def _shape(samples) -> tuple[int, int]:
    return max(s.grid.shape[-3] for s in samples), max(s.grid.shape[-2] for s in samples)


def plot_curve(curve: dict, path: Path, sensed: bool = False) -> Path:
    """The training curve (losses and validation accuracy) as a PNG (``sensed``: the sensed
    track's network, its imitation on belief snapshots)."""
    import matplotlib

    matplotlib.use('Agg')
    from matplotlib import pyplot as plt

    figure, (left, right) = plt.subplots(1, 2, figsize=(9, 3.5))
    left.plot(curve['step'], curve['train_loss'], label='training (mean since last point)')
    left.plot(curve['step'], curve['validation_loss'], label='validation')
    left.set(xlabel='optimiser step', ylabel='imitation loss', yscale='log')
    left.legend()
    right.plot(curve['step'], curve['validation_accuracy'], color='C2')
    right.set(xlabel='optimiser step', ylabel='validation: optimal-move accuracy', ylim=(0, 1))
    track = 'lights sensed: DAgger on belief snapshots' if sensed else 'lights known'
    figure.suptitle(f'Generalist (VIN), {track}: imitation of value iteration')
    figure.tight_layout()
    figure.savefig(path, dpi=90)
    plt.close(figure)
    return path


def _write_above_bar(line: str) -> None:
    from tqdm import tqdm

    tqdm.write(line)


def main(argv=None) -> int:
    args = parse_args(argv)
    threads = os.environ.get('XLA_FLAGS', '')
    print(
        f'training on {os.cpu_count()} cores (XLA_FLAGS={threads!r}); '
        f'load {os.getloadavg()[0]:.1f}',
        flush=True,
    )
    try:
        record = train(args, log=_write_above_bar, progress=True)
    except (GenerationError, data.DataError, policy_file.PolicyFileError, LayoutError) as error:
        print(f'train_generalist: {error}', file=sys.stderr)
        return 2
    architecture = record['architecture']
    training = {
        'train_iterations': args.iterations,
        'steps': args.steps,
        'batch': args.batch,
        'lr': args.lr,
        'lit_weight': args.lit_weight,
        'seed': args.seed,
        'train_scenarios': record['train_scenarios'],
        'selected_step': record['selected_step'],
        'validation_loss': record['validation_loss'],
        'seconds': round(record['seconds'], 1),
        'train_seconds': round(record['train_seconds'], 1),
        'samples_per_second': round(record['samples_per_second'], 3),
        'sizes': [list(s) for s in args.sizes],
    }
    try:
        track = 'sensed' if args.sensed else 'full'
        path = policy_file.save(args.out, record['params'], track, architecture, training)
    except (OSError, policy_file.PolicyFileError) as error:  # e.g. a diverged (NaN) loss
        print(f'train_generalist: {args.out}: not written ({error})', file=sys.stderr)
        return 2
    picture = plot_curve(record['curve'], args.out.with_suffix('.png'), args.sensed)
    print(
        f'wrote {path} (selected step {record["selected_step"]}) and {picture}; '
        f'{record["seconds"]:.0f} s ({record["generate_seconds"]:.0f} s generating), '
        f'load {os.getloadavg()[0]:.1f}'
    )
    return 0


if __name__ == '__main__':
    sys.exit(main())
