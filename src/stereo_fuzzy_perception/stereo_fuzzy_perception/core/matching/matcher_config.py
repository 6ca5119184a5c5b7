"""Settings and results of the window matcher (window_matcher.py describes the method).

MatcherConfig (validated on construction), the errors the matcher raises, MatchStatus (why a
pixel has, or has no, disparity; the kernel defines the codes) and DisparityMap (a match's
output). ROS-free: numpy only.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np

METHODS = ('zncc', 'plain')
PREPROCESS_MODES = ('none', 'edges', 'binary')
MAX_WINDOW_SIZE = 31
MAX_DISPARITY_RANGE = 512


class MatcherConfigError(ValueError):
    """A matcher setting out of its allowed range, named in the message."""


class MatcherInputError(ValueError):
    """Images the matcher cannot use (shape, dtype, size or a region outside the image)."""


class MatchStatus(enum.IntEnum):
    """Why a pixel of the disparity map has, or has no, disparity.

    The kernel defines the codes (window_matcher_kernel.h, MATCH_STATUSES, exported as
    _window_matcher_kernel.STATUS_CODES); test_window_matcher checks that the two agree.
    """

    VALID = 0
    OUTSIDE_ROI = 1
    NO_CANDIDATE = 2
    LOW_TEXTURE = 3
    LOW_SCORE = 4
    NOT_UNIQUE = 5
    LR_INCONSISTENT = 6
    SKIPPED_ROW = 7  # not matched: only every row_step-th row was asked for


@dataclass(frozen=True)
class MatcherConfig:
    """Settings of the window-correlation matcher; validated on construction.

    Attributes:
        method: `zncc` (Eq. 8) or `plain` (Eq. 7 divided by the window energies).
        window_size: Side of the square correlation window [px], odd, 3..31.
        min_disparity: Smallest disparity searched [px].
        disparity_range: Number of disparities searched [px], 1..512.
        min_score: Lowest accepted best score (-1..1).
        texture_threshold: Lowest accepted standard deviation of the left window [grey levels].
        uniqueness_ratio: Margin by which the best cost (1 - score) must beat every cost more
            than 1 px away (0 disables; 0.1 = 10 %).
        lr_check_max_diff: Largest accepted difference between the left disparity and the
            right pixel's own best disparity [px]; negative disables the check.
        subpixel: Refine disparities with a parabola fit around the peak.
        preprocess: `none`, `edges` (Sobel magnitude) or `binary` (Otsu threshold).
        roi: Region matched, (x, y, width, height) [px] in the left rectified image; a width or
            height of 0 means the whole image.
    """

    method: str = 'zncc'
    window_size: int = 9
    min_disparity: int = 0
    disparity_range: int = 64
    min_score: float = 0.3
    texture_threshold: float = 0.5
    uniqueness_ratio: float = 0.0
    lr_check_max_diff: int = 1
    subpixel: bool = True
    preprocess: str = 'none'
    roi: tuple[int, int, int, int] = field(default=(0, 0, 0, 0))

    def __post_init__(self) -> None:
        reason = self.problem()
        if reason:
            raise MatcherConfigError(reason)

    def problem(self) -> str | None:
        """Return why this configuration is unusable, or None."""
        if self.method not in METHODS:
            return f'method {self.method!r} is not one of {", ".join(METHODS)}'
        if not _is_int(self.window_size) or not 3 <= self.window_size <= MAX_WINDOW_SIZE:
            return f'window_size {self.window_size!r} must be an integer in 3..{MAX_WINDOW_SIZE}'
        if self.window_size % 2 == 0:
            return f'window_size {self.window_size} must be odd (the window has a centre pixel)'
        if not _is_int(self.min_disparity) or abs(self.min_disparity) > 4096:
            return f'min_disparity {self.min_disparity!r} must be an integer in -4096..4096'
        if (not _is_int(self.disparity_range)
                or not 1 <= self.disparity_range <= MAX_DISPARITY_RANGE):
            return (f'disparity_range {self.disparity_range!r} must be an integer in '
                    f'1..{MAX_DISPARITY_RANGE}')
        if not -1.0 <= self.min_score <= 1.0:
            return f'min_score {self.min_score} must be in -1..1 (a correlation coefficient)'
        if not self.texture_threshold >= 0.0:
            return f'texture_threshold {self.texture_threshold} must be >= 0 [grey levels]'
        if not 0.0 <= self.uniqueness_ratio <= 10.0:
            return f'uniqueness_ratio {self.uniqueness_ratio} must be in 0..10'
        if not _is_int(self.lr_check_max_diff) or self.lr_check_max_diff > MAX_DISPARITY_RANGE:
            return (f'lr_check_max_diff {self.lr_check_max_diff!r} must be an integer <= '
                    f'{MAX_DISPARITY_RANGE} (negative disables the check)')
        if self.preprocess not in PREPROCESS_MODES:
            return (f'preprocess {self.preprocess!r} is not one of '
                    f'{", ".join(PREPROCESS_MODES)}')
        if len(self.roi) != 4 or not all(_is_int(value) for value in self.roi):
            return f'roi {self.roi!r} must be four integers (x, y, width, height)'
        if any(value < 0 for value in self.roi):
            return f'roi {self.roi!r} must not hold negative values'
        return None

    @property
    def max_disparity(self) -> int:
        """Largest disparity searched [px]."""
        return self.min_disparity + self.disparity_range - 1


def _is_int(value: object) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


@dataclass(frozen=True)
class DisparityMap:
    """Output of the matcher for one rectified pair.

    Attributes:
        disparity: (H, W) float32 disparity [px] (left x minus right x), NaN where invalid.
        score: (H, W) float32 best score at each matched pixel (-1..1), NaN where no candidate
            was scored (outside the region of interest).
        status: (H, W) uint8 MatchStatus of each pixel.
        roi: The region actually matched, (x, y, width, height) [px].
        config: The settings used.
    """

    disparity: np.ndarray
    score: np.ndarray
    status: np.ndarray
    roi: tuple[int, int, int, int]
    config: MatcherConfig

    @property
    def valid(self) -> np.ndarray:
        """Return the (H, W) boolean mask of valid disparities."""
        valid: np.ndarray = self.status == MatchStatus.VALID
        return valid

    def status_counts(self) -> dict[str, int]:
        """Return how many pixels of the region of interest have each status, by name."""
        x, y, width, height = self.roi
        inside = self.status[y:y + height, x:x + width]
        counts = np.bincount(inside.ravel(), minlength=len(MatchStatus))
        return {status.name.lower(): int(counts[status]) for status in MatchStatus}
