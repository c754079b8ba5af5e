"""From the environment's float32[] state vector to a row of the Q-table (no rclpy).

Two mappings, as in rl-texplore-ros-pkg's rl_agent:

- ``exact`` (default; rl_agent's QLearner without --nstates): every distinct state vector (its
  float32 values) gets its own row, in the order first seen. Exact for any environment whose
  states are already discrete; stealth_env sends [x, y] rounded to its state grid (start +
  k*cell, e.g. 0.5 m cells centred on the move lattice's nodes), so each cell is one row and
  nothing needs to know the cell size.
- ``grid`` (rl_agent's DiscretizationAgent, --nstates): each feature is binned with a width,
  either the description's range divided by `nstates` (rl_agent's rule) or a given resolution
  (e.g. the scenario's cell size, which RLEnvDescription cannot carry). As in rl_agent, bins are
  centred on the multiples of the width (bin = floor(x / width + 1/2)), so values that already
  sit on a grid of that width never straddle a bin edge through float rounding.

In both, rows are handed out lazily by a growing index of the keys seen, so the table only holds
visited states, grows without bound and never overflows; a state outside the description's
ranges still gets its own row (the caller may warn, see `out_of_range`).
"""

from dataclasses import dataclass
import math

import numpy as np

MAPPING_KINDS = ('exact', 'grid')


class StateError(ValueError):
    """A state vector that cannot be used (wrong length, non-finite values, ...)."""


@dataclass(frozen=True)
class StateMapping:
    """How state vectors become keys; see the module docstring."""

    kind: str = 'exact'
    widths: tuple[float, ...] = ()  # grid: bin width per feature, or one width for all
    low: tuple[float, ...] = ()  # the description's min_state_range (may be empty)
    high: tuple[float, ...] = ()  # the description's max_state_range (may be empty)

    def __post_init__(self):
        if self.kind not in MAPPING_KINDS:
            raise ValueError(f'unknown state mapping {self.kind!r} (expected exact or grid)')
        if len(self.low) != len(self.high):
            raise ValueError(f'state ranges differ in length: {len(self.low)} vs {len(self.high)}')
        if self.kind == 'grid':
            if not self.widths:
                raise ValueError('a grid state mapping needs bin widths')
            if any(not math.isfinite(w) or w <= 0 for w in self.widths):
                raise ValueError(f'grid bin widths must be finite and > 0, got {self.widths}')
            if len(self.widths) > 1 and self.low and len(self.widths) != len(self.low):
                raise ValueError(
                    f'{len(self.widths)} bin widths for {len(self.low)} state features'
                )
        elif self.widths:
            raise ValueError('an exact state mapping has no bin widths')

    @property
    def dim(self) -> int | None:
        """The state length this mapping implies, or None when only the first state tells."""
        if self.low:
            return len(self.low)
        if self.kind == 'grid' and len(self.widths) > 1:
            return len(self.widths)
        return None

    def key(self, state: np.ndarray) -> tuple:
        """The hashable key of a checked float32 state vector."""
        if self.kind == 'exact':
            return tuple(state.tolist())
        bins = np.floor(state.astype(np.float64) / np.asarray(self.widths) + 0.5)
        return tuple(int(b) for b in bins)

    def out_of_range(self, state: np.ndarray) -> bool:
        """True when the state lies outside the description's ranges (by more than half a bin)."""
        if not self.low:
            return False
        slack = 0.5 * np.asarray(self.widths) if self.kind == 'grid' else 1e-6
        low, high = np.asarray(self.low), np.asarray(self.high)
        return bool(np.any(state < low - slack) or np.any(state > high + slack))

    def describe(self) -> str:
        if self.kind == 'exact':
            return 'exact (one row per distinct state vector)'
        widths = ', '.join(f'{w:g}' for w in self.widths)
        return f'grid (bin width {widths}, bins centred on multiples of the width)'

    def to_dict(self) -> dict:
        return {
            'kind': self.kind,
            'widths': list(self.widths),
            'low': list(self.low),
            'high': list(self.high),
        }

    @classmethod
    def from_dict(cls, data: dict) -> 'StateMapping':
        return cls(
            str(data['kind']),
            tuple(float(w) for w in data.get('widths', ())),
            tuple(float(v) for v in data.get('low', ())),
            tuple(float(v) for v in data.get('high', ())),
        )


def mapping_from_description(
    low, high, *, nstates: int = 0, resolution: float = 0.0
) -> tuple[StateMapping, list[str]]:
    """The state mapping for a description's ranges and the agent's settings, and warnings.

    resolution > 0: grid with that bin width on every feature; else nstates > 0 and ranges
    given: grid with width (high - low) / nstates per feature (rl_agent's --nstates); else
    exact. Unusable ranges (different lengths, non-finite, low > high) are dropped with a warning.
    """
    warnings = []
    low = tuple(float(v) for v in low)
    high = tuple(float(v) for v in high)
    if len(low) != len(high):
        warnings.append(
            f'description state ranges differ in length ({len(low)} min vs {len(high)} max); '
            'ignoring them'
        )
        low, high = (), ()
    elif not all(math.isfinite(v) for v in low + high) or any(
        lo > hi for lo, hi in zip(low, high, strict=True)
    ):
        warnings.append(
            f'description state ranges are not usable (min {low}, max {high}); ignoring them'
        )
        low, high = (), ()
    if resolution > 0:
        return StateMapping('grid', (float(resolution),), low, high), warnings
    if nstates > 0:
        if not low:
            warnings.append(
                f'nstates={nstates} needs the description state ranges, which are missing; '
                'using the exact state index'
            )
            return StateMapping('exact', (), low, high), warnings
        # A feature with an empty range is constant: any width keeps it in one bin.
        pairs = zip(low, high, strict=True)
        widths = tuple((hi - lo) / nstates if hi > lo else 1.0 for lo, hi in pairs)
        return StateMapping('grid', widths, low, high), warnings
    return StateMapping('exact', (), low, high), warnings


class StateIndex:
    """A growing map from state keys to table rows (0, 1, 2, ... in order of first sight)."""

    def __init__(self, mapping: StateMapping | None = None, dim: int | None = None):
        self.mapping = mapping if mapping is not None else StateMapping()
        implied = self.mapping.dim
        if dim is not None and implied is not None and dim != implied:
            raise ValueError(f'state length {dim} does not match the mapping ({implied})')
        self.dim = dim if dim is not None else implied
        self._rows: dict[tuple, int] = {}
        self._keys: list[tuple] = []

    def __len__(self) -> int:
        return len(self._keys)

    def check(self, state) -> np.ndarray:
        """The state as a float32 vector; StateError naming the problem. Changes nothing."""
        try:
            vector = np.asarray(state, dtype=np.float32)
        except (TypeError, ValueError) as error:
            raise StateError(f'state is not a vector of numbers ({error})') from None
        if vector.ndim != 1:
            raise StateError(f'state must be a flat vector, got shape {vector.shape}')
        if self.dim is not None and vector.shape[0] != self.dim:
            raise StateError(
                f'state has {vector.shape[0]} features, expected {self.dim} '
                '(the state vector length changed)'
            )
        if not np.all(np.isfinite(vector)):
            raise StateError(f'state has non-finite values: {vector.tolist()}')
        return vector

    def row(self, state) -> int:
        """The row of this state, adding a new row for a state never seen."""
        vector = self.check(state)
        key = self.mapping.key(vector)
        row = self._rows.get(key)
        if row is None:
            row = len(self._keys)
            self._rows[key] = row
            self._keys.append(key)
        if self.dim is None:
            self.dim = vector.shape[0]
        return row

    def lookup(self, state) -> int | None:
        """The row of this state, or None when it was never seen."""
        return self._rows.get(self.mapping.key(self.check(state)))

    def out_of_range(self, state) -> bool:
        return self.mapping.out_of_range(self.check(state))

    def keys_array(self) -> np.ndarray:
        """All keys in row order: float32 state values (exact) or int64 bins (grid)."""
        dtype = np.float32 if self.mapping.kind == 'exact' else np.int64
        return np.asarray(self._keys, dtype=dtype).reshape(len(self._keys), self.dim or 0)

    @classmethod
    def from_keys(cls, mapping: StateMapping, keys: np.ndarray, dim: int | None) -> 'StateIndex':
        """Rebuild an index from `keys_array()`; ValueError when the keys are unusable."""
        keys = np.asarray(keys)
        if keys.ndim != 2:
            raise ValueError(f'state keys must be a 2-D array, got shape {keys.shape}')
        if dim is not None and keys.shape[1] != dim and keys.shape[0] > 0:
            raise ValueError(f'state keys have {keys.shape[1]} features, metadata says {dim}')
        index = cls(mapping, dim)
        if mapping.kind == 'exact':
            if not np.all(np.isfinite(keys)):
                raise ValueError('state keys hold non-finite values')
            rows = [tuple(k) for k in keys.astype(np.float32).tolist()]
        else:
            if not np.issubdtype(keys.dtype, np.integer):
                raise ValueError(f'grid state keys must be integers, got {keys.dtype}')
            rows = [tuple(int(v) for v in k) for k in keys.tolist()]
        index._keys = rows
        index._rows = {key: i for i, key in enumerate(rows)}
        if len(index._rows) != len(rows):
            raise ValueError('state keys hold the same state twice')
        return index
