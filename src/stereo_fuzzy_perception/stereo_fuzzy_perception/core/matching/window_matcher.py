"""Window correlation along rectified rows: the chapter's Eqs. 7 and 8 as a dense matcher.

For every left pixel (x, y) inside the region of interest, a `window_size` x `window_size` window
is compared with the windows of the right image centred on (x - d, y), for the disparities
d = min_disparity .. min_disparity + disparity_range - 1 (convention: left (x, y) matches right
(x - d, y), so d > 0 for points in front of rectified cameras). The disparity with the highest
score wins, then validity filters decide whether it is trusted:

* `method='zncc'` scores with the correlation coefficient of Eq. 8 (zero-mean normalised
  cross-correlation, -1..1): invariant to a gain and an offset of either image's intensities.
* `method='plain'` scores with Eq. 7, the plain sum of products, divided by the two windows'
  energies, sum(f w) / sqrt(sum f^2 sum w^2) (0..1 for non-negative intensities): comparable across
  windows and with the same `min_score` scale, invariant to a gain but not to an offset.

Validity filters (each a MatcherConfig value; a rejected pixel gets NaN and a MatchStatus code):

* texture: the left window's standard deviation must reach `texture_threshold` [grey levels]; below
  it Eq. 8 divides noise by noise. A right window below it scores 0 as a candidate.
* score: the best score must reach `min_score`.
* uniqueness: with costs 1 - score, the best cost times (1 + `uniqueness_ratio`) must stay below
  every cost more than 1 px away from the best (StereoBM's uniquenessRatio, as a fraction).
* left-right consistency: the right pixel's own best score (over all its candidates, from the
  same scores) must be reached by a candidate within `lr_check_max_diff` [px] of the left's
  disparity (< 0 disables the check); occluded pixels fail it.
* sub-pixel: a parabola through the scores at the best disparity and its two neighbours refines
  the disparity (`subpixel`).

Windows lie inside the image horizontally (the window_size // 2 columns at each side get no
disparity, as with StereoBM); rows are padded by reflection, which is exact for rectified rows, so
the top and bottom rows are matched. A pixel near the left edge is matched against the disparities
that keep its right window inside the image (StereoBM instead gives up on the leftmost
min_disparity + disparity_range columns); the left-right check rejects it when its true partner
has left the image.

The speed comes from two kernels: window means and variances come from one numba pass of
running sums per image (_prepare_image), so each (pixel, disparity) cell needs only the cross
term sum(f w), kept as running column sums (updated with one new and one old row) and running
window sums along the row: O(1) per cell whatever the window size. That loop is C
(window_matcher_kernel.c, built by colcon), with the disparity loop innermost and contiguous (the
right image is stored with its columns reversed for that); numba runs it over bands of rows in
parallel. For 8-bit images the sums are of integers below 2^24 and therefore exact in float32.
Working memory is kept between calls (_ScratchMemory), and so are the output arrays once the caller
has dropped the previous result: allocating them per pair cost a quarter of the time in page
faults.

ROI ("correlation area", Fig. 2 of the chapter): only pixels inside `roi` are matched, which
divides the work by the share of the image it covers. Preprocessing (Fig. 8): `edges` correlates
Sobel gradient magnitudes, `binary` correlates Otsu-thresholded images.

ROS-free: numpy, OpenCV, numba and the C kernel only.
"""

from __future__ import annotations

import ctypes
import enum
import importlib.util
import math
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import cv2
import numba
import numpy as np
from llvmlite import binding as llvm_binding
from numba.core import cgutils
from numba.extending import intrinsic

METHODS = ('zncc', 'plain')
PREPROCESS_MODES = ('none', 'edges', 'binary')
MAX_WINDOW_SIZE = 31
MAX_DISPARITY_RANGE = 512
# Inside the kernel, scores are int32 fixed point with 1.0 = _SCORE_ONE; _NO_SCORE marks "no
# candidate" (no NaN or infinity under fastmath).
_SCORE_ONE = float(1 << 24)
_NO_SCORE = -3 * (1 << 24)
# Windows whose standard deviation is below this [grey levels] are flat whatever the threshold.
_FLAT_STD = 1e-3


class MatcherConfigError(ValueError):
    """A matcher setting out of its allowed range, named in the message."""


class MatcherInputError(ValueError):
    """Images the matcher cannot use (shape, dtype, size or a region outside the image)."""


class MatchStatus(enum.IntEnum):
    """Why a pixel of the disparity map has, or has no, disparity."""

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


# --- input preparation ------------------------------------------------------------------------


def preprocess_image(image: np.ndarray, mode: str) -> np.ndarray:
    """Apply the chapter's optional preprocessing (Fig. 8) to a grey image.

    Args:
        image: (H, W) grey image, uint8, uint16 or float.
        mode: `none` (returned as is), `edges` (Sobel gradient magnitude, uint8, scaled so
            that a full-range step reads 255) or `binary` (Otsu threshold, 0 or 255).

    Returns:
        The preprocessed (H, W) image.

    Raises:
        MatcherConfigError: For an unknown mode.
    """
    if mode == 'none':
        return image
    if mode not in PREPROCESS_MODES:
        raise MatcherConfigError(
            f'preprocess {mode!r} is not one of {", ".join(PREPROCESS_MODES)}')
    grey8 = _to_uint8(image)
    if mode == 'binary':
        binary: np.ndarray
        _, binary = cv2.threshold(grey8, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
        return binary
    gx = cv2.Sobel(grey8, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(grey8, cv2.CV_32F, 0, 1, ksize=3)
    # Integer gradients: the sum of squares is exact in float32 and numpy's sqrt is correctly
    # rounded. cv2.magnitude is not: its SIMD and scalar paths differ in the last bit, so an
    # image's edges changed by 1 grey level with the array's address (and so did matches).
    magnitude = np.sqrt(gx * gx + gy * gy) * np.float32(255.0 / (4.0 * 255.0))
    edges: np.ndarray = np.clip(np.rint(magnitude), 0, 255).astype(np.uint8)
    return edges


def _to_uint8(image: np.ndarray) -> np.ndarray:
    if image.dtype == np.uint8:
        return image
    if image.dtype == np.uint16:
        return (image >> 8).astype(np.uint8)
    clipped: np.ndarray = np.clip(np.rint(image), 0, 255).astype(np.uint8)
    return clipped


def _intensity_scale(image: np.ndarray, centre: bool) -> tuple[float, float]:
    """Return (gain, shift): the kernel reads float32(pixel) * gain - shift, a 0..255 scale
    shifted by -128 when `centre`. 8-bit images stay integer-valued, which keeps the kernel's
    window sums exact."""
    gain = 255.0 / 65535.0 if image.dtype == np.uint16 else 1.0
    return gain, 128.0 if centre else 0.0


def _check_images(left: np.ndarray, right: np.ndarray, config: MatcherConfig) -> None:
    for side, image in (('left', left), ('right', right)):
        if image.ndim != 2:
            raise MatcherInputError(
                f'{side} image has shape {image.shape}; the matcher needs one grey channel (H, W)')
        if not (np.issubdtype(image.dtype, np.integer) or np.issubdtype(image.dtype, np.floating)):
            raise MatcherInputError(f'{side} image has unsupported dtype {image.dtype}')
    if left.shape != right.shape:
        raise MatcherInputError(
            f'left image is {left.shape[1]}x{left.shape[0]} but right image is '
            f'{right.shape[1]}x{right.shape[0]}: a rectified pair has one size')
    height, width = left.shape
    if height < 1 or width < 1:
        raise MatcherInputError(f'image {width}x{height} is empty')


def effective_roi(config: MatcherConfig, width: int, height: int) -> tuple[int, int, int, int]:
    """Return the region matched for an image of `width` x `height` [px], clipped to it.

    Raises:
        MatcherInputError: When the configured region lies outside the image.
    """
    x, y, roi_width, roi_height = config.roi
    if roi_width == 0 or roi_height == 0:
        return 0, 0, width, height
    x_end, y_end = min(width, x + roi_width), min(height, y + roi_height)
    if x >= width or y >= height or x_end <= x or y_end <= y:
        raise MatcherInputError(
            f'roi {config.roi} (x, y, width, height) lies outside the {width}x{height} image')
    return x, y, x_end - x, y_end - y


# --- the C kernel -----------------------------------------------------------------------------


_KERNEL_SYMBOL = 'stereo_fuzzy_correlate_band'


def _load_band_kernel() -> None:
    """Make the C kernel, built by colcon from window_matcher_kernel.c, callable from numba.

    The kernel is known to numba by symbol name rather than as a ctypes object, so that the
    numba functions calling it can be cached on disk like the others.
    """
    module = f'{__package__}._window_matcher_kernel'
    spec = importlib.util.find_spec(module)
    if spec is None or spec.origin is None:
        raise ImportError(f'{module} (the matcher kernel, window_matcher_kernel.c) is not '
                          'built: run scripts/setup.sh, or colcon build in ros2_ws')
    address = ctypes.cast(getattr(ctypes.CDLL(spec.origin), _KERNEL_SYMBOL), ctypes.c_void_p)
    llvm_binding.add_symbol(_KERNEL_SYMBOL, address.value)


_load_band_kernel()
_POINTER, _I64, _F32 = numba.types.voidptr, numba.types.int64, numba.types.float32
_correlate_band: Any = numba.types.ExternalFunction(_KERNEL_SYMBOL, numba.types.void(
    *[_POINTER] * 7, *[_I64] * 10, _F32, _F32, *[_I64] * 3, _F32, *[_POINTER] * 8))


@intrinsic
def _void_pointer(typing_context: Any, address: Any) -> tuple[Any, Any]:
    """numba intrinsic: the integer `address` as a void pointer."""
    def codegen(context: Any, builder: Any, signature: Any, arguments: list[Any]) -> Any:
        return builder.inttoptr(arguments[0], cgutils.voidptr_t)
    return numba.types.voidptr(address), codegen


@numba.njit(inline='always')
def _data(array: np.ndarray) -> Any:
    """Return the address of a C-contiguous array's first element, as the C kernel takes it."""
    return _void_pointer(array.ctypes.data)  # type: ignore[call-arg]


# --- window statistics ------------------------------------------------------------------------


@numba.njit(cache=True, nogil=True)
def _reflect(index: int, size: int) -> int:
    """Mirror an index into 0..size-1 without repeating the edge (OpenCV's BORDER_REFLECT_101)."""
    if index < 0:
        return -index
    if index >= size:
        return 2 * (size - 1) - index
    return index


@numba.njit(cache=True, nogil=True)
def _intensity(image: np.ndarray, row: int, column: int, gain: np.float32,
               shift: np.float32) -> np.float32:
    # Two float32 roundings, as numpy's astype, multiply and subtract make them.
    return np.float32(np.float32(image[row, column]) * gain) - shift


# No fastmath: a fused multiply-add would round the padded intensities differently.
@numba.njit(cache=True, nogil=True, parallel=True)
def _prepare_image(image: np.ndarray, gain: float, shift: float, radius: int, zero_mean: bool,
                   texture_threshold: float, reverse: bool, band_count: int,
                   padded_out: np.ndarray, offset_out: np.ndarray, mean_out: np.ndarray,
                   scale_out: np.ndarray, texture_out: np.ndarray) -> None:
    """Write an image's float32 intensities (rows padded by reflection) and its window terms.

    Columns are stored reversed when `reverse` (the right image). Window sums come from running
    float64 column sums, windows reflected at the image edges (as cv2.boxFilter's default);
    per pixel: offset = count * mean * scale, mean = window mean (0 for Eq. 7), scale =
    1 / sqrt(energy) with energy the sum of squared deviations (Eq. 8) or of squares (Eq. 7), 0
    where the window is textureless; texture = the window's standard deviation reaches the
    threshold. One pass over the image, in row bands processed in parallel.
    """
    height, width = image.shape
    size = 2 * radius + 1
    count = float(size * size)
    gain32, shift32 = np.float32(gain), np.float32(shift)
    # The window's standard deviation sqrt(deviation / count) reaches the threshold (and is not
    # flat) where the deviation reaches this.
    textured_energy = count * max(texture_threshold, _FLAT_STD * (1.0 + 1e-9)) ** 2
    band_rows = (height + band_count - 1) // band_count
    for band in numba.prange(band_count):
        y_first = band * band_rows
        y_stop = min(height, y_first + band_rows)
        if y_first >= y_stop:
            continue
        padded_first = 0 if y_first == 0 else y_first + radius
        padded_stop = height + 2 * radius if y_stop == height else y_stop + radius
        for padded_row in range(padded_first, padded_stop):
            source = _reflect(padded_row - radius, height)
            for x in range(width):
                column = width - 1 - x if reverse else x
                padded_out[padded_row, column] = _intensity(image, source, x, gain32, shift32)
        # Column sums of image column x at index x + radius, with radius + 1 reflected columns
        # on each side: the running sums along a row then need no edge test per pixel.
        column_sum = np.zeros(width + 2 * radius + 1)
        column_square = np.zeros(width + 2 * radius + 1)
        window_sum = np.empty(width)
        window_square = np.empty(width)
        for step in range(-radius, radius + 1):
            source = _reflect(y_first + step, height)
            for x in range(width):
                value = np.float64(_intensity(image, source, x, gain32, shift32))
                column_sum[x + radius] += value
                column_square[x + radius] += value * value
        for y in range(y_first, y_stop):
            for index in range(-radius, 0):
                column_sum[index + radius] = column_sum[-index + radius]
                column_square[index + radius] = column_square[-index + radius]
            for index in range(width, width + radius + 1):
                column_sum[index + radius] = column_sum[2 * (width - 1) - index + radius]
                column_square[index + radius] = column_square[2 * (width - 1) - index + radius]
            total = 0.0
            square_total = 0.0
            for index in range(0, 2 * radius + 1):
                total += column_sum[index]
                square_total += column_square[index]
            for x in range(width):  # running window sums along the row
                window_sum[x] = total
                window_square[x] = square_total
                total += column_sum[x + 2 * radius + 1] - column_sum[x]
                square_total += column_square[x + 2 * radius + 1] - column_square[x]
            # The terms in a loop of their own, without branches, so that it vectorises: the
            # square root and division dominate this kernel.
            for x in range(width):
                total, square_total = window_sum[x], window_square[x]
                deviation = max(square_total - total * total / count, 0.0)
                textured = deviation >= textured_energy
                energy = deviation if zero_mean else square_total
                scale = 1.0 / math.sqrt(energy) if textured and energy > 0.0 else 0.0
                column = width - 1 - x if reverse else x
                offset_out[y, column] = total * scale if zero_mean else 0.0
                mean_out[y, column] = total / count if zero_mean else 0.0
                scale_out[y, column] = scale
                texture_out[y, column] = textured
            if y + 1 < y_stop:
                entering_row = _reflect(y + radius + 1, height)
                leaving_row = _reflect(y - radius, height)
                for x in range(width):
                    new = np.float64(_intensity(image, entering_row, x, gain32, shift32))
                    old = np.float64(_intensity(image, leaving_row, x, gain32, shift32))
                    column_sum[x + radius] += new - old
                    column_square[x + radius] += new * new - old * old


# --- matching: row bands in parallel, each by the C kernel ------------------------------------


@numba.njit(cache=True, nogil=True, parallel=True)
def _correlate_bands(left_padded: np.ndarray, right_reversed: np.ndarray, left_scale: np.ndarray,
                     left_offset: np.ndarray, right_mean_reversed: np.ndarray,
                     right_scale_reversed: np.ndarray, texture_ok: np.ndarray, radius: int,
                     min_disparity: int, disparity_range: int, x_begin: int, x_end: int,
                     y_begin: int, y_end: int, out_x_begin: int, out_x_end: int,
                     min_score: np.float32, uniqueness_ratio: np.float32, lr_max_diff: int,
                     subpixel: bool, band_count: int, row_step: int,
                     band_column_sums: np.ndarray, band_row_scores: np.ndarray,
                     band_window_sums: np.ndarray, band_right_best: np.ndarray,
                     band_best_score: np.ndarray, disparity_out: np.ndarray,
                     score_out: np.ndarray, status_out: np.ndarray) -> None:
    """Match rows y_begin..y_end-1 over columns x_begin..x_end-1 (inside r..W-1-r), in bands
    of rows processed in parallel by the C kernel (window_matcher_kernel.c describes the arrays).

    Decisions are written for columns out_x_begin..out_x_end-1. Scores are int32 fixed point
    (_SCORE_ONE = 1.0): integer maxima vectorise, and 2^-24 is finer than float32 resolves a
    score anyway. Only rows y with y % row_step == 0 are decided; the others only advance the
    running column sums. The band_* arrays are each band's working memory (first axis: band),
    reused between calls.
    """
    width = texture_ok.shape[1]
    rows = y_end - y_begin
    band_rows = (rows + band_count - 1) // band_count
    refine = 1 if subpixel else 0  # (numba cannot branch inside a call's arguments)
    score_one = np.float32(_SCORE_ONE)
    for band in numba.prange(band_count):
        y_first = y_begin + band * band_rows
        y_stop = min(y_end, y_first + band_rows)
        if y_first >= y_stop:
            continue
        _correlate_band(
            _data(left_padded), _data(right_reversed), _data(left_scale), _data(left_offset),
            _data(right_mean_reversed), _data(right_scale_reversed), _data(texture_ok), width,
            radius, min_disparity, disparity_range, x_begin, x_end, y_first, y_stop,
            out_x_begin, out_x_end, min_score, uniqueness_ratio, lr_max_diff,
            refine, row_step, score_one,
            _data(band_column_sums[band]), _data(band_row_scores[band]),
            _data(band_window_sums[band]), _data(band_right_best[band]),
            _data(band_best_score[band]), _data(disparity_out), _data(score_out),
            _data(status_out))


# --- public API -------------------------------------------------------------------------------


def match(left: np.ndarray, right: np.ndarray, config: MatcherConfig | None = None,
          band_count: int | None = None, row_step: int = 1) -> DisparityMap:
    """Match a rectified grey pair by window correlation and return the disparity map.

    Args:
        left: (H, W) left rectified grey image (uint8 gives exact sums; uint16 and float are
            scaled to 0..255).
        right: (H, W) right rectified grey image, same size.
        config: Matcher settings; MatcherConfig() when None.
        band_count: Row bands matched in parallel; by default 4 per numba thread.
        row_step: Decide only the rows y with y % row_step == 0 (the rows a triangulation with
            that stride keeps); the others get status SKIPPED_ROW. The decided rows are
            exactly those of row_step 1.

    Returns:
        The disparity map [px], scores and per-pixel status.

    Raises:
        MatcherInputError: For images that are not one grey channel, differ in size, are
            smaller than the window, or a region of interest outside the image.
    """
    config = config or MatcherConfig()
    if row_step < 1:
        raise ValueError(f'row_step {row_step} must be >= 1')
    _check_images(left, right, config)
    height, width = left.shape
    if height < config.window_size or width < config.window_size:
        raise MatcherInputError(
            f'image {width}x{height} is smaller than the {config.window_size}x'
            f'{config.window_size} correlation window')
    roi_x, roi_y, roi_width, roi_height = effective_roi(config, width, height)
    radius = config.window_size // 2
    if config.preprocess != 'none':
        left = preprocess_image(left, config.preprocess)
        right = preprocess_image(right, config.preprocess)
    # numba has no float16; any other integer or float dtype is read as it is
    left, right = (image.astype(np.float32) if image.dtype == np.float16 else image
                   for image in (left, right))
    bands = max(1, min(band_count or 4 * numba.get_num_threads(), roi_height))
    work = _scratch_memory(height, width, radius, config.disparity_range, bands)
    for image, padded, terms, reverse in ((left, work.left_padded, work.left_terms, False),
                                          (right, work.right_reversed, work.right_terms, True)):
        gain, shift = _intensity_scale(image, config.method == 'zncc')
        _prepare_image(image, gain, shift, radius, config.method == 'zncc',
                       float(config.texture_threshold), reverse, work.prepare_bands, padded,
                       *terms)
    disparity, score, status = work.outputs()
    disparity.fill(np.nan)
    score.fill(np.nan)
    status.fill(MatchStatus.OUTSIDE_ROI)
    status[roi_y:roi_y + roi_height, roi_x:roi_x + roi_width] = MatchStatus.NO_CANDIDATE
    skipped = np.arange(height) % row_step != 0
    skipped[:roi_y] = skipped[roi_y + roi_height:] = False
    status[skipped, roi_x:roi_x + roi_width] = MatchStatus.SKIPPED_ROW
    # The left-right check needs every candidate of the right pixels the region reaches.
    reach = config.disparity_range - 1 if config.lr_check_max_diff >= 0 else 0
    x_begin = max(radius, roi_x - reach)
    x_end = min(width - radius, roi_x + roi_width + reach)
    out_begin, out_end = max(radius, roi_x), min(width - radius, roi_x + roi_width)
    if out_begin < out_end:
        left_offset, _, left_scale, left_texture = work.left_terms
        _, right_mean, right_scale, _ = work.right_terms
        _correlate_bands(work.left_padded, work.right_reversed, left_scale, left_offset,
                         right_mean, right_scale, left_texture, radius, config.min_disparity,
                         config.disparity_range, x_begin, x_end, roi_y, roi_y + roi_height,
                         out_begin, out_end, np.float32(config.min_score),
                         np.float32(config.uniqueness_ratio), int(config.lr_check_max_diff),
                         bool(config.subpixel), bands, int(row_step), *work.band_arrays,
                         disparity, score, status)
    return DisparityMap(disparity, score, status, (roi_x, roi_y, roi_width, roi_height), config)


class _ScratchMemory:
    """The matcher's working memory for one image size and disparity range.

    Kept between calls (one per thread, for the last shape matched), as StereoBM keeps its
    buffers: a fresh page costs about 3 us to fault in on our VM, and the ~20 MB a 640x480 pair
    needs took a quarter of the matching time when allocated per call.
    """

    def __init__(self, height: int, width: int, radius: int, disparity_range: int,
                 bands: int) -> None:
        padded = (height + 2 * radius, width)
        self.left_padded = np.empty(padded, np.float32)
        self.right_reversed = np.empty(padded, np.float32)  # columns reversed
        # offset, mean, scale, texture_ok (see _prepare_image); the right one reversed
        self.left_terms = self._terms(height, width)
        self.right_terms = self._terms(height, width)
        self.prepare_bands = max(1, min(height, 2 * numba.get_num_threads()))
        self._outputs: list[np.ndarray] = []
        self.band_arrays = (np.empty((bands, width, disparity_range), np.float32),
                            np.empty((bands, width, disparity_range), np.int32),
                            np.empty((bands, disparity_range), np.float32),
                            np.empty((bands, width), np.int32),
                            np.empty((bands, width), np.int32))

    def outputs(self) -> list[np.ndarray]:
        """Return the (disparity, score, status) arrays for the next result.

        The previous result's arrays are reused when nothing but this scratch memory refers to them
        any more (the caller dropped that result, and no view of them is alive): a node or a
        benchmark matching pair after pair then never faults in fresh pages for its outputs.
        """
        # 2 = the list's reference and getrefcount's argument: nobody else holds the array
        held = [sys.getrefcount(self._outputs[index]) > 2 for index in range(len(self._outputs))]
        if not self._outputs or any(held):
            height, width = self.left_terms[0].shape
            self._outputs = [np.empty((height, width), np.float32),
                             np.empty((height, width), np.float32),
                             np.empty((height, width), np.uint8)]
        return list(self._outputs)

    @staticmethod
    def _terms(height: int, width: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return (np.empty((height, width), np.float32), np.empty((height, width), np.float32),
                np.empty((height, width), np.float32), np.empty((height, width), np.bool_))


_scratch_memories = threading.local()


def _scratch_memory(height: int, width: int, radius: int, disparity_range: int,
               bands: int) -> _ScratchMemory:
    """Return this thread's scratch memory for the shape, made anew when the shape changed."""
    key = (height, width, radius, disparity_range, bands, numba.get_num_threads())
    if getattr(_scratch_memories, 'key', None) != key:
        _scratch_memories.work = _ScratchMemory(height, width, radius, disparity_range, bands)
        _scratch_memories.key = key
    work: _ScratchMemory = _scratch_memories.work
    return work


def warm_up() -> float:
    """Compile (or load from numba's cache) the matching kernels; return the time taken [s]."""
    start = time.perf_counter()
    rng = np.random.default_rng(0)
    image = rng.integers(0, 256, size=(16, 24), dtype=np.uint8)
    match(image, image, MatcherConfig(window_size=3, disparity_range=4, uniqueness_ratio=0.1))
    return time.perf_counter() - start
