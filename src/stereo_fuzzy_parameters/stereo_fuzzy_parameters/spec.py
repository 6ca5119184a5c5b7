"""Node parameters as plain data: the one place their names, defaults, ranges and docs live.

A node's parameters are the fields of ONE frozen dataclass, its settings type: each field is
written once with `parameter(default, description, ...)` (groups of fields, such as `roi.x`,
with `parameter_group`), `parameter_specs` derives the ParameterSpec list that is declared on
the node and printed in the README, and `settings_from_values` turns the declared values into
the typed settings object the node uses. Cross-field rules are the settings type's `problem()`
method. As generate_parameter_library does from YAML, but from Python, so mypy sees the fields.

ROS-free, so the README tables and tests read the same specs the nodes declare.
"""

from __future__ import annotations

import array
import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, TypeVar

ParameterValue = bool | int | float | str | list[float] | list[int] | list[str]

_SPEC = 'stereo_fuzzy_parameters.spec'
_GROUP = 'stereo_fuzzy_parameters.group'

T = TypeVar('T')


@dataclass(frozen=True)
class ParameterSpec:
    """One node parameter: default, documentation and the constraints rclpy should enforce.

    Attributes:
        name: Parameter name, dotted for groups (`roi.x`).
        default: Default value; its Python type fixes the ROS parameter type.
        description: One line for the descriptor and the README, with units.
        minimum: Inclusive lower bound for int and float parameters (and array elements).
        maximum: Inclusive upper bound for int and float parameters (and array elements).
        choices: Allowed values of a string parameter (checked in the on-set callback).
        read_only: Wiring that must not change at run time (topics, ports, frames).
        size: Exact number of elements of an array parameter.
        dynamic_typing: Declared with dynamic typing: an integer given on the command line
            (`-p left_device:=0`) is accepted and read as its text.
    """

    name: str
    default: ParameterValue
    description: str
    minimum: float | None = None
    maximum: float | None = None
    choices: tuple[str, ...] = field(default_factory=tuple)
    read_only: bool = False
    size: int | None = None
    dynamic_typing: bool = False

    def constraint_text(self) -> str:
        """Describe the allowed values in words, for the descriptor and the README."""
        parts = []
        if self.size is not None:
            parts.append(f'{self.size} values')
        if self.minimum is not None or self.maximum is not None:
            parts.append(f'[{self.minimum}, {self.maximum}]')
        if self.choices:
            parts.append('one of ' + ', '.join(self.choices))
        if self.dynamic_typing:
            parts.append('integer or string')
        if self.read_only:
            parts.append('read-only')
        return '; '.join(parts)

    def check(self, value: object) -> str | None:
        """Return why `value` is not allowed for this parameter, or None if it is.

        The reason names the parameter, the value and what is allowed, in one line.
        """
        if self.choices and value not in self.choices:
            return f'{self.name}={value!r} is not one of {", ".join(self.choices)}'
        if isinstance(value, (list, tuple, array.array)):
            if self.size is not None and len(value) != self.size:
                return (f'{self.name}={list(value)!r} has {len(value)} values; allowed: '
                        f'{self.size} values')
            for element in value:
                reason = self._range_problem(element)
                if reason:
                    return f'{self.name}={list(value)!r}: element {reason}'
            return None
        reason = self._range_problem(value)
        return f'{self.name}={reason}' if reason else None

    def _range_problem(self, value: object) -> str | None:
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            return None
        allowed = f'allowed [{self.minimum}, {self.maximum}]'
        if self.minimum is not None and value < self.minimum:
            return f'{value} is below the minimum {self.minimum} ({allowed})'
        if self.maximum is not None and value > self.maximum:
            return f'{value} is above the maximum {self.maximum} ({allowed})'
        return None


def parameter(default: T, description: str, minimum: float | None = None,
              maximum: float | None = None, *, choices: Sequence[str] = (),
              read_only: bool = False, dynamic_typing: bool = False) -> T:
    """Declare a settings field as a node parameter named after the field.

    Use as the field's default: `window_size: int = parameter(9, 'Side [px]', 3, 31)`. Arrays
    are tuples in the settings (frozen) and lists on the ROS side, with their length fixed.

    Args:
        default: Default value; an int, float, bool, str or a tuple of them.
        description: One line with units, for the descriptor and the README.
        minimum: Inclusive lower bound (of every element, for arrays).
        maximum: Inclusive upper bound (of every element, for arrays).
        choices: Allowed values of a string parameter.
        read_only: The value cannot change after start-up (wiring, safety limits).
        dynamic_typing: Accept an integer on the command line and keep it as text.

    Returns:
        A dataclass field (typed as the default, as dataclasses.field is).
    """
    ros_default: Any = list(default) if isinstance(default, tuple) else default
    spec = ParameterSpec('', ros_default, description, minimum, maximum, tuple(choices),
                         read_only, len(default) if isinstance(default, tuple) else None,
                         dynamic_typing)
    result: T = field(default=default, metadata={_SPEC: spec})
    return result


def parameter_group(group_type: type[T], prefix: str | None = None) -> T:
    """Declare a settings field holding a group of parameters (a frozen dataclass).

    Args:
        group_type: The group's settings type; its defaults make the field's default.
        prefix: Prepended to the group's parameter names; default `<field name>.` (as in
            `roi.x`); '' declares the group's parameters under their own names.

    Returns:
        A dataclass field (typed as the group, as dataclasses.field is).
    """
    result: T = field(default_factory=group_type, metadata={_GROUP: prefix})
    return result


def _fields(settings_type: type[Any], prefix: str = '') -> list[tuple[str, str, Any]]:
    """Return (parameter name or group prefix, field name, spec or group type) in order."""
    entries: list[tuple[str, str, Any]] = []
    for item in dataclasses.fields(settings_type):
        name = item.name
        if _SPEC in item.metadata:
            entries.append((prefix + name, name, item.metadata[_SPEC]))
        elif _GROUP in item.metadata:
            group_prefix = item.metadata[_GROUP]
            group_prefix = f'{name}.' if group_prefix is None else group_prefix
            group_type = item.default_factory
            entries.append((prefix + group_prefix, name, group_type))
        else:
            raise TypeError(f'{settings_type.__name__}.{name} is neither a parameter() nor a '
                            'parameter_group()')
    return entries


def parameter_specs(settings_type: type[Any]) -> list[ParameterSpec]:
    """Return the ParameterSpec of every parameter of a settings type, in field order."""
    specs: list[ParameterSpec] = []

    def collect(current: type[Any], prefix: str) -> None:
        for name, _, entry in _fields(current, prefix):
            if isinstance(entry, ParameterSpec):
                specs.append(dataclasses.replace(entry, name=name))
            else:
                collect(entry, name)

    collect(settings_type, '')
    names = [spec.name for spec in specs]
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise TypeError(f'{settings_type.__name__} declares {", ".join(repeated)} twice')
    return specs


def settings_from_values(settings_type: type[T], values: Mapping[str, object]) -> T:
    """Build the settings object from parameter values by name, checking every value.

    Arrays become tuples, dynamically typed values their text (None: ''). Groups' and the
    settings type's `problem()` methods are called, innermost first.

    Raises:
        SettingsError: A value is not allowed or the values do not work together; the
            message names the parameter, the value and what is allowed.
    """
    def build(current: type[Any], prefix: str) -> Any:
        arguments: dict[str, Any] = {}
        for name, field_name, entry in _fields(current, prefix):
            if not isinstance(entry, ParameterSpec):
                arguments[field_name] = build(entry, name)
                continue
            value = values[name]
            if entry.dynamic_typing:
                value = '' if value is None else str(value)
            reason = dataclasses.replace(entry, name=name).check(value)
            if reason:
                raise SettingsError(reason)
            if isinstance(value, (list, tuple, array.array)):
                value = tuple(value)
            arguments[field_name] = value
        settings = current(**arguments)
        problem = getattr(settings, 'problem', None)
        reason = problem() if problem is not None else None
        if reason:
            raise SettingsError(reason)
        return settings

    result: T = build(settings_type, '')
    return result


def settings_values(settings: object) -> dict[str, ParameterValue]:
    """Return the parameter values of a settings object by name (arrays as lists)."""
    values: dict[str, ParameterValue] = {}

    def collect(current: object, prefix: str) -> None:
        for name, field_name, entry in _fields(type(current), prefix):
            value = getattr(current, field_name)
            if isinstance(entry, ParameterSpec):
                values[name] = list(value) if isinstance(value, tuple) else value
            else:
                collect(value, name)

    collect(settings, '')
    return values


class SettingsError(ValueError):
    """Parameter values that make no valid settings; the message names parameter and value."""
