"""The move lattice: which nodes and moves are collision-free, exactly at the cell level."""

import itertools
from types import SimpleNamespace

from lattice_reference import reference_clear
import numpy as np
import pytest
from stealth_core.move_lattice import ACTIONS, MoveLattice
from stealth_core.occupancy_map import OccupancyMap


def open_map(width=40, height=30, resolution=0.1, origin=(0.0, 0.0, 0.0)) -> OccupancyMap:
    return OccupancyMap(np.zeros((height, width), np.int8), resolution, origin)


def with_cells(occupancy: OccupancyMap, cells, value=100) -> OccupancyMap:
    data = occupancy.data.copy()
    for col, row in cells:
        data[row, col] = value
    return OccupancyMap(data, occupancy.resolution, occupancy.origin)


@pytest.mark.parametrize('seed', range(12))
def test_lattice_matches_the_brute_force_reference(seed):
    rng = np.random.default_rng(seed)
    data = np.where(rng.random((14, 16)) < 0.12, 100, 0).astype(np.int8)
    data[rng.random((14, 16)) < 0.03] = -1
    occupancy = OccupancyMap(data, 0.1, (-0.3, 0.2, 0.0))
    anchor = (-0.3 + rng.uniform(0.2, 1.4), 0.2 + rng.uniform(0.2, 1.2))
    step = float(rng.choice([0.1, 0.13, 0.25, 0.3]))
    radius = float(rng.choice([0.0, 0.05, 0.12, 0.2]))
    lattice = MoveLattice(occupancy, anchor, step, radius)
    assert lattice.shape[0] > 2 and lattice.shape[1] > 2
    for a, b in itertools.product(range(lattice.shape[0]), range(lattice.shape[1])):
        node = (a + lattice.i_min, b + lattice.j_min)
        p = lattice.node_to_point(node)
        assert occupancy.contains_point(*p)
        assert lattice.node_mask[a, b] == reference_clear(occupancy, p, p, radius), node
        for delta, moves in (((1, 0), lattice.right_moves), ((0, 1), lattice.up_moves)):
            if a + delta[0] < lattice.shape[0] and b + delta[1] < lattice.shape[1]:
                q = lattice.node_to_point((node[0] + delta[0], node[1] + delta[1]))
                expected = (
                    reference_clear(occupancy, p, p, radius)
                    and reference_clear(occupancy, q, q, radius)
                    and reference_clear(occupancy, p, q, radius)
                )
                assert moves[a, b] == expected, (node, delta)


def test_a_thin_wall_blocks_the_move_but_not_the_nodes():
    # Nodes 1 m apart at x = 1.05 and 2.05; a wall one cell thick at x in [1.5, 1.6].
    occupancy = with_cells(open_map(), [(15, row) for row in range(30)])
    lattice = MoveLattice(occupancy, (1.05, 1.05), 1.0, 0.2)
    assert lattice.is_valid((0, 0)) and lattice.is_valid((1, 0))
    assert not lattice.can_move((0, 0), (1, 0))
    assert (1, 0) not in lattice.neighbours((0, 0))


def test_radius_is_exact_at_the_cell_level():
    occupancy = with_cells(open_map(), [(20, 10)])  # square [2.0, 2.1] x [1.0, 1.1]
    radius = 0.3
    assert not MoveLattice(occupancy, (1.71, 1.05), 1.0, radius).is_valid((0, 0))  # 0.29 away
    assert MoveLattice(occupancy, (1.69, 1.05), 1.0, radius).is_valid((0, 0))  # 0.31 away
    # Diagonally the corner counts: (1.8, 0.8) is 0.283 from the corner (2.0, 1.0).
    assert not MoveLattice(occupancy, (1.8, 0.8), 1.0, radius).is_valid((0, 0))
    assert MoveLattice(occupancy, (1.75, 0.75), 1.0, radius).is_valid((0, 0))  # 0.354 away


def test_zero_radius_checks_the_cells_under_the_path():
    occupancy = with_cells(open_map(), [(12, 5)])
    lattice = MoveLattice(occupancy, (1.05, 0.55), 0.1, 0.0)
    assert not lattice.is_valid((2, 0)) and lattice.is_valid((1, 0))


def test_unknown_cells_and_the_map_edge_block():
    occupancy = with_cells(open_map(), [(5, 5)], value=-1)
    assert not MoveLattice(occupancy, (0.55, 0.55), 1.0, 0.0).is_valid((0, 0))
    near_edge = MoveLattice(open_map(), (0.15, 1.5), 0.5, 0.2)
    assert not near_edge.is_valid((0, 0)) and near_edge.is_valid((1, 0))


def test_nodes_cover_only_the_map():
    lattice = MoveLattice(open_map(), (1.0, 1.0), 0.5, 0.0)
    assert (lattice.i_min, lattice.j_min) == (-2, -2)
    assert lattice.shape == (8, 6)  # x in {0, ..., 3.5}, y in {0, ..., 2.5}
    assert not lattice.contains((6, 0)) and not lattice.is_valid((-3, 0))


def test_actions_are_the_originals():
    assert [name for name, _ in ACTIONS] == ['up', 'down', 'left', 'right']
    lattice = MoveLattice(open_map(), (2.0, 1.5), 0.5, 0.2)
    moved = [lattice.node_to_point(lattice.successor((0, 0), a)) for a in range(4)]
    assert moved == [(2.0, 2.0), (2.0, 1.0), (1.5, 1.5), (2.5, 1.5)]
    assert lattice.neighbours((0, 0)) == [(0, 1), (0, -1), (-1, 0), (1, 0)]


def test_successor_is_none_when_blocked():
    occupancy = with_cells(open_map(), [(col, 20) for col in range(40)])
    lattice = MoveLattice(occupancy, (2.0, 1.5), 0.5, 0.2)
    assert lattice.successor((0, 0), 0) is None  # the wall at y = 2.0
    with pytest.raises(ValueError, match='delta'):
        lattice.can_move((0, 0), (1, 1))


def test_points_and_nodes():
    lattice = MoveLattice(open_map(), (1.0, 1.0), 0.5, 0.2)
    assert lattice.node_to_point((2, -1)) == (2.0, 0.5)
    assert lattice.point_to_node(2.2, 0.3) == (2, -1)
    within = lattice.nodes_within(2.0, 1.0, 0.5)
    assert sorted(within) == [(1, 0), (2, -1), (2, 0), (2, 1), (3, 0)]


def test_bfs_finds_a_shortest_path():
    lattice = MoveLattice(open_map(), (0.5, 0.5), 0.5, 0.2)
    path = lattice.bfs((0, 0), goal=lambda node: node == (5, 3))
    assert path[0] == (0, 0) and path[-1] == (5, 3) and len(path) == 9
    for a, b in itertools.pairwise(path):
        assert abs(a[0] - b[0]) + abs(a[1] - b[1]) == 1


def test_bfs_respects_passable_and_reports_unreachable():
    occupancy = with_cells(open_map(), [(20, row) for row in range(30)])  # wall at x = 2.0
    lattice = MoveLattice(occupancy, (0.5, 0.5), 0.5, 0.2)
    assert lattice.bfs((0, 0), goal=lambda node: node[0] >= 4) is None
    detour = lattice.bfs((0, 0), goal=lambda node: node == (2, 0), passable=lambda n: n[1] != 0)
    assert detour is None  # the goal itself is impassable
    detour = lattice.bfs((0, 0), goal=lambda n: n == (2, 0), passable=lambda n: n != (1, 0))
    assert len(detour) == 5
    assert lattice.bfs((9, 9), goal=lambda node: True) is None  # not a valid node


def test_from_scenario_anchors_at_the_start():
    scenario = SimpleNamespace(
        map=open_map(), start=(1.0, 1.5, 0.3), step_distance=0.25, robot_radius=0.1
    )
    lattice = MoveLattice.from_scenario(scenario)
    assert lattice.anchor == (1.0, 1.5) and lattice.step == 0.25 and lattice.robot_radius == 0.1


@pytest.mark.parametrize(('step', 'radius'), [(0.0, 0.2), (-1.0, 0.2), (0.5, -0.1)])
def test_bad_parameters(step, radius):
    with pytest.raises(ValueError):
        MoveLattice(open_map(), (1.0, 1.0), step, radius)


@pytest.mark.parametrize('step', [0.25, 0.5])
def test_a_600_by_600_map_builds(step):
    # How fast: bench/bench_lattice.py (a timing here fails on a loaded machine).
    rng = np.random.default_rng(3)
    data = np.where(rng.random((600, 600)) < 0.05, 100, 0).astype(np.int8)
    occupancy = OccupancyMap(data, 0.05, (-15.0, -15.0, 0.0))
    lattice = MoveLattice(occupancy, (0.0, 0.0), step, 0.2)
    assert lattice.shape == (round(30 / step),) * 2
    rows, cols = lattice.shape
    assert lattice.node_mask.shape == lattice.shape
    assert lattice.right_moves.shape == (rows - 1, cols)
    assert lattice.up_moves.shape == (rows, cols - 1)
    assert 0 < lattice.node_mask.sum() < lattice.node_mask.size  # clutter blocks some, not all
    for a, b in zip(*(rng.integers(0, n - 1, 40) for n in lattice.shape), strict=True):
        p = lattice.node_to_point((a + lattice.i_min, b + lattice.j_min))
        assert lattice.node_mask[a, b] == reference_clear(occupancy, p, p, 0.2), (a, b)
