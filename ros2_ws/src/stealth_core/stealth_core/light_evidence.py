"""The steps the robot has taken, what each said of the light on it, and how far a hypothesised
light field misses them: the data side of ``light_belief``. No rclpy.

A step is one row of ``LatticeSamples`` (its start place and direction); its evidence a
``StepEvidence`` (a value read off the reward, or a bound). A robot walks the same steps again
and again, so a light's light is computed once per *distinct* step (``distinct``), and every
observation points at its own (``which``): after a few hundred training episodes through ROS,
22,000 observations were 710 distinct steps.

**Where the pose is judged off the node** (through ROS the environment judges the true pose,
which stops a few centimetres from the lattice node: median 5 cm, at most 31 cm, measured on
floorplan-moving), a step near a beam's edge reads dark once and lit the next time, and no
light field explains both at the node. With ``pose_jitter`` r > 0 each step is also sampled
with its whole way shifted by r along +x, +y, -x and -y, and a hypothesis predicts the
step's light at the node and at each of those four shifts (the *range* over them is what a
contradiction is judged on: the true lights, at 15 cm, left 1 of the 85 readings the node
alone missed on floorplan-moving outside it, and none of 32 on map1-moving; at 10 cm 5 were
left). The likelihood (``energy``) takes each reading as judged at the node or at one shift,
with ``shares`` 0.6 and 0.1 each: taking any reading inside the range as free let a lamp
hypothesised on the robot's way (the node dark beside it, every shift lit) explain all it
read there: on map1-moving's ROS evidence (three runs) the best in-run particle cost 20-33
against the truth's 16, and 181-576 against 53-69 with the shares. In-process the pose is
the node's (r = 0): one value, and the likelihood as before.
"""

from __future__ import annotations

import math

import numpy as np

from stealth_core.light_world import LightWorld, SamplePoints, StepEvidence

# Where the pose jitters, the share of readings judged at the node itself; each shift has an
# equal share of the rest (the pose stops a median 5 cm off the node through ROS, the shifts
# are 15 cm: the node is the likeliest).
NODE_SHARE = 0.6


class _Rows:
    """An array that grows by rows at amortised constant cost (doubling its capacity): a run
    through ROS observes tens of thousands of steps, one at a time."""

    def __init__(self, dtype, columns: int | None = None):
        shape = (16,) if columns is None else (16, columns)
        self._data = np.zeros(shape, dtype=dtype)
        self.size = 0

    def append(self, value) -> None:
        if self.size == self._data.shape[0]:
            grown = np.zeros((2 * self.size, *self._data.shape[1:]), dtype=self._data.dtype)
            grown[: self.size] = self._data
            self._data = grown
        self._data[self.size] = value
        self.size += 1

    @property
    def view(self) -> np.ndarray:
        return self._data[: self.size]


class EvidenceSet:
    """Observations of lattice steps and their sample rows (``observe``), a light's light at
    their distinct steps (``light_at``), and a summed field's misses (``predict``, ``misses``)."""

    def __init__(self, world: LightWorld, abs_tol: float, rel_tol: float, pose_jitter=0.0):
        self.world = world
        self.abs_tol, self.rel_tol = abs_tol, rel_tol
        self.steps: list[StepEvidence] = []
        self._rows = _Rows(np.int64)  # each observation's sample row
        self._low, self._high = _Rows(np.float64), _Rows(np.float64)
        self._distinct = _Rows(np.int64)  # the sample rows, in the order first taken
        self._which = _Rows(np.int64)  # each observation's index in ``distinct``
        self._index: dict[int, int] = {}
        # The distinct readings (a step read again reads the same, mostly): their step, bounds
        # and how often each was read, for the likelihood where the pose jitters (``energy``).
        self._reading: dict[tuple, int] = {}
        self._reading_step, self._reading_count = _Rows(np.int64), _Rows(np.float64)
        self._reading_low, self._reading_high = _Rows(np.float64), _Rows(np.float64)
        # Each distinct step's readings composed as one clamp of a predicted light (``clamps``).
        self._clamp_low, self._clamp_high = _Rows(np.float64), _Rows(np.float64)
        r = float(pose_jitter)
        shifts = [(0.0, 0.0)] + ([(r, 0.0), (0.0, r), (-r, 0.0), (0.0, -r)] if r > 0 else [])
        self.offsets = np.array(shifts)  # (shifts, 2) m: the node's first
        rest = (1.0 - NODE_SHARE) / max(len(shifts) - 1, 1)
        self.shares = np.array(
            [NODE_SHARE if len(shifts) > 1 else 1.0] + [rest] * (len(shifts) - 1)
        )
        # The distinct steps' sample points at the node and each shift (a light's light at
        # them is asked at every move of the search): (x, y, headings, time index) rows.
        samples = world.samples
        columns = len(shifts) * samples.width
        self._points = [
            _Rows(np.float64, columns),
            _Rows(np.float64, columns),
            None if samples.yaw is None else _Rows(np.float64, columns),
            None if samples.t is None else _Rows(np.int32, columns),
        ]

    def __len__(self) -> int:
        return len(self.steps)

    @property
    def rows(self) -> np.ndarray:
        """Each observation's sample row."""
        return self._rows.view

    @property
    def low(self) -> np.ndarray:
        """Each observation's least light."""
        return self._low.view

    @property
    def high(self) -> np.ndarray:
        """Each observation's most light (inf: a detection)."""
        return self._high.view

    @property
    def distinct(self) -> np.ndarray:
        """The distinct steps' sample rows, in the order first taken."""
        return self._distinct.view

    @property
    def which(self) -> np.ndarray:
        """Each observation's index in ``distinct``."""
        return self._which.view

    def observe(self, evidence: StepEvidence) -> bool:
        """Add one observation; True when its step is new (a distinct step more, whose light a
        hypothesised light learns when next read: ``LightBelief._current``)."""
        row = int(self.world.samples.step_rows(evidence.place, evidence.direction))
        self.steps.append(evidence)
        self._rows.append(row)
        self._low.append(evidence.low)
        self._high.append(evidence.high)
        new = row not in self._index
        if new:
            self._index[row] = self._distinct.size
            self._distinct.append(row)
            self._clamp_low.append(-math.inf)
            self._clamp_high.append(math.inf)
            points = self.world.samples.points(np.array([row]), self.offsets)
            for column, values in zip(self._points, points, strict=True):
                if column is not None:
                    column.append(values[0])
        self._which.append(self._index[row])
        self._compose_clamp(self._index[row], evidence)
        key = (self._index[row], evidence.low, evidence.high)
        if key not in self._reading:
            self._reading[key] = self._reading_step.size
            for column, value in zip(
                (self._reading_step, self._reading_low, self._reading_high, self._reading_count),
                (*key, 0.0),
                strict=True,
            ):
                column.append(value)
        self._reading_count.view[self._reading[key]] += 1.0
        return new

    def _compose_clamp(self, step: int, evidence: StepEvidence) -> None:
        """Follow a distinct step's clamp by one more reading's: an exact reading sets the
        light, a detection raises it to the threshold, a goal caps it below."""
        if evidence.exact:
            low, high = evidence.low, evidence.low
        elif not math.isfinite(evidence.high):
            low, high = self.world.threshold, math.inf
        else:
            low, high = -math.inf, evidence.high
        lows, highs = self._clamp_low.view, self._clamp_high.view
        lows[step], highs[step] = (min(max(v, low), high) for v in (lows[step], highs[step]))

    def clamps(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(places, directions, low, high) of the distinct steps: a predicted light v of a step
        becomes ``clip(v, low, high)``, what its readings in turn make of it (the last exact
        one, raised to the threshold by a detection after it, capped by a goal after it)."""
        places, directions = self.world.samples.steps_of(self.distinct)
        return places, directions, self._clamp_low.view, self._clamp_high.view

    def light_at(self, see, distinct: np.ndarray | None = None) -> np.ndarray:
        """(steps, shifts * width): the light of ``see`` at the samples of distinct steps (all
        by default), each step's samples at the node, then at each shift."""
        pick = slice(None) if distinct is None else distinct
        points = SamplePoints(
            *(None if column is None else column.view[pick] for column in self._points)
        )
        return self.world.samples.light_of(see, points)

    def sample_points(self, distinct: np.ndarray) -> tuple:
        """(x, y, t) of the samples of distinct steps at the node and every shift, (steps,
        samples) each; t (s in the cycle) None where lights do not move."""
        x, y, _, time_index = self._points
        t = None if time_index is None else self.world.samples.times[time_index.view[distinct]]
        return x.view[distinct], y.view[distinct], t

    def wanting(self, low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The distinct steps a predicted range (``predict``) leaves too dark for one of their
        readings, and those it leaves too bright, each by more than a tolerance."""
        z = self.misses(low, high)
        too_dark = np.unique(self.which[(z > 1.0) & (self.low > high)])
        too_bright = np.unique(self.which[(z > 1.0) & (low > self.high)])
        return too_dark, too_bright

    def predict(self, total: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) per observation: the least and most of a field's step light (``total``,
        the lights' ``light_at`` summed; None: no light) over the node and the shifts."""
        if total is None:
            zeros = np.zeros(len(self.steps))
            return zeros, zeros
        peaks = total.reshape(total.shape[0], len(self.offsets), -1).max(axis=2)
        if peaks.shape[1] == 1:
            values = peaks[:, 0][self.which]
            return values, values
        return peaks.min(axis=1)[self.which], peaks.max(axis=1)[self.which]

    def energy(self, total: np.ndarray | None) -> float:
        """The misses' energy of a field (``light_at`` summed over its lights; None: none):
        ``sum sqrt(1 + z^2) - 1`` over the observations, z each one's miss in tolerances.
        Where the pose jitters, each reading was judged at the node or at one shift, with
        their ``shares``: its energy is ``-log sum_k share_k exp(-(sqrt(1 + z_k^2) - 1))``, z_k
        its miss at shift k, so a reading a hypothesis explains only off the node costs more
        than one it explains there (a lamp on the robot's way explains any reading beside
        it, at some shift)."""
        if len(self.offsets) == 1:
            z = self.misses(*self.predict(total))
            return float(np.sum(np.sqrt(1.0 + z * z) - 1.0))
        steps = self._reading_step.view
        if total is None:
            light = np.zeros((steps.size, len(self.offsets)))
        else:
            peaks = total.reshape(total.shape[0], len(self.offsets), -1).max(axis=2)
            light = peaks[steps]
        low, high = self._reading_low.view[:, None], self._reading_high.view[:, None]
        z = self._misses(light, light, low, high)
        energies = np.sqrt(1.0 + z * z) - 1.0 - np.log(self.shares)
        least = energies.min(axis=1)
        per_reading = least - np.log(np.exp(least[:, None] - energies).sum(axis=1))
        return float(np.dot(self._reading_count.view, per_reading))

    def tolerance(self) -> np.ndarray:
        """Each observation's tolerance: ``abs_tol + rel_tol * v``."""
        return self._tolerance(self.low, self.high)

    def misses(self, low: np.ndarray, high: np.ndarray | None = None) -> np.ndarray:
        """Each observation's miss, in tolerances (0 where the predicted range [low, high]
        meets the observation's bounds)."""
        return self._misses(low, low if high is None else high, self.low, self.high)

    def _tolerance(self, low: np.ndarray, high: np.ndarray) -> np.ndarray:
        """The tolerance of readings with bounds [low, high]: of the value read, or the bound."""
        finite = np.where(np.isfinite(high), high, low)
        return self.abs_tol + self.rel_tol * finite

    def _misses(self, predicted_low, predicted_high, low, high) -> np.ndarray:
        """How far a predicted range misses readings' bounds, in the readings' tolerances."""
        over = np.maximum(predicted_low - high, 0.0)
        under = np.maximum(low - predicted_high, 0.0)
        return (over + under) / self._tolerance(low, high)

    def mixed_steps(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The steps read detected once and not another time (through ROS: a beam's edge within
        the pose's few cm off the node; in-process a step always reads the same): (places,
        directions, the share of their readings that were detections, the mean light of their
        undetected readings)."""
        steps = self.distinct.size
        counts = np.bincount(self.which, minlength=steps)
        detected = np.bincount(self.which, ~np.isfinite(self.high), minlength=steps)
        mixed = np.flatnonzero((detected > 0) & (detected < counts))
        if mixed.size == 0:
            empty = np.zeros(0, dtype=np.int64)
            return empty, empty, np.zeros(0), np.zeros(0)
        read = np.isfinite(self.high) & (self.low == self.high)
        sums = np.bincount(self.which, np.where(read, self.low, 0.0), steps)
        reads = np.bincount(self.which, read, minlength=steps)
        places, directions = self.world.samples.steps_of(self.distinct[mixed])
        share = detected[mixed] / counts[mixed]
        dark = sums[mixed] / np.maximum(reads[mixed], 1)
        return places, directions, share, dark

    def sample_time(self, distinct: int, column: int) -> float:
        """The time in the cycle of a column of ``light_at``'s row ``distinct``."""
        samples = self.world.samples
        return float(samples.t[self.distinct[distinct], column % samples.width])
