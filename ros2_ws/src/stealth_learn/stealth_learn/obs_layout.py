"""The JAX environment's observation layouts, and the check a policy file makes at load: a
policy trained on one layout is refused on another, naming both (issue 30's bad-input rule).

Two layouts (``jax_env.StealthJaxEnv(layout=...)``):

- ``vector`` (track 'full' only): float32 ``(8,)``, ``VECTOR``: x, y (the state grid's point,
  m: the Gym env's state), phase (bin, 0 without moving lights), heading (0-3, 0 without
  exposure), lit (1 when the judged light on the robot reaches the threshold), the episode's
  time used (steps / step_limit), and the goal's offset from the robot (m).
- ``grid``: ``Observation(grid, vector)``: the vector above and a float32 ``(rows, cols, 7)``
  grid over the move lattice padded to the batch's size (``[row, col] = [j - j_min, i -
  i_min]``, row 0 the southernmost; padding up and right is wall), channels ``CHANNELS``:
  free (1 on a valid lattice node), robot (1 on its node), goal (1 on nodes within the goal's
  radius), light (on each node), move_up and move_right (the most light along the move up /
  right from each node), age (steps since the value was sensed; -1 never; 0 on track 'full').
  Lights are -2 where no node or move is. Track 'full': the light of the lights as they stand
  now (the robot's bin and heading); track 'sensed': the last value sensed, -1 never (exactly
  the Gym sensed observation's ``light`` and ``moves``).

The layout id names layout, track and size, e.g. ``stealth-grid-v1/sensed/80x120``. The grid's
channels, ids and full-track construction are ``stealth_core.grid_observation``'s (what the
environment node sends through ROS).

The time-aware generalist (moving lights, lights known) reads the phased grid
(``stealth_core.grid_observation.FullTrackGrid.phased``, what the environment node sends):
every phase layer's grid and the light of each step from there; its id names the phase layers
and the layers a step advances, e.g. ``stealth-phased-v1/full/8phases-1perstep/60x60``, so a
policy of another phase count is refused naming both.
"""

from __future__ import annotations

from stealth_core import grid_observation
from stealth_core.grid_observation import CHANNELS as CHANNELS  # re-exported
from stealth_core.grid_observation import PHASED_CHANNELS as PHASED_CHANNELS
from stealth_core.grid_observation import PHASED_PREFIX as PHASED_PREFIX
from stealth_core.grid_observation import VERSION
from stealth_core.grid_observation import phased_layout_id as phased_layout_id

LAYOUTS = ('vector', 'grid')
VECTOR = ('x', 'y', 'phase', 'heading', 'lit', 'time_used', 'goal_dx', 'goal_dy')


class LayoutError(ValueError):
    """A layout that does not exist, or a policy trained for another layout."""


def layout_id(layout: str, track: str, rows: int, cols: int) -> str:
    """The id of a layout for a track and a padded lattice size."""
    if layout not in LAYOUTS:
        raise LayoutError(f'layout: expected one of {", ".join(LAYOUTS)}, got {layout!r}')
    if layout == 'vector':
        if track != 'full':
            raise LayoutError(
                f"layout 'vector' has no sensed light: track {track!r} needs layout 'grid'"
            )
        return f'stealth-vector-{VERSION}/full'
    return grid_observation.layout_id(track, rows, cols)


def check_layout(policy_layout: str, env_layout: str, source: str) -> None:
    """LayoutError (one line naming both layouts and the policy's source) unless they match."""
    if policy_layout != env_layout:
        raise LayoutError(
            f'{source}: the policy was trained for observation layout {policy_layout!r}, '
            f'this environment gives {env_layout!r}; train one for it or pick the matching track'
        )
