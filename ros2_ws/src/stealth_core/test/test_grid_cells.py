"""The cell of the grid observation a map point falls in (the environment's and agent's rule)."""

from stealth_core.grid_cells import cell_of

GEOMETRY = (0.5, -1.0, 2.0)  # 0.5 m cells from (-1, 2)


def test_a_point_falls_in_the_cell_whose_square_holds_it():
    assert cell_of(GEOMETRY, -1.0 + 0.5 * 2.5, 2.0 + 0.5 * 1.5) == (1, 2)  # row from y
    assert cell_of(GEOMETRY, -1.0, 2.0) == (0, 0)  # a cell holds its lower edges
    assert cell_of(GEOMETRY, -0.5, 2.5) == (1, 1)


def test_outside_the_grid_the_index_runs_on():
    assert cell_of(GEOMETRY, -1.01, 1.99) == (-1, -1)
    assert cell_of(GEOMETRY, 100.0, 2.0) == (0, 202)
    assert all(isinstance(index, int) for index in cell_of(GEOMETRY, 0.3, 0.3))
