"""Benchmark: what exposure by orientation costs the planners: building the lattice model (every
step of every place judged) with the heading in the state, against the same scenario with the
option off, and value iteration on each. Four headings make four times the places, six actions
(the turns) half as many more steps, and a step that turns is judged on up to 36 more headings
(the lights traced once per point, ``PointVisibility.turning``).

Run: PYTHONPATH=ros2_ws/src/stealth_core python bench/bench_exposure.py
"""

from __future__ import annotations

import dataclasses

from bench_visibility import REPEATS, best_of
from stealth_core.lattice_model import LatticeModel
from stealth_core.planners import value_iteration
from stealth_core.scenario import load_scenario
from stealth_core.task import StealthTask

SCENARIOS = ('map1-exposure', 'simple-maze-exposure')


def run(report=print) -> dict:
    figures = {}
    report(f'lattice model build and value iteration, best of {REPEATS}:')
    for name in SCENARIOS:
        scenario = load_scenario(name)
        for label, variant in (
            ('exposure', scenario),
            ('plain', dataclasses.replace(scenario, exposure=None)),
        ):
            task = StealthTask(variant)
            task._point_visibility  # noqa: B018  (the per-point model, built outside the timing)
            build, model = best_of(lambda task=task: LatticeModel.build(task))
            solve, _ = best_of(lambda model=model: value_iteration(model))
            report(
                f'  {name} ({label}): {model.size} places x {model.num_actions} actions, '
                f'build {build:.2f} s, value iteration {solve:.2f} s'
            )
            key = f'exposure_{name.replace("-", "_")}_{label}'
            figures[f'{key}_places'] = model.size
            figures[f'{key}_build_seconds'] = round(build, 3)
            figures[f'{key}_value_iteration_seconds'] = round(solve, 3)
    return figures


def main() -> None:
    run()


if __name__ == '__main__':
    main()
