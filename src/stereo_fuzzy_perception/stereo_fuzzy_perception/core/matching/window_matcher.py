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

The speed comes from one C kernel (window_matcher_kernel.h and its C files, built by colcon as
the extension _window_matcher_kernel), reached by one call that takes the numpy arrays: it
prepares both images (float32 rows padded by reflection, window means and variances from running
sums), so each (pixel, disparity) cell needs only the cross term sum(f w), kept as running
column sums (updated with one new and one old row) and running window sums along the row: O(1)
per cell whatever the window size. The disparity loop is innermost and contiguous (the right
image is stored with its columns reversed for that), and bands of rows run on POSIX threads with
the GIL released. For 8-bit images the sums are of integers below 2^24 and therefore exact in
float32. Working memory is kept between calls (_ScratchMemory), and so are the output arrays
once the caller has dropped the previous result, so that a pair does not fault in fresh pages.

ROI ("correlation area", Fig. 2 of the chapter): only pixels inside `roi` are matched and only
its rows are prepared, which divides the work by the share of the image it covers (rows outside
it, widened by the window's radius, are never read: they may hold anything). Preprocessing (Fig.
8): `edges` correlates Sobel gradient magnitudes, `binary` correlates Otsu-thresholded images.

ROS-free: numpy, OpenCV and the C kernel only.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from typing import NamedTuple

import numpy as np

from stereo_fuzzy_perception.core.matching.matcher_config import (
    MAX_DISPARITY_RANGE,
    MAX_WINDOW_SIZE,
    METHODS,
    PREPROCESS_MODES,
    DisparityMap,
    MatcherConfig,
    MatcherConfigError,
    MatcherInputError,
    MatchStatus,
)
from stereo_fuzzy_perception.core.matching.preprocessing import preprocess_image

try:
    from stereo_fuzzy_perception.core.matching import _window_matcher_kernel as _kernel
except ImportError as error:  # pragma: no cover - a checkout that was never built
    raise ImportError(
        'stereo_fuzzy_perception.core.matching._window_matcher_kernel (the matcher kernel, '
        'window_matcher_kernel.h and its C files) is not built: run scripts/setup.sh, or colcon '
        'build in ros2_ws') from error

# The settings, errors and results are defined in matcher_config.py and the preprocessing in
# preprocessing.py; they are part of this module's interface, which most callers import.
__all__ = ['MAX_DISPARITY_RANGE', 'MAX_WINDOW_SIZE', 'METHODS', 'PREPROCESS_MODES',
           'DisparityMap', 'MatchStatus', 'MatcherConfig', 'MatcherConfigError',
           'MatcherInputError', 'PixelsRead', 'default_threads', 'effective_roi', 'match',
           'pixels_read', 'preprocess_image', 'warm_up']

# Windows whose standard deviation is below this [grey levels] are flat whatever the threshold
# (the kernel's constant).
_FLAT_STD: float = _kernel.FLAT_STD
# Image dtypes the kernel reads as they are; any other integer or float dtype is converted to
# float32 first (which rounds as the kernel's own conversion would).
_KERNEL_DTYPES = (np.dtype(np.uint8), np.dtype(np.uint16), np.dtype(np.float32))


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


class PixelsRead(NamedTuple):
    """The rows and columns of each image a match reads, each as (start, stop) [px]."""

    rows: tuple[int, int]
    left_columns: tuple[int, int]
    right_columns: tuple[int, int]


def pixels_read(config: MatcherConfig, width: int, height: int) -> PixelsRead:
    """Return the pixels of a `width` x `height` pair that `match` reads with `config`.

    The rows are the region's, widened by the window's radius. The columns are those of the
    windows the kernel correlates: the region's, widened by the left-right check's reach (the
    right pixels the region's candidates meet are decided over every left pixel that meets
    them) and by the radius; in the right image, shifted by the searched disparities. What an
    8-bit pair holds outside them does not change the result: the kernel's sums over its
    pixels are sums of integers, exact whatever they add and take away. Preprocessing (Sobel,
    Otsu) and other pixel types read whole rows.

    Raises:
        MatcherInputError: When the configured region lies outside the image.
    """
    x, y, roi_width, roi_height = effective_roi(config, width, height)
    radius = config.window_size // 2
    rows = (max(0, y - radius), min(height, y + roi_height + radius))
    reach = config.disparity_range - 1 if config.lr_check_max_diff >= 0 else 0
    x_begin, x_end = max(radius, x - reach), min(width - radius, x + roi_width + reach)
    if config.preprocess != 'none' or x_begin >= x_end:
        return PixelsRead(rows, (0, width), (0, width))
    left = (max(0, x_begin - radius), min(width, x_end + radius))
    right_start = min(width, max(0, x_begin - radius - config.max_disparity))
    right = (right_start, max(right_start, min(width, x_end + radius - config.min_disparity)))
    return PixelsRead(rows, left, right)


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
    work = _scratch_memory(height, width, config.window_size // 2, threads)
    disparity, score, status = work.outputs()
    _kernel.correlate(
        left, right, disparity, score, status, work.workspace_for(config.disparity_range),
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
    The workspace grows to the widest disparity range asked for and is kept for narrower
    ones, so that a search range narrowed pair by pair (the tracked correlation area) does not
    allocate.
    """

    def __init__(self, height: int, width: int, radius: int, threads: int) -> None:
        self.shape = (height, width)
        self._sizes = {'height': height, 'width': width, 'radius': radius, 'threads': threads}
        self.workspace = np.empty(0, np.uint8)
        self._outputs: list[np.ndarray] = []

    def workspace_for(self, disparity_range: int) -> np.ndarray:
        """Return a workspace long enough for `disparity_range` [px], grown when it is not."""
        needed = _kernel.workspace_bytes(disparity_range=disparity_range, **self._sizes)
        if len(self.workspace) < needed:
            self.workspace = np.empty(needed, np.uint8)
        return self.workspace

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


def _scratch_memory(height: int, width: int, radius: int, threads: int) -> _ScratchMemory:
    """Return this thread's scratch memory for the shape, made anew when the shape changed."""
    key = (height, width, radius, threads)
    if getattr(_scratch_memories, 'key', None) != key:
        _scratch_memories.work = _ScratchMemory(height, width, radius, threads)
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
