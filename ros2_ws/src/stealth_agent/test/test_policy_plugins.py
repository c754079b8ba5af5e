"""Policy plugins (policy_plugins, grid_agent): the entry-point lookup and its one-line errors,
and the agent loop deciding on the grid observation (a state before the grid is held). No ROS:
the plugin here is this module's, registered by patching the entry points the lookup reads."""

from importlib import metadata

import numpy as np
import pytest
from stealth_agent import policy_plugins
from stealth_agent.agent_loop import AgentLoop
from stealth_agent.agent_messages import grid_from_msg
from stealth_agent.agent_parameters import change_problem, learns
from stealth_agent.policy_plugins import GROUP, PluginError, load_policy
from stealth_agent.protocol import BadInputError
from stealth_interfaces.msg import GridObservation, RLEnvDescription, RLStateReward
from test_agent_loop import FakeNode

ROWS, COLS = 3, 4
GEOMETRY = (0.5, -1.0, 2.0)  # resolution, origin x, origin y (m)


class RecordingPolicy:
    """Answers the robot's column mod 4 and records every grid it was asked about."""

    layout = 'test-grid/full'

    def __init__(self, path):
        self.path = path
        self.grids = []

    def check(self, layout):  # the full and the sensed layout
        if layout.split('/')[0] != self.layout.split('/')[0]:
            raise ValueError(f'{self.path}: trained for {self.layout!r}, got {layout!r}')

    def __call__(self, grid):
        self.grids.append(grid.copy())
        *_, col = np.unravel_index(int(np.argmax(grid[..., 1])), grid.shape[:-1])
        return int(col) % 4


def load_recording(path):
    if path == 'missing.npz':
        raise OSError(f'{path}: no such policy file')
    return RecordingPolicy(path)


@pytest.fixture
def plugins(monkeypatch):
    """Entry points: 'recording' (this module's) and 'broken' (a module that does not exist)."""
    entries = [
        metadata.EntryPoint('recording', f'{__name__}:load_recording', GROUP),
        metadata.EntryPoint('broken', 'no_such_module_for_stealth:load', GROUP),
    ]
    monkeypatch.setattr(policy_plugins.metadata, 'entry_points', lambda group: entries)
    policy_plugins.plugin_names.cache_clear()
    yield
    policy_plugins.plugin_names.cache_clear()


def grid_msg(layout=f'test-grid/full/{ROWS}x{COLS}', data=None):
    grid = np.zeros((ROWS, COLS, 7), np.float32)
    grid[..., 0] = 1.0
    message = GridObservation(layout=layout, rows=ROWS, cols=COLS, channels=7)
    message.resolution = GEOMETRY[0]
    message.origin.x, message.origin.y = GEOMETRY[1], GEOMETRY[2]
    message.data = grid.ravel().tolist() if data is None else data
    return message


def test_lookup_names_what_to_install(plugins):
    assert policy_plugins.plugin_names() == ('broken', 'recording')
    assert load_policy('recording', 'w.npz').path == 'w.npz'
    with pytest.raises(PluginError) as missing:
        load_policy('ppo', '')
    assert "no policy plugin 'ppo'" in str(missing.value) and 'make learn' in str(missing.value)
    with pytest.raises(PluginError) as broken:
        load_policy('broken', '')
    assert 'cannot be imported' in str(broken.value) and 'make learn' in str(broken.value)
    with pytest.raises(PluginError, match='missing.npz: no such policy file'):
        load_policy('recording', 'missing.npz')
    for error in (missing, broken):
        assert '\n' not in str(error.value)


def test_a_plugin_is_an_agent_that_does_not_learn(plugins):
    assert change_problem([('agent', 'recording')], None) is None
    assert 'recording' in change_problem([('agent', 'ppo')], None)
    assert not learns({'evaluate': False, 'agent': 'recording'})
    assert learns({'evaluate': False, 'agent': 'qlearning'})


def test_the_grid_message_is_read_and_checked():
    observed = grid_from_msg(grid_msg())
    assert observed.grid.shape == (ROWS, COLS, 7) and observed.geometry == GEOMETRY
    assert observed.cell_of(-1.0 + 0.5 * 2.5, 2.0 + 0.5 * 1.5) == (1, 2)
    with pytest.raises(BadInputError, match='outside the observation grid'):
        observed.cell_of(10.0, 2.0)
    with pytest.raises(BadInputError, match='data has 5 values'):
        grid_from_msg(grid_msg(data=[0.0] * 5))


def phased_grid_msg(layers=3, data=None):
    """A phased grid (moving lights): ``layers`` layers of 12 channels."""
    message = grid_msg(layout=f'test-grid/full/{layers}phases-1perstep/{ROWS}x{COLS}')
    message.layers, message.channels = layers, 12
    grid = np.zeros((layers, ROWS, COLS, 12), np.float32)
    grid[..., 0] = 1.0
    message.data = grid.ravel().tolist() if data is None else data
    return message


def test_a_phased_grid_is_read_with_its_layers():
    observed = grid_from_msg(phased_grid_msg())
    assert observed.grid.shape == (3, ROWS, COLS, 12) and observed.layers == 3
    assert observed.robot_at([0.25, 2.25, 2.0]) == (2, 0, 2)
    assert grid_from_msg(grid_msg()).robot_at([0.25, 2.25, 2.0]) == (0, 2)  # no layers
    for phase in (3.0, -1.0, 1.5, float('nan')):
        with pytest.raises(BadInputError, match=r'phase \(third feature\) an integer 0\.\.2'):
            observed.robot_at([0.25, 2.25, phase])
    with pytest.raises(BadInputError, match='phase'):
        observed.robot_at([0.25, 2.25])
    with pytest.raises(BadInputError, match=r'data has 144 values, .* = 2 x 3 x 4 x 12'):
        grid_from_msg(phased_grid_msg(layers=2, data=[0.0] * 144))
    message = grid_msg()
    message.layers = 0
    with pytest.raises(BadInputError, match='GridObservation: layers 0, expected >= 1'):
        grid_from_msg(message)


def test_on_a_phased_grid_the_robot_is_at_its_states_phase(plugins):
    """Moving lights: the state is (x, y, phase) and the robot channel is set at the phase's
    layer and the cell of (x, y); one grid serves every state."""
    node = FakeNode(agent='recording')
    loop = AgentLoop(node)
    loop.on_description(RLEnvDescription(
        num_actions=5, min_state_range=[-1.0, 2.0, 0.0], max_state_range=[1.0, 3.5, 2.0],
        title='t',
    ))  # fmt: skip
    loop.on_observation(phased_grid_msg())
    loop.on_state(RLStateReward(state=[0.25, 2.25, 2.0]), 1)
    loop.on_state(RLStateReward(state=[-0.75, 3.25, 0.0], reward=-1.0), 2)
    assert node.actions == [2, 0]
    _, first, second = loop.core.policy.grids  # the plan on arrival, then each decision
    assert first.shape == (3, ROWS, COLS, 12)
    assert first[2, 0, 2, 1] == 1.0 and first[..., 1].sum() == 1.0
    assert second[0, 2, 0, 1] == 1.0 and second[..., 1].sum() == 1.0
    assert len(loop.plan_seconds) == 1


def state(x, y, reward=0.0, terminal=False):
    return RLStateReward(state=[x, y], reward=reward, terminal=terminal)


def test_the_loop_decides_on_the_grid_and_holds_a_state_until_it_comes(plugins):
    node = FakeNode(agent='recording')
    loop = AgentLoop(node)
    description = RLEnvDescription(
        num_actions=4, min_state_range=[-1.0, 2.0], max_state_range=[1.0, 3.5], title='t'
    )
    loop.on_description(description)
    assert loop.core is not None, node.logs
    # The cell of (x, y) = (0.25, 2.25): row 0, col 2 (origin (-1, 2), 0.5 m cells).
    loop.on_state(state(0.25, 2.25), 1)
    assert node.actions == [] and node.told('warning', 'held until it arrives')
    assert not node.accepting_states
    loop.on_observation(grid_msg())
    assert node.accepting_states and node.actions == [2]
    policy = loop.core.policy
    asked = policy.grids[-1]
    assert asked[0, 2, 1] == 1.0 and asked[..., 1].sum() == 1.0
    loop.on_state(state(-0.75, 3.25, reward=-1.0), 2)  # row 2, col 0
    assert node.actions == [2, 0]
    assert policy.grids[-1][2, 0, 1] == 1.0 and policy.grids[-1][..., 1].sum() == 1.0
    loop.on_state(state(-0.75, 3.25, reward=5.0, terminal=True), 3)
    assert len(node.reports) == 1 and loop.states_received == 3
    assert loop.core.episode == 1 and not loop.core.learning


def sensed_grid_msg(light):
    """The sensed track's belief grid: ``light`` (ROWS, COLS) as last sensed, moves never."""
    grid = np.zeros((ROWS, COLS, 7), np.float32)
    grid[..., 0], grid[..., 3], grid[..., 4:6] = 1.0, light, -1.0
    return grid_msg(layout=f'test-grid/sensed/{ROWS}x{COLS}', data=grid.ravel().tolist())


def sensed_state(x, y, light, terminal=False):
    """A sensed-track state: x, y, lit, the light as sensed, the moves (never sensed)."""
    sensed = [*np.asarray(light, np.float32).ravel().tolist(), *[-1.0] * (2 * ROWS * COLS)]
    return RLStateReward(state=[x, y, 0.0, *sensed], terminal=terminal)


def test_on_the_sensed_track_a_state_waits_for_the_grid_it_carries(plugins):
    node = FakeNode(agent='recording', state_features=2)
    loop = AgentLoop(node)
    length = 3 + 3 * ROWS * COLS
    loop.on_description(RLEnvDescription(
        num_actions=4, min_state_range=[-1.0, 2.0] + [-2.0] * (length - 2),
        max_state_range=[1.0, 3.5] + [9.0] * (length - 2), title='t',
    ))  # fmt: skip
    first = np.full((ROWS, COLS), -1.0, np.float32)
    first[0, :2] = 0.25
    loop.on_observation(sensed_grid_msg(first))
    loop.on_state(sensed_state(0.25, 2.25, first), 1)  # its grid came first
    assert node.actions == [2]
    more = first.copy()
    more[1, :3] = 0.5
    loop.on_state(sensed_state(-0.75, 3.25, more), 2)  # its grid not yet: held, quietly
    assert node.actions == [2] and not node.told('warning', 'held')
    loop.on_observation(sensed_grid_msg(more))
    assert node.actions == [2, 0]
    policy = loop.core.policy
    np.testing.assert_array_equal(policy.grids[-1][..., 3], more)
    assert policy.grids[-1][2, 0, 1] == 1.0
    loop.on_state(sensed_state(0.25, 2.25, more), 3)  # nothing new sensed: the same grid
    assert node.actions == [2, 0, 2] and len(loop.plan_seconds) == 2
    loop.on_state(sensed_state(0.25, 2.25, first, terminal=True), 4)  # no decision: not held
    assert len(node.reports) == 1


def test_a_grid_of_another_layout_is_refused_naming_both(plugins):
    node = FakeNode(agent='recording')
    loop = AgentLoop(node)
    loop.on_description(
        RLEnvDescription(num_actions=4, min_state_range=[0.0, 0.0], max_state_range=[1.0, 1.0])
    )
    loop.on_observation(grid_msg(layout='other-grid/sensed/3x4'))
    (line,) = node.told('error', 'grid observation ignored')
    assert "'test-grid/full'" in line and "'other-grid/sensed/3x4'" in line
    assert not loop.core.ready


def test_an_unusable_plugin_leaves_the_agent_idle(plugins):
    node = FakeNode(agent='recording', policy_file='missing.npz')
    loop = AgentLoop(node)
    loop.on_description(
        RLEnvDescription(num_actions=4, min_state_range=[0.0, 0.0], max_state_range=[1.0, 1.0])
    )
    assert loop.core is None
    assert node.told('error', 'missing.npz: no such policy file')


def phased_sensed_grid_msg(mark=None, step=0, layers=3):
    """The phased grid of what was sensed (moving lights, track sensed): never sensed but the
    robot's channel, 1 at ``mark`` (layer, row, col) (None: no mark, as sent with the
    description); ``step``: the step of the state it goes with."""
    grid = np.zeros((layers, ROWS, COLS, 12), np.float32)
    grid[..., 0], grid[..., 3:6], grid[..., 7:] = 1.0, -1.0, -1.0
    if mark is not None:
        grid[(*mark, 1)] = 1.0
    message = phased_grid_msg(layers, grid.ravel().tolist())
    message.layout = f'test-grid/sensed/{layers}phases-1perstep/{ROWS}x{COLS}'
    message.step = step
    return message


def phased_sensed_state(x, y, phase, terminal=False):
    """A sensed-track state with moving lights: x, y, phase, lit, light and moves unknown."""
    return RLStateReward(state=[x, y, phase, 0.0, *[-1.0] * (3 * ROWS * COLS)], terminal=terminal)


def test_with_moving_lights_a_sensed_state_waits_for_the_grid_marked_at_its_place(plugins):
    """Moving lights, track sensed: the state's sensed part cannot tell the phased grids apart,
    so a state is decided only with the grid marked at its (phase, cell); an episode's first
    state only with a grid of step 0, never the last grid of the episode before."""
    node = FakeNode(agent='recording', state_features=3)
    loop = AgentLoop(node)
    length = 4 + 3 * ROWS * COLS
    loop.on_description(RLEnvDescription(
        num_actions=5, min_state_range=[-1.0, 2.0, 0.0] + [-2.0] * (length - 3),
        max_state_range=[1.0, 3.5, 2.0] + [9.0] * (length - 3), title='t',
    ))  # fmt: skip
    loop.on_observation(phased_sensed_grid_msg())  # with the description: marks no state
    loop.on_state(phased_sensed_state(0.25, 2.25, 0.0), 1)  # (layer 0, row 0, col 2)
    assert node.actions == []
    loop.on_observation(phased_sensed_grid_msg((0, 0, 2)))
    assert node.actions == [2]
    loop.on_state(phased_sensed_state(-0.75, 3.25, 1.0), 2)  # its grid not yet: held
    assert node.actions == [2]
    loop.on_observation(phased_sensed_grid_msg((1, 2, 0), step=1))
    assert node.actions == [2, 0]
    assert loop.core.policy.grids[-1][1, 2, 0, 1] == 1.0
    loop.on_state(phased_sensed_state(-0.75, 3.25, 2.0, terminal=True), 3)  # no grid, no wait
    assert len(node.reports) == 1
    # The next episode starts at a place the last grid marks: it waits for a grid of step 0.
    loop.on_observation(phased_sensed_grid_msg((0, 0, 2), step=5))
    loop.on_state(phased_sensed_state(0.25, 2.25, 0.0), 4)
    assert node.actions == [2, 0]
    loop.on_observation(phased_sensed_grid_msg((0, 0, 2)))
    assert node.actions == [2, 0, 2]
