"""config/nav2_exposure_filter.yaml, the Nav2 parameter snippet, against the node it consumes:
every costmap's filter is a KeepoutFilter listening on the node's filter info topic, and the
costmaps update at least as often as the mask's 5 Hz target."""

from pathlib import Path

import pytest
from stealth_nav2.exposure_mask_node import PARAMETERS
import yaml

SNIPPET = Path(__file__).resolve().parents[1] / 'config' / 'nav2_exposure_filter.yaml'


@pytest.fixture(scope='module')
def costmaps() -> dict:
    document = yaml.safe_load(SNIPPET.read_text(encoding='utf-8'))
    return {name: document[name][name]['ros__parameters'] for name in document}


def test_both_costmaps_use_the_keepout_filter_on_the_nodes_info_topic(costmaps):
    assert set(costmaps) == {'global_costmap', 'local_costmap'}
    for parameters in costmaps.values():
        (name,) = parameters['filters']
        plugin = parameters[name]
        assert plugin['plugin'] == 'nav2_costmap_2d::KeepoutFilter'
        assert plugin['enabled'] is True
        assert plugin['filter_info_topic'] == PARAMETERS['filter_info_topic'].default
        assert parameters['update_frequency'] >= 5.0
