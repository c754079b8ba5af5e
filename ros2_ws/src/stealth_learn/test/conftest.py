"""Generated scenarios shared by the tests (generating one takes seconds): small buildings,
one with still lights and one with sweeping and patrolling lights."""

import pytest
from stealth_core.scenario import load_scenario
from stealth_core.scenario_generator import Options, generate

STILL = (11, Options(width=20, height=20, lights=3, moving='none'))
MOVING = (2, Options(width=20, height=20, lights=3, moving='mixed'))
WIDER = (5, Options(width=26, height=20, lights=2, moving='none', difficulty='easy'))


@pytest.fixture(scope='session')
def generated(tmp_path_factory):
    """{'still' | 'moving' | 'wider': Scenario} from the training seed range."""
    directory = tmp_path_factory.mktemp('generated')
    return {
        name: load_scenario(generate(seed, options).write(directory))
        for name, (seed, options) in (('still', STILL), ('moving', MOVING), ('wider', WIDER))
    }
