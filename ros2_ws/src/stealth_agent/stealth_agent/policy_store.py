"""Policy files: the Q-table with everything needed to resume or evaluate it (no rclpy).

One `.npz` archive (numpy, loaded with allow_pickle=False) holding

- ``q``: the Q-table, float64 (rows, actions);
- ``state_keys``: the state index in row order, float32 state values (exact mapping) or int64
  bins (grid mapping);
- ``model_*``: Dyna-Q's learned model (dyna only);
- ``meta``: a JSON string: format and version, learner name, hyperparameters and schedules,
  action count, state dimension, state mapping, finished episodes and updates, the scenario
  identity (the environment description, title first, and, when the run gave them, the
  SHA-256 of the map's grid and of the lights: CONTENT_KEYS), the random generator's state (so a
  resumed run continues the same random stream), when it was saved and free-form extras.

Writes are atomic: a temporary file in the same directory, fsync, then os.replace, so a crash
leaves either the old or the new file, never a torn one. Loading checks everything and raises
PolicyFileError naming the file and the problem; check_compatible raises PolicyMismatchError
naming the file and every mismatch (action count, state dimension, learner, scenario, mapping).
"""

import contextlib
from dataclasses import dataclass
import datetime
import json
import os
import pathlib
import tempfile

import numpy as np

from .learners import LEARNER_NAMES, LearnerConfig, TabularLearner, make_learner
from .state_index import StateIndex, StateMapping

FORMAT = 'stealth-nav tabular policy'
FORMAT_VERSION = 1
ZIP_MAGIC = b'PK\x03\x04'  # every .npz is a zip archive
# The scenario identity by content (stealth_core.scenario.content_identity), in the scenario
# meta beside the title when the run knew it: files saved before have none.
CONTENT_KEYS = ('grid_sha256', 'lights_sha256')


class PolicyFileError(ValueError):
    """A policy file that cannot be read or used."""


class PolicyMismatchError(PolicyFileError):
    """A readable policy file made for a different environment or learner."""


@dataclass
class SavedPolicy:
    """A loaded policy file."""

    path: pathlib.Path
    learner: TabularLearner
    index: StateIndex
    meta: dict

    @property
    def scenario(self) -> dict:
        return self.meta.get('scenario') or {}

    def restored_rng(self) -> np.random.Generator | None:
        """A generator continuing the saved random stream, or None if none was saved."""
        return restore_rng(self.meta.get('rng_state'))


def restore_rng(state) -> np.random.Generator | None:
    """A PCG64 generator set to a saved `bit_generator.state`, None when not restorable."""
    if not isinstance(state, dict) or state.get('bit_generator') != 'PCG64':
        return None
    rng = np.random.default_rng()
    try:
        rng.bit_generator.state = state
    except (TypeError, ValueError, KeyError):
        return None
    return rng


def save_policy(
    path,
    learner: TabularLearner,
    index: StateIndex,
    *,
    scenario: dict | None = None,
    rng: np.random.Generator | None = None,
    extra: dict | None = None,
) -> dict:
    """Write the policy atomically; returns the metadata written."""
    path = pathlib.Path(path)
    learner.ensure_rows(len(index))
    if learner.num_rows != len(index):
        raise ValueError(
            f'the table has {learner.num_rows} rows but the state index only {len(index)}'
        )
    meta = {
        'format': FORMAT,
        'version': FORMAT_VERSION,
        **learner.to_meta(),
        'state_dim': index.dim,
        'state_mapping': index.mapping.to_dict(),
        'num_states': len(index),
        'scenario': scenario or {},
        'rng_state': rng.bit_generator.state if rng is not None else None,
        'saved_at': datetime.datetime.now(datetime.UTC).isoformat(timespec='seconds'),
        'extra': extra or {},
    }
    arrays = learner.to_arrays()
    arrays['state_keys'] = index.keys_array()
    arrays['meta'] = np.array(json.dumps(meta))
    write_atomically(path, lambda f: np.savez(f, **arrays))
    return meta


def write_atomically(path: pathlib.Path, write) -> None:
    """Call write(binary file) on a temporary file beside `path`, then move it into place."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f'.{path.name}.', suffix='.tmp', dir=path.parent)
    try:
        with os.fdopen(fd, 'wb') as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    with contextlib.suppress(OSError):
        dir_fd = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)


def load_policy(path) -> SavedPolicy:
    """Read and check a policy file; PolicyFileError naming the file and the problem."""
    path = pathlib.Path(path)
    if not path.is_file():
        raise PolicyFileError(f'policy file {path}: no such file')
    try:
        with open(path, 'rb') as f:
            head = f.read(4)
    except OSError as error:
        raise PolicyFileError(f'policy file {path}: cannot be read ({error})') from None
    if head != ZIP_MAGIC:
        what = 'it is empty' if not head else f'it starts with {head!r}'
        raise PolicyFileError(f'policy file {path}: corrupt or not a policy archive ({what})')
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except Exception as error:  # any reader failure means the same thing: unusable file
        raise PolicyFileError(
            f'policy file {path}: corrupt or not a policy archive '
            f'({type(error).__name__}: {error})'
        ) from None
    try:
        return _policy_from_arrays(path, arrays)
    except PolicyFileError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError) as error:
        raise PolicyFileError(
            f'policy file {path}: corrupt contents ({type(error).__name__}: {error})'
        ) from None


def _policy_from_arrays(path: pathlib.Path, arrays: dict) -> SavedPolicy:
    for name in ('meta', 'q', 'state_keys'):
        if name not in arrays:
            raise PolicyFileError(f'policy file {path}: corrupt, the array {name!r} is missing')
    meta = json.loads(str(arrays['meta'][()]))
    if not isinstance(meta, dict) or meta.get('format') != FORMAT:
        raise PolicyFileError(f'policy file {path}: not a {FORMAT} file')
    if meta.get('version') != FORMAT_VERSION:
        raise PolicyFileError(
            f'policy file {path}: format version {meta.get("version")!r}, '
            f'this agent reads version {FORMAT_VERSION}'
        )
    if meta.get('learner') not in LEARNER_NAMES:
        raise PolicyFileError(f'policy file {path}: unknown learner {meta.get("learner")!r}')
    learner = make_learner(
        meta['learner'], meta['num_actions'], LearnerConfig.from_dict(meta['config'])
    )
    learner.load_arrays(arrays, int(meta['episodes']), int(meta['updates']))
    mapping = StateMapping.from_dict(meta['state_mapping'])
    dim = meta.get('state_dim')
    index = StateIndex.from_keys(mapping, arrays['state_keys'], None if dim is None else int(dim))
    if len(index) != learner.num_rows:
        raise PolicyFileError(
            f'policy file {path}: corrupt, {learner.num_rows} table rows '
            f'but {len(index)} indexed states'
        )
    return SavedPolicy(path, learner, index, meta)


def content_differences(saved: dict, now: dict[str, str]) -> list[str] | None:
    """The CONTENT_KEYS whose hash the policy file records (``saved``: its scenario meta) and
    that differ from ``now`` (``content_identity`` of the scenario asked for): [] when it was
    learned on this map and these lights; None when the file records neither (saved before
    policies did: only its name can be compared)."""
    if not any(saved.get(key) for key in CONTENT_KEYS):
        return None
    return [key for key in CONTENT_KEYS if saved.get(key) and saved[key] != now.get(key)]


def check_compatible(
    policy: SavedPolicy,
    *,
    num_actions: int | None = None,
    state_dim: int | None = None,
    learner: str | None = None,
    scenario_title: str | None = None,
    mapping: StateMapping | None = None,
) -> None:
    """PolicyMismatchError listing every way the policy differs from what is expected.

    Arguments left at None are not checked.
    """
    problems = []
    if num_actions is not None and policy.learner.num_actions != num_actions:
        problems.append(
            f'action count {policy.learner.num_actions} in the file, {num_actions} expected'
        )
    if state_dim is not None and policy.index.dim is not None and policy.index.dim != state_dim:
        problems.append(f'state dimension {policy.index.dim} in the file, {state_dim} expected')
    if learner is not None and policy.learner.name != learner:
        problems.append(f'learner {policy.learner.name!r} in the file, {learner!r} expected')
    saved_title = policy.scenario.get('title')
    if scenario_title is not None and saved_title != scenario_title:
        problems.append(f'scenario {saved_title!r} in the file, {scenario_title!r} expected')
    if mapping is not None and (
        policy.index.mapping.kind != mapping.kind or policy.index.mapping.widths != mapping.widths
    ):
        problems.append(
            f'state mapping {policy.index.mapping.describe()} in the file, '
            f'{mapping.describe()} expected'
        )
    if problems:
        raise PolicyMismatchError(
            f'policy file {policy.path} does not fit: ' + '; '.join(problems)
        )
