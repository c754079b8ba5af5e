"""The generalist's weights file: one ``.npz`` (5 KB: the network has ~700 parameters) with
the parameters and a JSON header naming the observation layout, the track and the architecture.

Every user (the benchmark, the agent node's plugin, ``python -m stealth_learn.generalist``)
reads it through ``load``, which checks all of it before any network is built, so a bad file is
refused in one line naming its path and what was expected (issue 30's and 40's bad-input rules):

- the path: missing, a directory or not a regular file, empty, unreadable, or too large;
- the npz: not a zip, truncated, a member damaged (CRC), a member too large;
- the header (``check_header``): every field's type and range (``ARCHITECTURE_RANGES``,
  ``TRAINING_FIELDS``), no unknown or duplicated field; another layout or track is
  ``obs_layout.LayoutError`` naming both layouts;
- the parameters: exactly the ones the header's architecture has, each of the shape that
  architecture gives (``expected_shapes``: the network initialised abstractly, never a table
  written by hand), floating point and finite.

The layout is the grid layout without its size (``stealth-grid-v1/full``): the network is
fully convolutional, so any scenario's grid fits. A time-aware network (moving lights: the
architecture's ``layers`` > 1) reads the phased grid of its phase count and step
(``obs_layout.phased_layout_id``, e.g. ``stealth-phased-v1/full/8phases-1perstep``): the
header's layout must be its architecture's. A network trained for the sensed track has
``uncertain`` 1 in its architecture (optional, 0 or 1: it reads the never-sensed input) and
track 'sensed'. One with a distance cap has ``distance_cap`` (optional, > 0: the most goal
distance its reward reads, ``vin.Vin``).
"""

from __future__ import annotations

from collections import Counter
import dataclasses
import functools
import json
from pathlib import Path
import stat

import numpy as np
from stealth_core.gym_env import TRACKS
from stealth_core.yaml_fields import FieldReader

from stealth_learn.obs_layout import (
    PHASED_PREFIX,
    check_layout,
    layout_id,
    phased_layout_id,
)

FORMAT = 'stealth-generalist-v1'
SHIPPED = Path(__file__).resolve().parent / 'policies' / 'generalist-full.npz'  # lights known
HEADER = '__header__'
PARAMS = 'params/'
ZIP_MAGIC = b'PK\x03\x04'  # an npz is a zip archive
NPY_MAGIC = b'\x93NUMPY'
# Bellman backups at decision time: 40x the shipped 240, 25x the longest episode of a generated
# building (400 steps; a backup more than an episode has steps changes no decision). The bound
# keeps one plan of the largest generated building (80 x 120 nodes) under a second or so.
MAX_ITERATIONS = 10_000
MAX_HIDDEN = 1024  # the reward network's width (32 shipped)
MAX_FEATURES = 256  # the 3x3 convolution's channels (8 shipped)
MAX_LAYERS = 256  # phase layers of a time-aware network (the generated buildings' cycle: 8)


@dataclasses.dataclass(frozen=True)
class Range:
    """A header field's type and range: a whole number ``low..high`` (``high`` None: no
    bound), or a finite real number >= ``low`` (> ``low`` when ``above``)."""

    integer: bool
    low: float
    high: int | None = None
    above: bool = False

    @property
    def text(self) -> str:
        if self.integer and self.high is None:
            return f'an integer >= {self.low}'
        if self.integer:
            return f'an integer {self.low}..{self.high}'
        return f'a finite number {">" if self.above else ">="} {self.low:g}'

    def holds(self, value) -> bool:
        if self.integer:
            return self.low <= value and (self.high is None or value <= self.high)
        return value > self.low if self.above else value >= self.low


# the architecture's fields (the header's ``architecture``), all required
ARCHITECTURE_RANGES = {
    'iterations': Range(True, 1, MAX_ITERATIONS),
    'hidden': Range(True, 1, MAX_HIDDEN),
    'features': Range(True, 1, MAX_FEATURES),
    'threshold': Range(False, 0.0, above=True),  # the detection threshold it was trained for
}
ARCHITECTURE = tuple(ARCHITECTURE_RANGES)
# a time-aware network's (``vin.Vin``'s layers and advance), both or neither; neither: static
PHASED_RANGES = {
    'layers': Range(True, 2, MAX_LAYERS),
    'advance': Range(True, 0, MAX_LAYERS - 1),  # and < layers
}
# optional: 1 for a network of the sensed track reading the never-sensed input (``vin.Vin``)
UNCERTAIN_RANGES = {'uncertain': Range(True, 0, 1)}
# optional: the most goal distance the reward reads, tens of lattice steps (``vin.Vin``)
CAP_RANGES = {'distance_cap': Range(False, 0.0, above=True)}
# the training record (optional, each field optional; read by no decision)
TRAINING_FIELDS = {
    'train_iterations': Range(True, 1, MAX_ITERATIONS),
    'steps': Range(True, 1),
    'batch': Range(True, 1),
    'lr': Range(False, 0.0, above=True),
    'lit_weight': Range(False, 1.0),  # the loss weight of cells with a lit step (--lit-weight)
    'seed': Range(True, 0),
    'train_scenarios': Range(True, 1),
    'selected_step': Range(True, 0),  # and <= steps
    'validation_loss': Range(False, 0.0),
    'seconds': Range(False, 0.0),
    'train_seconds': Range(False, 0.0),  # the optimiser's loop (validation included)
    'samples_per_second': Range(False, 0.0),  # scenarios (every cell of each) a second
    # reinforcement learning (``train_ppo``): environment steps taken, and a second over the
    # rollouts and learning; the update whose weights were kept (validation's best)
    'env_steps': Range(True, 1),
    'env_steps_per_second': Range(False, 0.0),
    'selected_update': Range(True, 0),
}
SIZES = 'sizes'  # training: [[width m, height m, lights], ...], whole numbers >= 1
# The largest network the ranges allow has ~1 MB of parameters: a bigger file is not one.
MAX_FILE_BYTES = 32 * 2**20  # on disk, and the npz's members unpacked together
MAX_ARRAYS = 64  # the header and the parameters (8 in the network)


class PolicyFileError(ValueError):
    """A weights file that is missing, unreadable, corrupt or not a generalist's."""


def policy_layout(track: str, architecture: dict | None = None) -> str:
    """The generalist's layout for a track: the grid layout of any size, or the phased grid of
    a time-aware ``architecture`` (its ``layers`` and ``advance``)."""
    if architecture is not None and int(architecture.get('layers', 1)) > 1:
        return phased_layout_id(track, architecture['layers'], architecture['advance'])
    return without_size(layout_id('grid', track, 0, 0))


def without_size(layout: str) -> str:
    parts = layout.split('/')
    if parts[0].startswith('stealth-phased-'):
        return '/'.join(parts[:3])
    return '/'.join(parts[:2]) if parts[0].startswith('stealth-grid-') else layout


def save(path, params, track: str, architecture: dict, training: dict | None = None) -> Path:
    """Write ``params`` (a flax params tree) with the header; returns the path. The header is
    checked as ``load`` checks it, so no command writes a file ``load`` would refuse."""
    path = Path(path)
    names = ARCHITECTURE + (tuple(PHASED_RANGES) if architecture.get('layers', 1) > 1 else ())
    names += tuple(UNCERTAIN_RANGES) if architecture.get('uncertain', 0) else ()
    names += tuple(CAP_RANGES) if architecture.get('distance_cap', 0) else ()
    header = {
        'format': FORMAT,
        'layout': policy_layout(track, architecture),
        'track': track,
        'architecture': {name: architecture[name] for name in names},
        **({'training': training} if training is not None else {}),
    }
    check_header(path, header)
    arrays = {f'{PARAMS}{key}': np.asarray(value) for key, value in _flatten(params).items()}
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open('wb') as stream:
        np.savez_compressed(stream, **arrays, **{HEADER: np.array(json.dumps(header))})
    return path


def load(path, env_layout: str | None) -> tuple[dict, dict]:
    """(params tree, header) of the file at ``path`` for an environment giving ``env_layout``
    (``obs_layout.layout_id``: any grid size; None: any lights-known layout, static or phased,
    or the sensed one, static or phased, of a network trained for that track (it reads the
    never-sensed input), the scenario's checked
    when it is known: ``GeneralistPolicy.check_scenario``), checked
    whole (module docstring). PolicyFileError or ``obs_layout.LayoutError`` (another layout,
    track or phase count): one line naming the path. Needs the learning extra (the shapes
    come from the network)."""
    path = Path(path)
    _check_path(path)
    header, flat = _read(path)
    header = check_header(path, header)
    if env_layout is None:
        trained_sensed = header['architecture'].get('uncertain', 0) == 1
        known = header['track'] == 'full' or header['layout'].startswith(PHASED_PREFIX)
        known = known or trained_sensed
        env_layout = header['layout'] if known else policy_layout('full')
    check_layout(header['layout'], without_size(env_layout), str(path))
    _check_params(path, flat, header['architecture'])
    return _unflatten({name: value.astype(np.float32) for name, value in flat.items()}), header


def _check_path(path: Path) -> None:
    try:
        info = path.stat()
    except FileNotFoundError:
        raise PolicyFileError(
            f'{path}: no such policy file (train one: python -m '
            'stealth_learn.train_generalist --help)'
        ) from None
    except OSError as error:
        raise PolicyFileError(f'{path}: cannot read the policy file ({_reason(error)})') from None
    if stat.S_ISDIR(info.st_mode):
        raise PolicyFileError(f'{path}: is a directory, expected a generalist policy file (.npz)')
    if not stat.S_ISREG(info.st_mode):
        raise PolicyFileError(
            f'{path}: not a regular file, expected a generalist policy file (.npz)'
        )
    if info.st_size == 0:
        raise PolicyFileError(
            f'{path}: empty file (0 bytes), expected a generalist policy file (.npz with '
            f'{HEADER} and the parameters)'
        )
    if info.st_size > MAX_FILE_BYTES:
        raise PolicyFileError(
            f'{path}: {info.st_size} bytes, larger than any generalist policy file '
            f'(at most {MAX_FILE_BYTES} bytes)'
        )


def _read(path: Path) -> tuple[object, dict[str, np.ndarray]]:
    """(the header's JSON value, {parameter name: array}), or PolicyFileError."""
    try:
        with path.open('rb') as stream:
            start = stream.read(len(ZIP_MAGIC))
            stream.seek(0)
            if start.startswith(NPY_MAGIC):
                raise PolicyFileError(f'{path}: a single .npy array, expected an .npz archive')
            if start != ZIP_MAGIC:  # np.load would try it as a pickle
                raise PolicyFileError(
                    f'{path}: not an npz archive (it does not start as a zip file), expected a '
                    'generalist policy file'
                )
            with np.load(stream, allow_pickle=False) as data:
                text, arrays = _members(path, data)
    except PolicyFileError:
        raise
    except OSError as error:
        raise PolicyFileError(f'{path}: cannot read the policy file ({_reason(error)})') from None
    except Exception as error:  # noqa: BLE001 -- any failure to parse the bytes is a corrupt file
        kind = type(error)
        name = (
            kind.__name__
            if kind.__module__ == 'builtins'
            else f'{kind.__module__}.{kind.__name__}'
        )
        first = str(error).strip().splitlines()
        detail = f'{name}: {first[0][:200]}' if first else name
        raise PolicyFileError(
            f'{path}: not a readable generalist policy file (a damaged npz: {detail})'
        ) from None
    if text.ndim != 0 or text.dtype.kind != 'U':
        raise PolicyFileError(
            f'{path}: {HEADER}: expected one JSON string, got an array of {text.dtype} '
            f'{text.shape}'
        )
    try:
        header = json.loads(str(text), object_pairs_hook=_unique_keys)
    except ValueError as error:  # JSONDecodeError and a duplicated key
        raise PolicyFileError(f'{path}: {HEADER}: not valid JSON ({error})') from None
    return header, {name[len(PARAMS) :]: array for name, array in arrays.items()}


def _members(path: Path, data) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """(the header array, the parameters' arrays) of an open npz; its size, the number of its
    arrays and their names are checked before any is read."""
    unpacked = sum(info.file_size for info in data.zip.infolist())
    if unpacked > MAX_FILE_BYTES:
        raise PolicyFileError(
            f'{path}: the archive unpacks to {unpacked} bytes, more than any generalist policy '
            f'file (at most {MAX_FILE_BYTES})'
        )
    if len(data.files) > MAX_ARRAYS:
        raise PolicyFileError(
            f'{path}: {len(data.files)} arrays, more than any generalist policy file (at most '
            f'{MAX_ARRAYS})'
        )
    twice = sorted(name for name, count in Counter(data.files).items() if count > 1)
    if twice:
        raise PolicyFileError(f'{path}: array {twice[0]!r} stored twice in the archive')
    if HEADER not in data.files:
        raise PolicyFileError(
            f'{path}: not a generalist policy file (no {HEADER}; expected format {FORMAT})'
        )
    unexpected = sorted(n for n in data.files if n != HEADER and not n.startswith(PARAMS))
    if unexpected:
        raise PolicyFileError(
            f'{path}: unexpected array {unexpected[0]!r} (expected {HEADER} and {PARAMS}*)'
        )
    return data[HEADER], {name: np.asarray(data[name]) for name in data.files if name != HEADER}


def _unique_keys(pairs: list) -> dict:
    """json's object hook: a field given twice is an error (json keeps the last silently)."""
    seen = set()
    for key, _ in pairs:
        if key in seen:
            raise ValueError(f'field {key!r} given twice')
        seen.add(key)
    return dict(pairs)


def check_header(path, header) -> dict:
    """``header`` if every field has its type and range (module docstring), else
    PolicyFileError naming the file and the field: ``<path> header: field 'architecture.
    iterations': expected an integer 1..10000, got 100000000``."""
    if not isinstance(header, dict):
        raise PolicyFileError(
            f'{path}: {HEADER}: expected a JSON object of header fields, got '
            f'{type(header).__name__}'
        )
    fields = FieldReader(f'{path} header', header, PolicyFileError)
    fields.reject_unknown(('format', 'layout', 'track', 'architecture', 'training'))
    if fields.string('format', f'{FORMAT!r} (a generalist policy file)') != FORMAT:
        fields.fail('format', f'{FORMAT!r} (a generalist policy file)', header['format'])
    layouts = [policy_layout(track) for track in TRACKS]
    expected = f'one of {", ".join(layouts)} (or a phased grid: {PHASED_PREFIX}full/...)'
    layout = fields.string('layout', expected)
    if layout not in layouts and not layout.startswith(PHASED_PREFIX):
        fields.fail('layout', expected, layout)
    track = fields.string('track', f'one of {", ".join(TRACKS)}')
    if track not in TRACKS or layout.split('/')[1:2] != [track]:
        fields.fail('track', f"the layout's track ({'/'.join(layout.split('/')[1:2])})", track)
    architecture = fields.mapping('architecture', 'a mapping')
    phased = any(architecture.has(name) for name in PHASED_RANGES)
    ranges = {**ARCHITECTURE_RANGES, **(PHASED_RANGES if phased else {})}
    ranges.update(UNCERTAIN_RANGES if architecture.has('uncertain') else {})
    ranges.update(CAP_RANGES if architecture.has('distance_cap') else {})
    _check_ranges(architecture, ranges, True)
    if phased:
        layers = architecture.values['layers']
        architecture.integer('advance', f'an integer 0..{layers - 1} (< layers)',
                             lambda v: v < layers)  # fmt: skip
    if policy_layout(track, architecture.values) != layout:
        fields.fail('layout', f"{policy_layout(track, architecture.values)!r} (the "
                    "architecture's)", layout)  # fmt: skip
    if fields.has('training'):
        training = fields.mapping('training', 'a mapping of the training record')
        _check_ranges(training, TRAINING_FIELDS, False, extra=(SIZES,))
        steps = training.values.get('steps')
        if training.has('selected_step') and steps is not None:
            training.integer('selected_step', f'an integer 0..{steps} (steps)',
                             lambda v: v <= steps)  # fmt: skip
        if training.has(SIZES):
            _check_sizes(training)
    return header


def _check_ranges(fields: FieldReader, ranges: dict, required: bool, extra=()) -> None:
    fields.reject_unknown((*ranges, *extra))
    for name, valid in ranges.items():
        if not required and not fields.has(name):
            continue
        read = fields.integer if valid.integer else fields.number
        read(name, valid.text, valid.holds)


def _check_sizes(training: FieldReader) -> None:
    sizes = training.values[SIZES]
    expected = 'a list of [width m, height m, lights], whole numbers >= 1'
    if not isinstance(sizes, list) or not all(
        isinstance(size, list)
        and len(size) == 3
        and all(isinstance(v, int) and not isinstance(v, bool) and v >= 1 for v in size)
        for size in sizes
    ):
        training.fail(SIZES, expected, sizes)


@functools.lru_cache(maxsize=16)
def _shapes(architecture: tuple) -> dict[str, tuple[int, ...]]:
    from stealth_learn.jax_deps import jax, jnp
    from stealth_learn.vin import Vin

    # abstract key and grid: no backend starts (no XLA threads in a process that forks later)
    key = jax.ShapeDtypeStruct((2,), jnp.uint32)
    model = Vin(**dict(architecture))
    grid = jax.ShapeDtypeStruct((1, *model.grid_shape(3, 3)), jnp.float32)
    tree = jax.eval_shape(model.init, key, grid)['params']
    return {name: tuple(leaf.shape) for name, leaf in _flatten(tree).items()}


def expected_shapes(architecture: dict) -> dict[str, tuple[int, ...]]:
    """{parameter name: shape} of the network of ``architecture`` (``vin.Vin``'s fields),
    found by initialising it abstractly (``jax.eval_shape``): any grid, no computation."""
    return dict(_shapes(tuple(sorted(architecture.items()))))


def _check_params(path: Path, flat: dict[str, np.ndarray], architecture: dict) -> None:
    shapes = expected_shapes(architecture)
    sizes = ', '.join(f'{name} {architecture[name]}' for name in ('hidden', 'features'))
    for name, shape in shapes.items():
        if name not in flat:
            raise PolicyFileError(
                f'{path}: parameter {name!r} is missing (expected shape {shape} for the '
                f"header's architecture: {sizes})"
            )
    for name, value in sorted(flat.items()):
        if name not in shapes:
            raise PolicyFileError(
                f"{path}: unexpected parameter {name!r} (the header's architecture has "
                f'{", ".join(shapes)})'
            )
        if value.shape != shapes[name]:
            raise PolicyFileError(
                f"{path}: parameter {name!r}: expected shape {shapes[name]} for the header's "
                f'architecture ({sizes}), found {value.shape}'
            )
        if value.dtype.kind != 'f':
            raise PolicyFileError(
                f'{path}: parameter {name!r}: expected floating-point values, found {value.dtype}'
            )
        with np.errstate(over='ignore'):  # float64 beyond float32: inf, counted below
            bad = int(np.count_nonzero(~np.isfinite(value.astype(np.float32))))
        if bad:
            raise PolicyFileError(
                f'{path}: parameter {name!r}: {bad} of {value.size} values not finite (NaN or '
                'infinite in float32): the file is corrupt'
            )


def _reason(error: OSError) -> str:
    return error.strerror or str(error) or type(error).__name__


def _flatten(tree, prefix: str = '') -> dict:
    out = {}
    for key, value in tree.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict) or hasattr(value, 'items'):
            out.update(_flatten(value, name + '/'))
        else:
            out[name] = value
    return out


def _unflatten(flat: dict) -> dict:
    tree: dict = {}
    for name, value in flat.items():
        node = tree
        *parents, leaf = name.split('/')
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = value
    return tree
