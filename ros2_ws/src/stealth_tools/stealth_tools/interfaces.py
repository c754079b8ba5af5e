"""Message types and their definitions, read from the installed .msg files via the ament index.

rosbag2 stores each topic's type as a `ros2msg` schema: the type's .msg text, then the text of
every nested type, each after a line of 80 '=' and a line 'MSG: pkg/Type'. Foxglove and
mcap_ros2 decode CDR from nothing but that text, so it is assembled here exactly as rosbag2's
LocalMessageDefinitionSource does (same dependency regex, same sorted depth-first order).
"""

from __future__ import annotations

from collections.abc import Iterator
import importlib
from pathlib import Path
import re

from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

DEFINITION_ENCODING = 'ros2msg'
DELIMITER_LINE = '=' * 80
PRIMITIVE_TYPES = frozenset(
    {
        'bool',
        'byte',
        'char',
        'float32',
        'float64',
        'int8',
        'uint8',
        'int16',
        'uint16',
        'int32',
        'uint32',
        'int64',
        'uint64',
        'string',
    }
)
# 'pkg/Type' or 'pkg/msg/Type' (rosbag2's PACKAGE_TYPENAME_REGEX).
_TYPE_NAME = re.compile(r'^([a-zA-Z0-9_]+)/(?:msg/)?([a-zA-Z0-9_]+)$')
# The type of each field line (rosbag2's MSG_FIELD_TYPE_REGEX).
_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')


class InterfaceError(LookupError):
    """A type name that is malformed, or whose package or .msg file is not installed."""


def split_type_name(type_name: str) -> tuple[str, str]:
    """('pkg', 'Type') from 'pkg/msg/Type' or 'pkg/Type'."""
    match = _TYPE_NAME.match(type_name)
    if not match:
        raise InterfaceError(
            f"invalid message type '{type_name}' (expected package/msg/Type, e.g. "
            'std_msgs/msg/String)'
        )
    return match.group(1), match.group(2)


def full_type_name(type_name: str) -> str:
    """'pkg/msg/Type', the form the ROS graph and rosbag2 use."""
    package, name = split_type_name(type_name)
    return f'{package}/msg/{name}'


def msg_file(type_name: str) -> Path:
    """The installed share/<pkg>/msg/<Type>.msg of a message type."""
    package, name = split_type_name(type_name)
    try:
        share = Path(get_package_share_directory(package))
    except PackageNotFoundError:
        raise InterfaceError(f"package '{package}' not found (workspace not sourced?)") from None
    path = share / 'msg' / f'{name}.msg'
    if not path.is_file():
        raise InterfaceError(f"package '{package}' has no message '{name}' ({path} missing)")
    return path


def nested_type_names(msg_text: str, package: str) -> list[str]:
    """The non-primitive field types of a .msg text, qualified and sorted as rosbag2 does."""
    names = set()
    for match in _FIELD_TYPE.finditer(msg_text):
        field_type = match.group(1)
        if field_type in PRIMITIVE_TYPES:
            continue
        names.add(field_type if '/' in field_type else f'{package}/{field_type}')
    return sorted(names)


def definition_text(type_name: str) -> str:
    """The complete `ros2msg` definition of a type: its text, then every nested type's."""
    seen: set[str] = set()

    def append_recursive(name: str) -> str:
        text = msg_file(name).read_text()
        package, _ = split_type_name(name)
        for nested in nested_type_names(text, package):
            if nested not in seen:
                seen.add(nested)
                text += f'\n{DELIMITER_LINE}\nMSG: {nested}\n' + append_recursive(nested)
        return text

    return append_recursive(type_name)


def message_class(type_name: str):
    """The Python class of a message type (what rosidl_runtime_py's get_message returns)."""
    package, name = split_type_name(type_name)
    try:
        module = importlib.import_module(f'{package}.msg')
    except ImportError:
        raise InterfaceError(f"package '{package}' has no Python messages installed") from None
    try:
        return getattr(module, name)
    except AttributeError:
        raise InterfaceError(f"package '{package}' has no message '{name}'") from None


def _shown_line(line: str, package: str, name: str, show_comments: bool):
    """(text to print or None, nested type of the line or None), as `ros2 interface show`."""
    from rosidl_adapter.parser import parse_message_string

    spec = parse_message_string(pkg_name=package, msg_name=name, message_string=line)
    field = spec.fields[0] if spec.fields else None
    nested = None
    if field is not None and '/' in str(field.type):
        nested = str(field.type).split('[')[0]
    if show_comments:
        return line, nested
    if not line.strip() or spec.annotations.get('comment'):
        return None, nested
    element = field or (spec.constants[0] if spec.constants else None)
    comments = element.annotations.get('comment') if element is not None else None
    if comments:
        line = line[: line.rfind('#', 0, line.find(comments[0]))].rstrip()
    return line, nested


def show_interface_lines(
    type_name: str,
    *,
    show_comments: bool = True,
    show_nested_comments: bool = False,
    indent: int = 0,
) -> Iterator[str]:
    """The lines `ros2 interface show` prints: nested definitions follow their field, tabbed."""
    package, name = split_type_name(type_name)
    for raw in msg_file(type_name).read_text().splitlines():
        line, nested = _shown_line(raw.rstrip(), package, name, show_comments)
        if line is not None:
            yield '\t' * indent + line if line else ''
        if nested:
            yield from show_interface_lines(
                nested,
                show_comments=show_nested_comments,
                show_nested_comments=show_nested_comments,
                indent=indent + 1,
            )
