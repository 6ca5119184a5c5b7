"""Cross-check the controller's own `$$` settings against the driver's motion parameters.

ROS-free. After connecting, the session reads `$$`; motion is refused when the workspace,
mapped into machine coordinates, does not fit the controller's travel ($130-$132), or when a
driver rate exceeds the controller's maximum rate ($110-$112), which Grbl would otherwise cap
silently.

Which side of zero the travel lies on depends on the firmware: stock Grbl homes to 0 and its
machine space is [-travel, 0]; with HOMING_FORCE_SET_ORIGIN (and the simulator) it is
[0, travel] on an axis homing towards its minimum. `$$` does not say which, so each axis may
fit either; the controller's soft limits ($20) remain the authority on the exact side.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass

from .gcode import AXES, MotionConfig, Vector3

#: Slack for rounding when comparing machine coordinates with the travel [mm].
TRAVEL_TOLERANCE_MM = 0.0005
_SETTING_RE = re.compile(r'^\$(\d+)=([-+]?(?:\d+\.?\d*|\.\d+))$')
#: The `$n` numbers the check needs.
REQUIRED_SETTINGS = (20, 110, 111, 112, 130, 131, 132)


def parse_setting(line: str) -> tuple[int, float] | None:
    """Return (n, value) of a `$n=value` line from `$$`, or None for anything else."""
    match = _SETTING_RE.match(line.strip())
    if match is None:
        return None
    return int(match.group(1)), float(match.group(2))


@dataclass(frozen=True)
class MachineSettings:
    """The controller settings the driver checks itself against.

    Attributes:
        max_travel_mm: Travel per axis, $130-$132 [mm].
        max_rate_mm_min: Maximum rate per axis, $110-$112 [mm/min].
        soft_limits: Grbl refuses targets outside the travel itself, $20.
    """

    max_travel_mm: Vector3
    max_rate_mm_min: Vector3
    soft_limits: bool

    @classmethod
    def from_values(cls, values: Mapping[int, float]) -> MachineSettings:
        """Build from the `$n` values read.

        Raises:
            ValueError: When a setting in REQUIRED_SETTINGS is missing.
        """
        missing = [f'${number}' for number in REQUIRED_SETTINGS if number not in values]
        if missing:
            raise ValueError(f'the controller did not report {", ".join(missing)} in $$')
        return cls((values[130], values[131], values[132]),
                   (values[110], values[111], values[112]), bool(values[20]))

    def describe(self) -> str:
        """Summarise the settings in one line for the log."""
        travel = ' x '.join(f'{value:g}' for value in self.max_travel_mm)
        rates = ', '.join(f'{value:g}' for value in self.max_rate_mm_min)
        return (f'travel {travel} mm, max rates {rates} mm/min, soft limits '
                f"{'on' if self.soft_limits else 'off'}")


def settings_problem(settings: MachineSettings, motion: MotionConfig) -> str:
    """Return why the driver must not move with these controller settings, or ''.

    Args:
        settings: What the controller reported.
        motion: The driver's transform, workspace and rates.
    """
    problems = []
    low, high = motion.machine_limits_mm()
    tolerance = TRAVEL_TOLERANCE_MM
    for i, axis in enumerate(AXES):
        number = 130 + i
        travel = settings.max_travel_mm[i]
        positive = -tolerance <= low[i] and high[i] <= travel + tolerance
        negative = -travel - tolerance <= low[i] and high[i] <= tolerance
        if not (positive or negative):
            problems.append(
                f'the workspace maps to machine {axis} [{low[i]:.3f}, {high[i]:.3f}] mm, '
                f'outside the travel ${number}={travel:.3f} ([0, {travel:g}] or '
                f'[{-travel:g}, 0] mm)')
    for i, axis in enumerate(AXES):
        number = 110 + i
        rate, limit = motion.max_rate_mm_min[i], settings.max_rate_mm_min[i]
        if rate > limit:
            problems.append(f'max_rate_mm_min for {axis} is {rate:g} mm/min, above the '
                            f"controller's ${number}={limit:.3f}")
    return '; '.join(problems)
