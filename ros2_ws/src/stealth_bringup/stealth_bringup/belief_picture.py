"""light_belief.png: what a light-model run came to believe of the searchlights, beside the
true field. No rclpy.

Drawn from the saved policy's belief (``belief_lights``, ``belief_weights``: the arrays
``LightModelLearner.to_arrays`` saves) on the grid the agent publishes it on
(``stealth_core.light_belief_map``), so the picture is what Foxglove showed last: the true
field (the scenario's lights, which only the orchestrator knows), the most likely field, and
the weight of the hypotheses that light each cell (counted as uncertain where at least
UNSURE_PERCENT % of the weight disagrees). Each field is drawn in units of the detection
threshold, with the threshold's contour.
"""

from __future__ import annotations

from pathlib import Path

from matplotlib.figure import Figure  # no pyplot: no global state, no display (Agg)
import numpy as np
from stealth_core.light_belief_map import BeliefMapper, belief_rows
from stealth_core.light_world import LightWorld

from stealth_bringup.run_outputs import replacing

SHOWN_MAX = 1.5  # the fields' colour scale tops out at 1.5x the detection threshold
UNSURE_PERCENT = 5  # a cell counts as uncertain where at least this % of the weight disagrees


def saved_belief(policy_path: Path) -> tuple[np.ndarray, np.ndarray] | None:
    """(lights, weights) of a saved light-model policy; None for a policy without a belief
    (another learner's). OSError/ValueError for a file that cannot be read."""
    with np.load(policy_path, allow_pickle=False) as arrays:
        if 'belief_lights' not in arrays or 'belief_weights' not in arrays:
            return None
        return np.array(arrays['belief_lights']), np.array(arrays['belief_weights'])


def plot_light_belief(scenario, goal: str, policy_path: Path, path: Path, title: str):
    """light_belief.png of the policy at ``policy_path`` (see the module docstring); None when
    it holds no belief. BeliefArrayError for arrays that are not a belief."""
    belief = saved_belief(policy_path)
    if belief is None:
        return None
    world = LightWorld(scenario, goal)  # the scenario without its lights: the agent's world
    mapper = BeliefMapper(world)
    grid = mapper.grid(*belief)
    truth = mapper.grid(belief_rows(scenario.lights), [1.0]).likely_field
    threshold = world.threshold
    x0, y0 = grid.origin[:2]
    extent = (x0, x0 + grid.width * grid.resolution, y0, y0 + grid.height * grid.resolution)
    lights, weights = belief
    best = int(np.argmax(weights))
    count = int(np.count_nonzero(lights[:, 0] == best))
    unsure = np.count_nonzero(grid.uncertain >= 2 * UNSURE_PERCENT)  # the minority's >= 5 %
    panels = (
        (truth / threshold, f'true field ({len(scenario.lights)} lights)', 'magma', SHOWN_MAX),
        (grid.likely_field / threshold,
         f'most likely belief ({count} lights, weight {weights[best] / weights.sum():.2f})',
         'magma', SHOWN_MAX),
        (grid.lit_probability,
         f'weight that says lit ({unsure} cells where >= {UNSURE_PERCENT} % disagree)', 'viridis',
         1.0),
    )  # fmt: skip
    figure = Figure(figsize=(15, 5.4), layout='constrained')
    axes = figure.subplots(1, 3)
    for ax, (values, label, colours, top) in zip(axes, panels, strict=True):
        shown = np.ma.masked_invalid(values)
        image = ax.imshow(shown, origin='lower', extent=extent, cmap=colours, vmin=0.0,
                          vmax=top, interpolation='nearest')  # fmt: skip
        ax.set_facecolor('0.55')  # walls and unknown cells
        if top == SHOWN_MAX and np.nanmax(values, initial=0.0) >= 1.0:
            ax.contour(np.nan_to_num(values), levels=[1.0], colors='cyan', linewidths=0.8,
                       origin='lower', extent=extent)  # fmt: skip
        ax.plot(*scenario.start[:2], marker='o', color='lime', markersize=6)
        ax.plot(*scenario.goals[goal].point, marker='*', color='gold', markersize=11)
        ax.set_title(label, fontsize=10)
        ax.set_aspect('equal')
        ax.set_xlabel('x (m)')
        figure.colorbar(
            image,
            ax=ax,
            shrink=0.8,
            label='light / detection threshold' if top == SHOWN_MAX else 'weight',
        )
    axes[0].set_ylabel('y (m)')
    figure.suptitle(f'{title} (cyan: the detection threshold)')
    with replacing(path) as temporary:
        figure.savefig(temporary, format='png', dpi=90)
    return Path(path)
