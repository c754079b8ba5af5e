"""Fuzzing the generalist's weights file (issue 40): over 200 files mutated from the shipped
weights by a seeded generator (truncations, bit flips, wrong shapes, missing and extra
parameters, NaN and infinities, wrong dtypes, header fields of the wrong type or out of range,
files that are no npz, paths that are no file). Each one is refused by ``policy_file.load`` in
one line naming the file (PolicyFileError; a well-formed file of another track: LayoutError,
naming both layouts), or, where the mutation leaves a valid file, loads and runs: the network's
logits on a generated building, equal to the shipped weights' where the parameters are the
same. Each file gets 5 s, load and run together."""

from collections import Counter
import contextlib
import gzip
import io
import json
import math
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import time
import warnings
import zipfile

import numpy as np
import pytest
from stealth_learn import generalist_data as data
from stealth_learn import policy_file
from stealth_learn.env_tables import TaskArrays
from stealth_learn.generalist import GeneralistPolicy
from stealth_learn.obs_layout import LayoutError

SEED = 40
PER_FILE = 5.0  # s: load, and the network's run where the file is valid
ENV_LAYOUT = policy_file.policy_layout('full')
SHIPPED = policy_file.SHIPPED

# what a mutation may give: refused; valid with the shipped parameters and architecture
# ('same'); valid with other values ('valid'); refused or the same (a damaged byte that the
# zip format may not notice, as a timestamp's)
REFUSED, SAME, VALID, EITHER = 'refused', 'same', 'valid', 'refused or same'


def _shipped():
    with np.load(SHIPPED) as stored:
        arrays = {name: np.array(stored[name]) for name in stored.files}
    header = json.loads(str(arrays.pop(policy_file.HEADER)))
    return arrays, header


def _npz(path: Path, arrays: dict, header) -> None:
    """An npz of ``arrays`` and the header: a dict (as JSON), a str (the JSON text as is) or
    an array (stored as it is)."""
    if isinstance(header, dict):
        header = json.dumps(header)
    stored = dict(arrays)
    if header is not None:
        stored[policy_file.HEADER] = np.asarray(header)
    with path.open('wb') as stream:
        np.savez_compressed(stream, **stored)


class Mutations:
    """(kind, expected, path) of every mutated file, written into ``directory``."""

    def __init__(self, directory: Path):
        self.directory = directory
        self.rng = np.random.default_rng(SEED)
        self.arrays, self.header = _shipped()
        self.raw = SHIPPED.read_bytes()
        self.cases: list[tuple[str, str, Path]] = []

    def path(self, kind: str) -> Path:
        return self.directory / f'{len(self.cases):03d}-{kind}.npz'

    def add(self, kind: str, expected: str, path: Path) -> None:
        self.cases.append((kind, expected, path))

    def write_bytes(self, kind: str, expected: str, content: bytes) -> None:
        path = self.path(kind)
        path.write_bytes(content)
        self.add(kind, expected, path)

    def write_npz(self, kind: str, expected: str, arrays=None, header=None) -> None:
        path = self.path(kind)
        _npz(path, self.arrays if arrays is None else arrays,
             self.header if header is None else header)  # fmt: skip
        self.add(kind, expected, path)

    def header_with(self, kind: str, expected: str, where: tuple, value) -> None:
        """The header with the field at ``where`` (keys) set to ``value`` (or removed: ...)."""
        header = json.loads(json.dumps(self.header))
        node = header
        for key in where[:-1]:
            node = node[key]
        if value is ...:
            del node[where[-1]]
        else:
            node[where[-1]] = value
        self.write_npz(kind, expected, header=json.dumps(header, allow_nan=True))

    def all(self) -> list[tuple[str, str, Path]]:
        self.truncations()
        self.bit_flips()
        self.shapes()
        self.missing_and_extra()
        self.values()
        self.header_fields()
        self.headers()
        self.foreign_files()
        self.paths()
        return self.cases

    def truncations(self) -> None:
        size = len(self.raw)
        offsets = {0, 1, 4, 30, size - 22, size - 1, *self.rng.integers(1, size, 34).tolist()}
        for offset in sorted(offsets):
            self.write_bytes('truncation', REFUSED, self.raw[:offset])

    def bit_flips(self) -> None:
        for _ in range(50):
            flipped = bytearray(self.raw)
            for _ in range(int(self.rng.integers(1, 4))):  # 1 to 3 bits
                offset = int(self.rng.integers(0, len(flipped)))
                flipped[offset] ^= 1 << int(self.rng.integers(0, 8))
            self.write_bytes('bit flip', EITHER, bytes(flipped))

    def shapes(self) -> None:
        for name in self.params():
            value = self.arrays[name]
            variants = [value.reshape(*value.shape, 1), np.zeros((*value.shape, 2), value.dtype)]
            if value.ndim:
                grown = list(value.shape)
                grown[int(self.rng.integers(0, value.ndim))] += 1
                variants += [np.zeros(grown, value.dtype), value.reshape(-1)[:-1]]
                if value.ndim > 1:
                    variants.append(value.T)
            else:
                variants.append(value.reshape(1))
            for variant in variants:
                if variant.shape == value.shape:
                    continue
                self.write_npz('wrong shape', REFUSED, {**self.arrays, name: variant})

    def missing_and_extra(self) -> None:
        for name in self.params():
            arrays = {k: v for k, v in self.arrays.items() if k != name}
            self.write_npz('missing parameter', REFUSED, arrays)
        for name in ('params/extra', 'params/context/other', 'params/scale2', 'weights', 'x/y'):
            arrays = {**self.arrays, name: np.zeros(3, np.float32)}
            self.write_npz('extra parameter', REFUSED, arrays)
        self.write_npz('extra parameter', REFUSED, {'params/only': np.zeros(1, np.float32)})

    def values(self) -> None:
        for name in self.params():
            for bad in (np.nan, np.inf, -np.inf):
                value = self.arrays[name].copy()
                value.reshape(-1)[int(self.rng.integers(0, max(value.size, 1)))] = bad
                self.write_npz('NaN or infinity', REFUSED, {**self.arrays, name: value})
        big = self.arrays['params/scale'].astype(np.float64) * 1e300  # inf in float32
        self.write_npz('NaN or infinity', REFUSED, {**self.arrays, 'params/scale': big})
        name = 'params/reward_hidden/kernel'
        for dtype, expected in ((np.int32, REFUSED), (np.complex64, REFUSED),
                                (np.bool_, REFUSED), (np.float64, SAME)):  # fmt: skip
            value = self.arrays[name].astype(dtype)
            self.write_npz('dtype', expected, {**self.arrays, name: value})
        value = self.arrays[name].astype(np.float16)
        self.write_npz('dtype', VALID, {**self.arrays, name: value})

    def header_fields(self) -> None:
        """Every field: of the wrong type, out of range, missing; and valid other values."""
        arch = ('architecture',)
        cases = [
            (('format',), [1, None, [], 'stealth-generalist-v2', '', ...], REFUSED),
            (
                ('layout',),
                [5, None, 'stealth-vector-v1/full', 'stealth-grid-v1', 'x', ...],
                REFUSED,
            ),
            (('track',), [3, None, 'sensed', 'both', '', ...], REFUSED),
            (arch, [[], 'x', 1, None, {}, ...], REFUSED),
            (
                (*arch, 'iterations'),
                [0, -1, -240, 10_001, 100_000_000, 1e8, 240.0, '240', True, None, [240], ...],
                REFUSED,
            ),
            ((*arch, 'hidden'), [0, -32, 1025, 32.5, '32', False, None, 16, 64, ...], REFUSED),
            ((*arch, 'features'), [0, 257, 8.0, '8', None, 4, ...], REFUSED),
            ((*arch, 'threshold'), [0, -0.3, math.nan, math.inf, '0.3', True, None, ...], REFUSED),
            ((*arch, 'extra'), [1], REFUSED),
            (('training',), [[], 'x', 1, None], REFUSED),
            (('training', 'steps'), [0, -1, 2.5, '2000'], REFUSED),
            (('training', 'lr'), [0, -0.005, math.nan, math.inf, 'fast'], REFUSED),
            (('training', 'seed'), [-1, 0.5], REFUSED),
            (('training', 'selected_step'), [-1, 2001, 1650.5], REFUSED),
            (('training', 'validation_loss'), [-0.1, math.nan], REFUSED),
            (('training', 'seconds'), [-1, math.inf], REFUSED),
            (('training', 'train_iterations'), [0, 10_001], REFUSED),
            (('training', 'sizes'), [[[20, 20]], [[20, 20, 0]], 'big', [[20, 20, 3.5]]], REFUSED),
            (('training', 'note'), ['unknown field'], REFUSED),
            (('note',), ['unknown field'], REFUSED),
            ((*arch, 'iterations'), [1, 60, policy_file.MAX_ITERATIONS], VALID),
            ((*arch, 'threshold'), [0.5, 2], VALID),
            (('training',), [...], SAME),  # optional
            (('training', 'seconds'), [0, 1e6], SAME),
        ]
        for where, values, expected in cases:
            for value in values:
                self.header_with('header field', expected, where, value)

    def headers(self) -> None:
        """The header as a whole: not JSON, not an object, not one string, twice, missing."""
        text = json.dumps(self.header)
        for header in (text[:-1], text + 'x', '', '[]', '"a string"', '42', 'null',
                       text.replace('{', '{"format": 1, ', 1),  # a field given twice
                       ):  # fmt: skip
            self.write_npz('header', REFUSED, header=header)
        for header in (np.array([text, text]), np.array(text.encode()), np.array(3.0),
                       np.frombuffer(text.encode(), np.uint8)):  # fmt: skip
            self.write_npz('header', REFUSED, header=header)
        path = self.path('header')
        _npz(path, self.arrays, None)
        self.add('header', REFUSED, path)
        self.write_npz('header', SAME, header=json.dumps(self.header, indent=2, sort_keys=True))
        sensed = {**self.header, 'layout': policy_file.policy_layout('sensed'), 'track': 'sensed'}
        self.write_npz('header', REFUSED, header=sensed)  # another track's: LayoutError
        # the same array stored twice in the archive
        path = self.path('header')
        with zipfile.ZipFile(io.BytesIO(self.raw)) as source:
            members = [(info.filename, source.read(info)) for info in source.infolist()]
        with zipfile.ZipFile(path, 'w') as out, warnings.catch_warnings():
            warnings.simplefilter('ignore')  # zipfile's 'Duplicate name': what this case is
            for name, content in [*members, members[-2]]:
                out.writestr(name, content)
        self.add('header', REFUSED, path)

    def foreign_files(self) -> None:
        self.write_bytes('not an npz', REFUSED, b'not a zip at all\n')
        self.write_bytes('not an npz', REFUSED, self.rng.bytes(5000))
        self.write_bytes('not an npz', REFUSED, gzip.compress(self.raw))
        self.write_bytes('not an npz', REFUSED, json.dumps(self.header).encode())
        self.write_bytes('not an npz', REFUSED, SHIPPED.with_suffix('.png').read_bytes())
        stream = io.BytesIO()
        np.save(stream, np.zeros(3))
        self.write_bytes('not an npz', REFUSED, stream.getvalue())
        stream = io.BytesIO()
        np.savez(stream, data=np.array([{'a': 1}], dtype=object))
        self.write_bytes('not an npz', REFUSED, stream.getvalue())
        stream = io.BytesIO()
        with zipfile.ZipFile(stream, 'w') as archive:
            archive.writestr('readme.txt', 'hello')
        self.write_bytes('not an npz', REFUSED, stream.getvalue())
        # bigger than any weights file: on disk (sparse), and unpacked (a zip bomb's kind)
        path = self.path('too large')
        with path.open('wb') as stream:
            stream.truncate(policy_file.MAX_FILE_BYTES + 1)
        self.add('too large', REFUSED, path)
        big = {**self.arrays, 'params/big': np.zeros(10_000_000, np.float32)}
        self.write_npz('too large', REFUSED, big)
        many = {f'params/extra/{k}': np.zeros(1, np.float32) for k in range(2000)}
        self.write_npz('too large', REFUSED, {**self.arrays, **many})
        wide = {**self.header, **{f'note{k}': k for k in range(50_000)}}
        self.write_npz('too large', REFUSED, header=wide)

    def paths(self) -> None:
        directory = self.path('directory')
        directory.mkdir()
        self.add('directory', REFUSED, directory)
        self.add('missing file', REFUSED, self.path('missing file'))
        self.write_bytes('empty file', REFUSED, b'')
        broken = self.path('broken link')
        broken.symlink_to(self.directory / 'nowhere.npz')
        self.add('missing file', REFUSED, broken)
        loop = self.path('link loop')
        loop.symlink_to(loop)
        self.add('unreadable', REFUSED, loop)
        fifo = self.path('fifo')
        os.mkfifo(fifo)  # opening it for reading would wait for a writer forever
        self.add('not a regular file', REFUSED, fifo)

    def params(self) -> list[str]:
        return sorted(name for name in self.arrays if name.startswith(policy_file.PARAMS))


@contextlib.contextmanager
def _deadline(seconds: float, what: str):
    """TimeoutError if the block takes longer than ``seconds`` (a hang fails, not blocks)."""

    def expire(signum, frame):
        raise TimeoutError(f'{what}: over {seconds:g} s')

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


@pytest.fixture(scope='module')
def building(generated):
    return data.grid_of(TaskArrays(generated['still']).tables())


class Runner:
    """Loads a file and, when it is accepted, runs the network on a building."""

    def __init__(self, building):
        self.building = building
        self.shipped, self.header = policy_file.load(SHIPPED, ENV_LAYOUT)
        self.policies = {}  # architecture -> a policy, its network compiled once
        self.logits = self.run(self.shipped, self.header['architecture'])

    def run(self, params, architecture) -> np.ndarray:
        key = json.dumps(architecture, sort_keys=True)
        if key not in self.policies:
            self.policies[key] = GeneralistPolicy(params, architecture)
        policy = self.policies[key]
        policy.variables = {'params': params}
        return policy.cell_logits(self.building)

    def outcome(self, kind: str, expected: str, path: Path) -> str:
        """'refused' or 'ran', after checking the refusal's line or the run's result."""
        try:
            params, header = policy_file.load(path, ENV_LAYOUT)
        except (policy_file.PolicyFileError, LayoutError) as error:
            message = str(error)
            assert expected in (REFUSED, EITHER), f'{kind} {path.name}: refused: {message}'
            assert '\n' not in message and str(path) in message, message
            return 'refused'
        assert expected != REFUSED, f'{kind} {path.name}: accepted'
        logits = self.run(params, header['architecture'])
        assert logits.shape == self.logits.shape and np.isfinite(logits).all(), path.name
        if expected in (SAME, EITHER):  # the shipped parameters: the shipped decisions
            for name, value in policy_file._flatten(self.shipped).items():
                np.testing.assert_array_equal(policy_file._flatten(params)[name], value)
            np.testing.assert_array_equal(logits, self.logits)
        if expected == EITHER:
            assert header == self.header, path.name
        return 'ran'


def test_over_200_mutated_weights_files_refused_in_one_line_or_valid_and_run(tmp_path, building):
    cases = Mutations(tmp_path).all()
    runner = Runner(building)
    outcomes, problems = Counter(), []
    for kind, expected, path in cases:
        started = time.monotonic()
        try:
            with _deadline(PER_FILE, f'{kind} {path.name}'):
                outcomes[kind, runner.outcome(kind, expected, path)] += 1
        except Exception as error:  # noqa: BLE001 -- every file's problem, listed at the end
            problems.append(f'{kind} {path.name}: {type(error).__name__}: {error}'[:300])
            continue
        if time.monotonic() - started >= PER_FILE:
            problems.append(f'{kind} {path.name}: {time.monotonic() - started:.1f} s')
    counts = Counter(kind for kind, _, _ in cases)
    print('\n' + '\n'.join(
        f'{kind}: {n} ({outcomes[kind, "refused"]} refused, {outcomes[kind, "ran"]} valid and '
        'run)' for kind, n in counts.items()))  # fmt: skip
    assert not problems, f'{len(problems)} of {len(cases)} files:\n' + '\n'.join(problems)
    assert len(cases) >= 200
    # the mutations the format cannot hide are all refused
    for kind in ('truncation', 'wrong shape', 'missing parameter', 'extra parameter',
                 'NaN or infinity', 'not an npz', 'directory', 'missing file', 'empty file',
                 'unreadable', 'not a regular file', 'too large'):  # fmt: skip
        assert outcomes[kind, 'ran'] == 0, kind


def test_an_unreadable_file_is_refused_naming_it(tmp_path):
    """Permission denied (as an unprivileged user when the tests run as root, where the mode
    bits do not hold): named in one line, as every other refusal."""
    directory = Path(tempfile.mkdtemp(prefix='unreadable-'))
    try:
        directory.chmod(0o755)  # nobody may look into it, not read the file
        path = directory / 'weights.npz'
        path.write_bytes(SHIPPED.read_bytes())
        path.chmod(0)
        script = (
            'import os, sys\n'
            'from stealth_learn import policy_file\n'
            'if os.geteuid() == 0:\n'
            '    os.setgid(65534); os.setuid(65534)\n'
            'try:\n'
            '    policy_file.load(sys.argv[1], sys.argv[2])\n'
            'except policy_file.PolicyFileError as error:\n'
            '    sys.exit(str(error))\n'
        )
        done = subprocess.run(
            [sys.executable, '-c', script, str(path), ENV_LAYOUT],
            capture_output=True, text=True, timeout=60, check=False,
        )  # fmt: skip
    finally:
        for entry in directory.iterdir():
            entry.unlink()
        directory.rmdir()
    assert done.returncode == 1, done.stderr
    assert done.stderr.strip() == (f'{path}: cannot read the policy file (Permission denied)'), (
        done.stderr
    )
