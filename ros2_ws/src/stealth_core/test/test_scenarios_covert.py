"""Every shipped scenario is a stealth problem: each goal can be reached unseen, but not by the
shortest way.

For each scenario and goal, on the robot's move lattice (the moves the RL agent has):

(a) a path exists on which every node, and every point of every move between nodes, has total
    visibility below the detection threshold;
(b) the shortest path ignoring the lights is detected at one of its nodes, and in fact every
    shortest path is: avoiding detection takes more moves.

"Every point of a move" is checked on the visibility field at the cells the move's segment
crosses (sampled at a quarter cell), and the path found in (a) is re-checked point by point with
the per-point reference. Moving lights are judged at their worst over one cycle.

The moving-light variants (``scenarios/*-moving.yaml``) are the opposite by design: no route is
dark at every time, and their goals are reached unseen only by timing the passage, which
``test_moving_scenarios`` proves on the time-expanded lattice. They are left out here. The
one-bounce variants (``scenarios/*-bounce.yaml``) are in, judged with their bounce (the field
and the per-point reference, ``stealth_core.bounce``).
"""

import math
from pathlib import Path

import numpy as np
import pytest
from stealth_core.bounce import point_bounce, received_light, wall_emitters
from stealth_core.lighting import GridFrame, point_visibility
from stealth_core.move_lattice import ACTIONS, MoveLattice
from stealth_core.scenario_drawing import goal_marks
from stealth_core.searchlight import PatrolMotion, SweepMotion
from stealth_core.visibility import visibility_field

scenario_module = pytest.importorskip('stealth_core.scenario')

REPO = Path(__file__).resolve().parents[4]
SCENARIO_FILES = sorted(  # the variants' own tests: test_moving_scenarios, test_exposure
    path
    for path in (REPO / 'scenarios').glob('*.yaml')
    if not path.stem.endswith(('-moving', '-exposure'))
)
TIME_SAMPLES = 24  # instants per cycle at which moving lights are judged


def cycle_times(lights) -> list[float]:
    """Instants covering one cycle of every moving light (t = 0 alone when none moves)."""
    periods = []
    for light in lights:
        if isinstance(light.motion, SweepMotion) and light.motion.angular_speed > 0:
            span = light.motion.max_direction - light.motion.min_direction
            periods.append(2 * span / light.motion.angular_speed)
        if isinstance(light.motion, PatrolMotion) and light.motion.speed > 0:
            route = [(light.x, light.y), *light.motion.waypoints, (light.x, light.y)]
            lap = sum(math.dist(a, b) for a, b in zip(route, route[1:], strict=False))
            periods.append(lap / light.motion.speed)
    periods = [p for p in periods if p > 0]
    if not periods:
        return [0.0]
    longest = max(periods)
    return [longest * k / TIME_SAMPLES for k in range(TIME_SAMPLES)]


class Judge:
    """Visibility of one scenario on its move lattice, worst case over the lights' cycle."""

    def __init__(self, scenario):
        self.scenario = scenario
        occupancy = scenario.map
        self.threshold = scenario.detection_threshold
        self.lattice = MoveLattice.from_scenario(scenario)
        self.frame = GridFrame.of(occupancy.blocked, occupancy.resolution, occupancy.origin)
        self.times = cycle_times(scenario.lights)
        self.grid = (occupancy.blocked, occupancy.resolution, occupancy.origin)
        fields = [
            visibility_field(*self.grid, scenario.lights, t, bounce=scenario.bounce)[0]
            for t in self.times
        ]
        self.field = np.max(fields, axis=0)
        if scenario.bounce is not None:  # static lights only: the emitters' light, once
            self.emitters = wall_emitters(occupancy.blocked)
            self.received = received_light(*self.grid, scenario.lights, self.emitters)

    def visibility(self, x: float, y: float) -> float:
        """Per-point reference, worst over the cycle (plus the bounce, if any)."""
        direct = max(
            point_visibility(*self.grid, self.scenario.lights, x, y, t) for t in self.times
        )
        if self.scenario.bounce is None:
            return direct
        bounce = self.scenario.bounce
        return direct + point_bounce(*self.grid, self.emitters, self.received, bounce, x, y)

    def segment_points(self, node, other, spacing, fraction=1.0):
        """Points from node towards other, every ``spacing`` m, over ``fraction`` of the way."""
        (x0, y0), (x1, y1) = self.lattice.node_to_point(node), self.lattice.node_to_point(other)
        x1, y1 = x0 + (x1 - x0) * fraction, y0 + (y1 - y0) * fraction
        count = max(math.ceil(math.dist((x0, y0), (x1, y1)) / spacing), 1)
        return [(x0 + (x1 - x0) * k / count, y0 + (y1 - y0) * k / count) for k in range(count + 1)]

    def field_at(self, x: float, y: float) -> float:
        col, row = self.frame.cell_of(x, y)
        return float(self.field[row, col])

    def node_seen(self, node) -> bool:
        return self.field_at(*self.lattice.node_to_point(node)) >= self.threshold

    def covert(self, node) -> bool:
        """The node and its half of every valid move out of it are unseen, on the field's cells.

        Two covert neighbours thus make a move that is unseen all along.
        """
        if self.node_seen(node):
            return False
        spacing = self.scenario.map.resolution / 4
        for _, delta in ACTIONS:
            if self.lattice.can_move(node, delta):
                other = (node[0] + delta[0], node[1] + delta[1])
                half = self.segment_points(node, other, spacing, fraction=0.5)
                if max(self.field_at(x, y) for x, y in half) >= self.threshold:
                    return False
        return True


CASES = []
for path in SCENARIO_FILES:
    for goal in goal_marks(scenario_module.load_scenario(path)):
        CASES.append(pytest.param(path, goal.name, id=f'{path.stem}-{goal.name}'))


@pytest.fixture(scope='module')
def judges():
    cache = {}

    def judge(path):
        if path not in cache:
            cache[path] = Judge(scenario_module.load_scenario(path))
        return cache[path]

    return judge


def test_the_four_scenarios_are_shipped():
    assert len([path for path in SCENARIO_FILES if not path.stem.endswith('-bounce')]) == 4


def _reach(judge, goal_name, passable):
    goal = next(g for g in goal_marks(judge.scenario) if g.name == goal_name)
    targets = set(judge.lattice.nodes_within(goal.x, goal.y, goal.radius))
    assert targets, f'goal {goal_name!r} has no lattice node within its radius'
    start = judge.lattice.point_to_node(*judge.scenario.start[:2])
    return judge.lattice.bfs(start, goal=targets.__contains__, passable=passable)


@pytest.mark.parametrize(('path', 'goal_name'), CASES)
def test_each_goal_can_be_reached_unseen(judges, path, goal_name):
    judge = judges(path)
    route = _reach(judge, goal_name, judge.covert)
    assert route is not None, f'{path.stem}: no covert path to goal {goal_name!r}'
    assert len(route) - 1 <= judge.scenario.step_limit, 'the covert path is over the step limit'
    spacing = judge.scenario.map.resolution / 2
    for node, other in zip(route, route[1:], strict=False):
        for x, y in judge.segment_points(node, other, spacing):
            seen = judge.visibility(x, y)
            assert seen < judge.threshold, f'({x:.2f}, {y:.2f}) on the covert path: {seen:.3f}'


@pytest.mark.parametrize(('path', 'goal_name'), CASES)
def test_the_shortest_way_is_seen(judges, path, goal_name):
    judge = judges(path)
    shortest = _reach(judge, goal_name, lambda node: True)
    assert shortest is not None
    peak = max(judge.visibility(*judge.lattice.node_to_point(node)) for node in shortest)
    assert peak >= judge.threshold, f'{path.stem}: the shortest path to {goal_name!r} is unseen'
    unseen = _reach(judge, goal_name, lambda node: not judge.node_seen(node))
    assert unseen is None or len(unseen) > len(shortest), (
        f'{path.stem}: a shortest path to {goal_name!r} avoids every lit node'
    )
