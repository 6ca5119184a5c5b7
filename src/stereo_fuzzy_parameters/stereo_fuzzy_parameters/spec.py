"""Node parameters as plain data: the one place their names, defaults, ranges and docs live.

ROS-free, so the README tables and tests can read the same specs the nodes declare.
"""

from __future__ import annotations

from dataclasses import dataclass, field

ParameterValue = bool | int | float | str | list[float] | list[int] | list[str]


@dataclass(frozen=True)
class ParameterSpec:
    """One node parameter: default, documentation and the constraints rclpy should enforce.

    Attributes:
        name: Parameter name, dotted for groups (`qos.depth`).
        default: Default value; its Python type fixes the ROS parameter type.
        description: One line for the descriptor and the README, with units.
        minimum: Inclusive lower bound for int and float parameters.
        maximum: Inclusive upper bound for int and float parameters.
        choices: Allowed values of a string parameter (checked in the on-set callback).
        read_only: Wiring that must not change at run time (topics, ports, frames).
    """

    name: str
    default: ParameterValue
    description: str
    minimum: float | None = None
    maximum: float | None = None
    choices: tuple[str, ...] = field(default_factory=tuple)
    read_only: bool = False

    def constraint_text(self) -> str:
        """Describe the allowed values in words, for the descriptor and the README."""
        parts = []
        if self.minimum is not None or self.maximum is not None:
            parts.append(f'[{self.minimum}, {self.maximum}]')
        if self.choices:
            parts.append('one of ' + ', '.join(self.choices))
        if self.read_only:
            parts.append('read-only')
        return '; '.join(parts)

    def check(self, value: ParameterValue) -> str | None:
        """Return why `value` is not allowed for this parameter, or None if it is."""
        if self.choices and value not in self.choices:
            return f'{self.name}={value!r} is not one of {", ".join(self.choices)}'
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            if self.minimum is not None and value < self.minimum:
                return f'{self.name}={value} is below the minimum {self.minimum}'
            if self.maximum is not None and value > self.maximum:
                return f'{self.name}={value} is above the maximum {self.maximum}'
        return None
