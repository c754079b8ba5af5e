"""Messages as `ros2 topic echo` prints them."""

from nav_msgs.msg import OccupancyGrid
from std_msgs.msg import Header, String
from stealth_interfaces.msg import RLStateReward, Searchlight, SearchlightArray
from stealth_tools.message_yaml import message_to_ordereddict, message_to_yaml


def test_fields_in_msg_order_nested_as_mappings():
    header = Header(frame_id='map')
    header.stamp.sec, header.stamp.nanosec = 1, 2
    assert message_to_yaml(header) == 'stamp:\n  sec: 1\n  nanosec: 2\nframe_id: map\n'
    assert message_to_yaml(String(data='hello ü')) == 'data: hello ü\n'


def test_arrays_become_lists_and_are_truncated_like_ros2():
    message = RLStateReward(state=[1.5, 2.0, 2.5], reward=-1.0, terminal=True)
    assert message_to_yaml(message) == (
        'state:\n- 1.5\n- 2.0\n- 2.5\nreward: -1.0\nterminal: true\n'
    )
    assert message_to_ordereddict(message, truncate_length=2)['state'] == [1.5, 2.0, '...']
    assert message_to_ordereddict(message, no_arr=True)['state'] == (
        '<sequence type: float, length: 3>'
    )
    grid = OccupancyGrid(data=[0, 100, -1])
    assert message_to_ordereddict(grid)['data'] == [0, 100, -1]


def test_strings_can_be_hidden_or_cut():
    message = String(data='abcdef')
    assert message_to_ordereddict(message, no_str=True) == {'data': '<string length: <6>>'}
    assert message_to_ordereddict(message, truncate_length=3) == {'data': 'abc...'}


def test_sequences_of_messages_are_lists_of_mappings():
    lights = SearchlightArray(lights=[Searchlight(name='a'), Searchlight(name='b')])
    converted = message_to_ordereddict(lights)
    assert [light['name'] for light in converted['lights']] == ['a', 'b']
    assert '- header:\n' in message_to_yaml(lights)
