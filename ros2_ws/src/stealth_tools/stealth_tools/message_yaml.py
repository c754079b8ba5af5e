"""Messages as the YAML `ros2 topic echo` prints (rosidl_runtime_py's message_to_yaml).

rosidl_runtime_py is not on this platform; this walks `get_fields_and_field_types()` with the
field types in SLOT_TYPES the same way, with the same truncation and abbreviation rules.
"""

from __future__ import annotations

import array
from collections import OrderedDict
import sys

import numpy as np
from rosidl_parser.definition import (
    AbstractString,
    AbstractWString,
    Array,
    BasicType,
    BoundedSequence,
    NamedType,
    NamespacedType,
    UnboundedSequence,
)
import yaml

DEFAULT_TRUNCATE_LENGTH = 128


def _type_name(value_type) -> str:
    if isinstance(value_type, BasicType):
        return value_type.typename
    if isinstance(value_type, AbstractString):
        return 'string'
    if isinstance(value_type, AbstractWString):
        return 'wstring'
    if isinstance(value_type, NamedType):
        return value_type.name
    if isinstance(value_type, NamespacedType):
        return '/'.join(value_type.namespaced_name())
    return 'unknown'


def _abbreviated_array(value, field_type) -> str:
    element = _type_name(field_type.value_type)
    if isinstance(field_type, Array):
        return f'<array type: {element}[{field_type.size}]>'
    if isinstance(field_type, BoundedSequence):
        return f'<sequence type: {element}[{field_type.maximum_size}], length: {len(value)}>'
    if isinstance(field_type, UnboundedSequence):
        return f'<sequence type: {element}, length: {len(value)}>'
    return 'unknown'


def _convert(value, field_type=None, *, truncate_length=None, no_arr=False, no_str=False):
    options = {'truncate_length': truncate_length, 'no_arr': no_arr, 'no_str': no_str}
    if isinstance(value, bytes):
        shown = value if truncate_length is None else value[:truncate_length]
        text = ''.join(chr(c) for c in shown)
        return text + '...' if len(shown) < len(value) else text
    if isinstance(value, str):
        if no_str:
            return f'<string length: <{len(value)}>>'
        if truncate_length is not None and len(value) > truncate_length:
            return value[:truncate_length] + '...'
        return value
    if isinstance(value, (list, tuple, array.array, np.ndarray)):
        if no_arr and field_type is not None:
            return _abbreviated_array(value, field_type)
        truncated = truncate_length is not None and len(value) > truncate_length
        items = [_convert(v, **options) for v in value[: truncate_length if truncated else None]]
        return items + ['...'] if truncated else items
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (bool, float, int)):
        return value
    return message_to_ordereddict(value, **options)


def message_to_ordereddict(
    msg, *, truncate_length=None, no_arr=False, no_str=False
) -> OrderedDict:
    """The fields of a message, in .msg order, nested messages as nested dicts."""
    return OrderedDict(
        (
            name,
            _convert(
                getattr(msg, name, None),
                field_type,
                truncate_length=truncate_length,
                no_arr=no_arr,
                no_str=no_str,
            ),
        )
        for name, field_type in zip(msg.get_fields_and_field_types(), msg.SLOT_TYPES, strict=True)
    )


class _OrderedDumper(yaml.SafeDumper):
    """A dumper that writes OrderedDicts as plain mappings in their own order."""


_OrderedDumper.add_representer(
    OrderedDict, lambda dumper, data: dumper.represent_dict(list(data.items()))
)


def message_to_yaml(
    msg, *, truncate_length=None, no_arr=False, no_str=False, flow_style=False
) -> str:
    """The YAML text of a message, as `ros2 topic echo` prints it."""
    return yaml.dump(
        message_to_ordereddict(msg, truncate_length=truncate_length, no_arr=no_arr, no_str=no_str),
        Dumper=_OrderedDumper,
        allow_unicode=True,
        width=sys.maxsize,
        default_flow_style=flow_style,
    )
