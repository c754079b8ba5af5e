"""State vectors to table rows: the exact growing index and the range-based grid."""

import numpy as np
import pytest
from stealth_agent.state_index import (
    StateError,
    StateIndex,
    StateMapping,
    mapping_from_description,
)


def test_exact_index_hands_out_rows_in_order_of_first_sight():
    index = StateIndex()
    assert index.row([0.5, 1.0]) == 0
    assert index.row([1.0, 1.0]) == 1
    assert index.row(np.array([0.5, 1.0], dtype=np.float32)) == 0
    assert index.lookup([2.0, 2.0]) is None
    assert len(index) == 2 and index.dim == 2


def test_exact_index_grows_without_limit():
    index = StateIndex()
    xs = np.arange(20_000, dtype=np.float32) * 0.5
    rows = [index.row([x, -x]) for x in xs]
    assert rows == list(range(20_000))
    assert index.row([xs[1234], -xs[1234]]) == 1234
    assert index.keys_array().shape == (20_000, 2)


def test_exact_keys_survive_a_round_trip():
    index = StateIndex()
    for state in ([0.1, 0.2], [0.30000001, 5.5], [-0.0, 1e-7]):
        index.row(state)
    rebuilt = StateIndex.from_keys(index.mapping, index.keys_array(), index.dim)
    for state in ([0.1, 0.2], [0.30000001, 5.5], [0.0, 1e-7]):
        assert rebuilt.lookup(state) == index.lookup(state)
    assert rebuilt.row([9.0, 9.0]) == 3


def test_grid_bins_are_centred_on_multiples_of_the_width():
    index = StateIndex(StateMapping('grid', (0.5,)))
    # Values on the 0.5 m grid, as stealth_env sends them, each get their own row ...
    cells = [index.row([x, y]) for x in np.arange(0, 5, 0.5) for y in np.arange(0, 3, 0.5)]
    assert cells == list(range(60))
    # ... and values near a grid point share its row.
    assert index.row([1.5 + 0.2, 2.0 - 0.2]) == index.lookup([1.5, 2.0])
    assert index.row([1.5 + 0.3, 2.0]) == index.lookup([2.0, 2.0])


def test_grid_from_nstates_uses_the_description_ranges():
    mapping, warnings = mapping_from_description([0.0, -2.0], [10.0, 2.0], nstates=5)
    assert not warnings
    assert mapping.kind == 'grid' and mapping.widths == (2.0, 0.8)
    index = StateIndex(mapping)
    assert index.dim == 2
    assert index.row([4.1, 0.3]) == index.row([3.9, -0.3])
    assert index.row([4.1, 0.3]) != index.row([6.1, 0.3])


def test_resolution_overrides_nstates_and_exact_is_the_default():
    mapping, _ = mapping_from_description([0.0], [10.0], nstates=5, resolution=0.25)
    assert mapping.widths == (0.25,)
    mapping, warnings = mapping_from_description([0.0], [10.0])
    assert mapping.kind == 'exact' and not warnings


def test_unusable_ranges_fall_back_with_a_warning():
    mapping, warnings = mapping_from_description([0.0, 1.0], [5.0], nstates=4)
    assert mapping.kind == 'exact' and mapping.low == ()
    assert any('differ in length' in w for w in warnings)
    assert any('nstates=4 needs the description state ranges' in w for w in warnings)
    mapping, warnings = mapping_from_description([5.0], [0.0])
    assert mapping.low == () and 'not usable' in warnings[0]


def test_states_outside_the_ranges_still_get_rows():
    mapping, _ = mapping_from_description([0.0, 0.0], [4.0, 4.0], resolution=0.5)
    index = StateIndex(mapping)
    assert not index.out_of_range([4.0, 0.0])
    assert index.out_of_range([4.5, 0.0])
    assert index.row([40.0, -3.0]) == 0 and index.row([1.0, 1.0]) == 1


@pytest.mark.parametrize(
    ('state', 'message'),
    [
        ([1.0, 2.0, 3.0], 'state has 3 features, expected 2'),
        ([1.0], 'state has 1 features, expected 2'),
        ([1.0, float('nan')], 'non-finite'),
        ([float('inf'), 0.0], 'non-finite'),
        ([[1.0, 2.0]], 'flat vector'),
        (['a', 'b'], 'not a vector of numbers'),
    ],
)
def test_unusable_states_are_rejected_without_change(state, message):
    index = StateIndex()
    index.row([0.0, 0.0])
    with pytest.raises(StateError, match=message):
        index.row(state)
    assert len(index) == 1 and index.dim == 2


def test_ranges_fix_the_dimension_before_the_first_state():
    mapping, _ = mapping_from_description([0.0, 0.0, 0.0], [1.0, 1.0, 1.0])
    with pytest.raises(StateError, match='expected 3'):
        StateIndex(mapping).row([0.0, 0.0])
