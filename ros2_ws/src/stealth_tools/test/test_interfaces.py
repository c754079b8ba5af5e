"""Definition text in rosbag2's `ros2msg` form, `interface show`, type names."""

from mcap_ros2._dynamic import generate_dynamic
import pytest
from stealth_tools.interfaces import (
    DELIMITER_LINE,
    InterfaceError,
    definition_text,
    full_type_name,
    message_class,
    msg_file,
    nested_type_names,
    show_interface_lines,
)


def sections(text: str) -> list[tuple[str, str]]:
    """(type, text) of each part of a ros2msg definition, the root first as ('', text)."""
    parts = text.split(f'\n{DELIMITER_LINE}\n')
    result = [('', parts[0])]
    for part in parts[1:]:
        header, _, body = part.partition('\n')
        assert header.startswith('MSG: ')
        result.append((header[len('MSG: ') :], body))
    return result


def test_odometry_definition_is_rosbag2s_text_with_every_nested_type_once():
    text = definition_text('nav_msgs/msg/Odometry')
    parts = sections(text)
    # rosbag2: depth first, each type's dependencies in sorted order, each type only once.
    assert [name for name, _ in parts] == [
        '',
        'geometry_msgs/PoseWithCovariance',
        'geometry_msgs/Pose',
        'geometry_msgs/Point',
        'geometry_msgs/Quaternion',
        'geometry_msgs/TwistWithCovariance',
        'geometry_msgs/Twist',
        'geometry_msgs/Vector3',
        'std_msgs/Header',
        'builtin_interfaces/Time',
    ]
    for name, body in parts:
        # Each part is its .msg file verbatim, comments included.
        assert body == msg_file(name or 'nav_msgs/msg/Odometry').read_text()


def test_definition_text_lets_a_reader_build_a_decoder():
    for type_name in ('nav_msgs/msg/Odometry', 'stealth_interfaces/msg/SearchlightArray'):
        decoders = generate_dynamic(type_name, definition_text(type_name))
        assert type_name in decoders


def test_types_of_the_same_package_are_qualified_with_it():
    text = definition_text('stealth_interfaces/msg/SearchlightArray')
    names = [name for name, _ in sections(text)]
    assert 'stealth_interfaces/Searchlight' in names
    assert names.count('std_msgs/Header') == 1  # in both the array and each light: once
    assert {'geometry_msgs/Point', 'builtin_interfaces/Time'} <= set(names)


def test_nested_type_names_skip_primitives_constants_and_comments():
    text = (
        '# geometry_msgs/Comment is not a field\n'
        'uint8 KIND=1  # a constant\n'
        'float64[] values\n'
        'string<=5 short\n'
        'Searchlight[3] lights\n'
        'std_msgs/Header header\n'
    )
    assert nested_type_names(text, 'stealth_interfaces') == [  # sorted, as rosbag2's std::set
        'std_msgs/Header',
        'stealth_interfaces/Searchlight',
    ]


@pytest.mark.parametrize(
    ('name', 'why'),
    [
        ('String', 'invalid message type'),
        ('no_such_pkg/msg/Foo', "package 'no_such_pkg' not found"),
        ('std_msgs/msg/NoSuchType', "has no message 'NoSuchType'"),
    ],
)
def test_bad_type_names_say_why(name, why):
    with pytest.raises(InterfaceError, match=why):
        definition_text(name)


def test_type_names_and_classes():
    assert full_type_name('std_msgs/String') == 'std_msgs/msg/String'
    assert full_type_name('std_msgs/msg/String') == 'std_msgs/msg/String'
    assert message_class('std_msgs/msg/String')().data == ''
    with pytest.raises(InterfaceError, match='no message'):
        message_class('std_msgs/msg/Nope')


def test_interface_show_indents_nested_definitions_and_drops_their_comments():
    lines = list(show_interface_lines('stealth_interfaces/msg/SearchlightArray'))
    assert lines[0] == '# All searchlights of a scenario at one instant.'
    header = lines.index(
        "std_msgs/Header header   # stamp: time the lights' state holds for; frame_id: 'map'"
    )
    assert lines[header + 1 : header + 5] == [
        '\tbuiltin_interfaces/Time stamp',
        '\t\tint32 sec',
        '\t\tuint32 nanosec',
        '\tstring frame_id',
    ]
    assert '\tuint8 MOTION_STATIC=0' in lines
    assert '\t\tfloat64 x' in lines  # a light's position, two levels down


def test_interface_show_without_comments():
    lines = list(show_interface_lines('stealth_interfaces/msg/RLAction', show_comments=False))
    assert lines == ['int32 action']
