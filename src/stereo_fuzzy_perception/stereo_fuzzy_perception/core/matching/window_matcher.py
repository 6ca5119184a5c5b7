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

The speed comes from one C kernel (window_matcher_kernel.c, built by colcon as the extension
_window_matcher_kernel), reached by one call that takes the numpy arrays: it prepares both
images (float32 rows padded by reflection, window means and variances from running sums), so
each (pixel, disparity) cell needs only the cross term sum(f w), kept as running column sums
(updated with one new and one old row) and running window sums along the row: O(1) per cell
whatever the window size. The disparity loop is innermost and contiguous (the right image is
stored with its columns reversed for that), and bands of rows run on POSIX threads with the GIL
released. For 8-bit images the sums are of integers below 2^24 and therefore exact in float32.
Working memory is kept between calls (_ScratchMemory), and so are the output arrays once the
caller has dropped the previous result, so that a pair does not fault in fresh pages.

ROI ("correlation area", Fig. 2 of the chapter): only pixels inside `roi` are matched, which
divides the work by the share of the image it covers. Preprocessing (Fig. 8): `edges` correlates
Sobel gradient magnitudes, `binary` correlates Otsu-thresholded images.

ROS-free: numpy, OpenCV and the C kernel only.
"""

from __future__ import annotations

import enum
import os
import sys
import threading
import time
from dataclasses import dataclass, field

import cv2
import numpy as np

try:
    from stereo_fuzzy_perception.core.matching import _window_matcher_kernel as _kernel
except ImportError as error:  # pragma: no cover - a checkout that was never built
    raise ImportError(
        'stereo_fuzzy_perception.core.matching._window_matcher_kernel (the matcher kernel, '
        'window_matcher_kernel.c) is not built: run scripts/setup.sh, or colcon build in '
        'ros2_ws') from error

METHODS = ('zncc', 'plain')
PREPROCESS_MODES = ('none', 'edges', 'binary')
MAX_WINDOW_SIZE = 31
MAX_DISPARITY_RANGE = 512
# Windows whose standard deviation is below this [grey levels] are flat whatever the threshold
# (the kernel's constant).
_FLAT_STD: float = _kernel.FLAT_STD
# Image dtypes the kernel reads as they are; any other integer or float dtype is converted to
# float32 first (which rounds as the kernel's own conversion would).
_KERNEL_DTYPES = (np.dtype(np.uint8), np.dtype(np.uint16), np.dtype(np.float32))


class MatcherConfigError(ValueError):
    """A matcher setting out of its allowed range, named in the message."""


class MatcherInputError(ValueError):
    """Images the matcher cannot use (shape, dtype, size or a region outside the image)."""


class MatchStatus(enum.IntEnum):
    """Why a pixel of the disparity map has, or has no, disparity.

    The kernel defines the codes (window_matcher_kernel.c, MATCH_STATUSES, exported as
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


# --- public API -------------------------------------------------------------------------------


def default_threads() -> int:
    """Return the threads a match uses by default: the CPUs this process may run on."""
    return max(1, min(len(os.sched_getaffinity(0)), _kernel.MAX_THREADS))


def match(left: np.ndarray, right: np.ndarray, config: MatcherConfig | None = None,
          band_count: int | None = None, row_step: int = 1,
          threads: int | None = None) -> DisparityMap:
    """Match a rectified grey pair by window correlation and return the disparity map.

    Args:
        left: (H, W) left rectified grey image (uint8 gives exact sums; uint16 and float are
            scaled to 0..255).
        right: (H, W) right rectified grey image, same size.
        config: Matcher settings; MatcherConfig() when None.
        band_count: Row bands matched in parallel; by default 4 per thread.
        row_step: Decide only the rows y with y % row_step == 0 (the rows a triangulation with
            that stride keeps); the others get status SKIPPED_ROW. The decided rows are
            exactly those of row_step 1.
        threads: Threads that match (the calling one included); default_threads() when None.

    Returns:
        The disparity map [px], scores and per-pixel status.

    Raises:
        MatcherInputError: For images that are not one grey channel, differ in size, are
            smaller than the window, or a region of interest outside the image.
    """
    config = config or MatcherConfig()
    if row_step < 1:
        raise ValueError(f'row_step {row_step} must be >= 1')
    threads = default_threads() if threads is None else threads
    if not 1 <= threads <= _kernel.MAX_THREADS:
        raise ValueError(f'threads {threads} must be in 1..{_kernel.MAX_THREADS}')
    _check_images(left, right, config)
    height, width = left.shape
    if height < config.window_size or width < config.window_size:
        raise MatcherInputError(
            f'image {width}x{height} is smaller than the {config.window_size}x'
            f'{config.window_size} correlation window')
    roi = effective_roi(config, width, height)
    if config.preprocess != 'none':
        left = preprocess_image(left, config.preprocess)
        right = preprocess_image(right, config.preprocess)
    left, right = (_kernel_image(image) for image in (left, right))
    work = _scratch_memory(height, width, config.window_size // 2, config.disparity_range,
                           threads)
    disparity, score, status = work.outputs()
    _kernel.correlate(
        left, right, disparity, score, status, work.workspace,
        zero_mean=config.method == 'zncc', radius=config.window_size // 2,
        min_disparity=int(config.min_disparity), disparity_range=int(config.disparity_range),
        texture_threshold=float(config.texture_threshold), min_score=float(config.min_score),
        uniqueness_ratio=float(config.uniqueness_ratio),
        lr_max_diff=int(config.lr_check_max_diff), subpixel=bool(config.subpixel), roi=roi,
        row_step=int(row_step), bands=max(1, band_count or 4 * threads), threads=threads)
    return DisparityMap(disparity, score, status, roi, config)


def _kernel_image(image: np.ndarray) -> np.ndarray:
    """Return the image as the kernel reads it: C-contiguous uint8, uint16 or float32."""
    if image.dtype.newbyteorder('=') in _KERNEL_DTYPES:
        converted: np.ndarray = np.ascontiguousarray(image, dtype=image.dtype.newbyteorder('='))
        return converted
    return np.ascontiguousarray(image, dtype=np.float32)


class _ScratchMemory:
    """The matcher's working memory for one image size, disparity range and thread count.

    Kept between calls (one per Python thread, for the last shape matched), as StereoBM keeps
    its buffers: faulting in the megabytes a pair needs on every call costs a noticeable share
    of the matching (the package README has the measurement).
    """

    def __init__(self, height: int, width: int, radius: int, disparity_range: int,
                 threads: int) -> None:
        self.shape = (height, width)
        self.workspace = np.empty(_kernel.workspace_bytes(
            height=height, width=width, radius=radius, disparity_range=disparity_range,
            threads=threads), np.uint8)
        self._outputs: list[np.ndarray] = []

    def outputs(self) -> list[np.ndarray]:
        """Return the (disparity, score, status) arrays for the next result.

        The previous result's arrays are reused when nothing but this scratch memory refers to them
        any more (the caller dropped that result, and no view of them is alive): a node or a
        benchmark matching pair after pair then never faults in fresh pages for its outputs.
        """
        # 2 = the list's reference and getrefcount's argument: nobody else holds the array
        held = [sys.getrefcount(self._outputs[index]) > 2 for index in range(len(self._outputs))]
        if not self._outputs or any(held):
            self._outputs = [np.empty(self.shape, np.float32), np.empty(self.shape, np.float32),
                             np.empty(self.shape, np.uint8)]
        return list(self._outputs)


_scratch_memories = threading.local()


def _scratch_memory(height: int, width: int, radius: int, disparity_range: int,
                    threads: int) -> _ScratchMemory:
    """Return this thread's scratch memory for the shape, made anew when the shape changed."""
    key = (height, width, radius, disparity_range, threads)
    if getattr(_scratch_memories, 'key', None) != key:
        _scratch_memories.work = _ScratchMemory(height, width, radius, disparity_range, threads)
        _scratch_memories.key = key
    work: _ScratchMemory = _scratch_memories.work
    return work


def warm_up() -> float:
    """Run the matcher once on a small pair (loads the kernel); return the time taken [s]."""
    start = time.perf_counter()
    rng = np.random.default_rng(0)
    image = rng.integers(0, 256, size=(16, 24), dtype=np.uint8)
    match(image, image, MatcherConfig(window_size=3, disparity_range=4, uniqueness_ratio=0.1))
    return time.perf_counter() - start
