"""Typed reading of the YAML files stealth-nav loads (maps, scenarios, their headers):
one error that names the file, the field and what was expected, never a KeyError or a
TypeError from deep inside, and no key given twice.
"""

from collections.abc import Callable, Mapping
import math
import numbers
import os
from pathlib import Path
from typing import Any, NoReturn

import numpy as np
import yaml

_REQUIRED = object()


class FieldReader:
    """Typed access to one YAML mapping, failing with one error that names file and field.

    Shared by the map loader and the scenario loader so both report problems the same way:
    ``<file>: field '<name>': expected <what>, got <value>``.
    """

    def __init__(
        self,
        source: str | os.PathLike,
        values: Mapping[str, Any],
        error: type[ValueError],
        prefix: str = '',
    ):
        self.source = str(source)
        self.values = values
        self.error = error
        self.prefix = prefix

    def name(self, key: str) -> str:
        return f'{self.prefix}{key}'

    def fail(self, key: str, expected: str, got: Any = _REQUIRED) -> NoReturn:
        found = 'nothing (the field is missing)' if got is _REQUIRED else _show(got)
        self.fail_with(key, expected, found)

    def fail_with(self, key: str, expected: str, found: str) -> NoReturn:
        """Fail with a description of what was found written out in full."""
        raise self.error(f'{self.where(key)}: expected {expected}, got {found}')

    def where(self, key: str) -> str:
        return f"{self.source}: field '{self.name(key)}'"

    def has(self, key: str) -> bool:
        return key in self.values

    def raw(self, key: str, expected: str, default: Any = _REQUIRED) -> Any:
        if key in self.values:
            return self.values[key]
        if default is _REQUIRED:
            self.fail(key, expected)
        return default

    def number(
        self,
        key: str,
        expected: str = 'a number',
        valid: Callable[[float], bool] = math.isfinite,
        default: Any = _REQUIRED,
    ) -> float:
        if default is not _REQUIRED and not self.has(key):
            return default
        value = self.raw(key, expected)
        if not is_number(value) or not math.isfinite(value) or not valid(float(value)):
            self.fail(key, expected, value)
        return float(value)

    def integer(
        self,
        key: str,
        expected: str = 'an integer',
        valid: Callable[[int], bool] = lambda _: True,
        default: Any = _REQUIRED,
    ) -> int:
        if default is not _REQUIRED and not self.has(key):
            return default
        value = self.raw(key, expected)
        if not is_number(value) or not isinstance(value, numbers.Integral) or not valid(value):
            self.fail(key, expected, value)
        return int(value)

    def string(self, key: str, expected: str = 'a non-empty string', default: Any = _REQUIRED):
        if default is not _REQUIRED and not self.has(key):
            return default
        value = self.raw(key, expected)
        if not isinstance(value, str) or not value.strip():
            self.fail(key, expected, value)
        return value

    def numbers(self, key: str, count: int, expected: str) -> tuple[float, ...]:
        value = self.raw(key, expected)
        if (
            not isinstance(value, list | tuple)
            or len(value) != count
            or not all(is_number(v) and math.isfinite(v) for v in value)
        ):
            self.fail(key, expected, value)
        return tuple(float(v) for v in value)

    def mapping(self, key: str, expected: str, default: Any = _REQUIRED) -> 'FieldReader':
        value = self.raw(key, expected, default)
        if not isinstance(value, Mapping):
            self.fail(key, expected, value)
        return FieldReader(self.source, value, self.error, f'{self.name(key)}.')

    def reject_unknown(self, known: tuple[str, ...] | list[str]) -> None:
        unknown = sorted(str(k) for k in self.values if k not in known)
        if unknown:
            expected = f'one of {", ".join(known)}'
            raise self.error(f'{self.where(unknown[0])}: unknown field, expected {expected}')


def is_number(value: Any) -> bool:
    """True for ints and floats (numpy's too), not for booleans, which Python counts as ints."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + '...'


class _UniqueKeyLoader(yaml.SafeLoader):
    """yaml.safe_load, except that a key given twice in one mapping is an error: PyYAML keeps
    the last value silently, and a scenario or map file must not mean something else than it
    seems to say."""

    def construct_mapping(self, node, deep=False):
        seen = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None,
                    None,
                    f'duplicate key {key!r} (first at line {seen[key] + 1})',
                    key_node.start_mark,
                )
            seen[key] = key_node.start_mark.line
        return super().construct_mapping(node, deep=deep)


def read_yaml_mapping(path: str | os.PathLike, error: type[ValueError], what: str) -> dict:
    """Parse a YAML file whose top level must be a mapping; one clear error otherwise."""
    try:
        text = Path(path).read_text(encoding='utf-8')
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise error(f'{path}: cannot read {what}: {reason}') from None
    try:
        values = yaml.load(text, Loader=_UniqueKeyLoader)  # a SafeLoader: no Python objects
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        where = f' at line {mark.line + 1}, column {mark.column + 1}' if mark else ''
        problem = getattr(exc, 'problem', None) or str(exc)
        raise error(f'{path}: YAML syntax error{where}: {problem}') from None
    if not isinstance(values, dict):
        raise error(f'{path}: expected a YAML mapping of {what} fields, got {_show(values)}')
    return values
