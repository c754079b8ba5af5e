"""The visibility field cached on disk, per scenario, so that a second load is instant.

A field is stored under the hash of everything it depends on (:func:`cache_key`: the map, the
lights, the time, the code's version, the bounce), as one ``.npz`` written whole or not at all;
a corrupt or mismatched file is recomputed, and a cache that cannot be written only warns.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
import hashlib
import os
from pathlib import Path
import tempfile
import warnings
import zipfile

import numpy as np

from stealth_core.bounce import Bounce
from stealth_core.searchlight import Searchlight
from stealth_core.visibility import active_bounce, visibility_field

# Bump whenever the model or the field's output changes: it is part of every cache key.
CODE_VERSION = 'visibility-1'
BOUNCE_VERSION = 'bounce-1'  # part of the key of fields with a bounce only
CACHE_ENV = 'STEALTH_NAV_CACHE'
DEFAULT_CACHE_DIR = Path('~/.cache/stealth_nav/visibility')


def cache_key(
    blocked: np.ndarray,
    resolution: float,
    origin: Sequence[float],
    lights: Iterable[Searchlight],
    t: float = 0.0,
    bounce: Bounce | None = None,
) -> str:
    """Hash of everything the field depends on, including CODE_VERSION (and, with a bounce,
    BOUNCE_VERSION and the bounce: without one the key is what it was before bounces)."""
    digest = hashlib.sha256()
    digest.update(CODE_VERSION.encode())
    digest.update(repr((blocked.shape, str(blocked.dtype))).encode())
    digest.update(np.ascontiguousarray(blocked).tobytes())
    parameters = (float(resolution), tuple(float(v) for v in origin), tuple(lights), float(t))
    digest.update(repr(parameters).encode())
    bounce = active_bounce(bounce)
    if bounce is not None:
        digest.update(repr((BOUNCE_VERSION, bounce)).encode())
    return digest.hexdigest()


def cache_directory(cache_dir: str | os.PathLike | None = None) -> Path:
    """The argument, else $STEALTH_NAV_CACHE, else ~/.cache/stealth_nav/visibility."""
    chosen = cache_dir or os.environ.get(CACHE_ENV) or DEFAULT_CACHE_DIR
    return Path(chosen).expanduser()


def _load(path: Path, n_lights: int, shape: tuple[int, int]):
    """The cached arrays, or None when missing, unreadable or of the wrong shape."""
    try:
        with np.load(path, allow_pickle=False) as data:
            total, per_light = data['total'], data['per_light']
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        return None
    if total.shape != shape or per_light.shape != (n_lights, *shape):
        return None
    if not (np.all(np.isfinite(total)) and np.all(np.isfinite(per_light))):
        return None
    return total, per_light


def _save(path: Path, total: np.ndarray, per_light: np.ndarray) -> None:
    """Write atomically: a temporary file in the same directory, then os.replace."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=path.stem, suffix='.tmp')
    try:
        with os.fdopen(handle, 'wb') as stream:
            np.savez_compressed(stream, total=total, per_light=per_light)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def cached_visibility_field(
    blocked: np.ndarray,
    resolution: float,
    origin: Sequence[float],
    lights: Iterable[Searchlight],
    t: float = 0.0,
    cache_dir: str | os.PathLike | None = None,
    bounce: Bounce | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``visibility_field`` through the disk cache; a corrupt cache file is recomputed."""
    lights = tuple(lights)
    key = cache_key(blocked, resolution, origin, lights, t, bounce)
    path = cache_directory(cache_dir) / f'{key}.npz'
    cached = _load(path, len(lights), blocked.shape)
    if cached is not None:
        return cached
    total, per_light = visibility_field(blocked, resolution, origin, lights, t, bounce)
    try:
        _save(path, total, per_light)
    except OSError as error:  # a read-only cache must not stop the robot; the field is right
        warnings.warn(f'visibility cache not written to {path}: {error}', stacklevel=2)
    return total, per_light


def scenario_visibility(scenario, t: float = 0.0, cache_dir=None):
    """(total, per_light) of a ``stealth_core.scenario.Scenario`` at time t, cached; total
    includes the scenario's bounce, if it has one."""
    occupancy = scenario.map
    return cached_visibility_field(
        occupancy.blocked,
        occupancy.resolution,
        occupancy.origin,
        scenario.lights,
        t,
        cache_dir,
        bounce=getattr(scenario, 'bounce', None),
    )
