"""Whether a part of the raw left image changed between two pairs, from their block means.

correlation_node tracks the object in the region of the newest decision (area_tracker.py). Two
of its choices depend on whether the scene changed, and a comparison of the pairs' block means
(BLOCK_PX x BLOCK_PX, about 0.1 ms for 640x480) answers that before anything is matched:

* a region whose blocks changed since the previous pair (an object taken away or put down, a
  hand) would most likely fail its check after it was matched (area_search.region_problem) and
  the pair be matched again on the whole image: the pair goes to the whole image at once;
* the periodic whole-image pair (roi.full_frame_every) looks for what changed elsewhere since
  the last whole image: when no block outside the region changed since then, it is matched in
  the region.

A block changed when its mean moved by more than `grey_levels` after the median move of the
blocks compared is taken off (an exposure or lighting change of the whole image is not a scene
change). Grey levels are those of an 8-bit image (16-bit images are scaled).

ROS-free: numpy and OpenCV only.
"""

from __future__ import annotations

import cv2
import numpy as np

BLOCK_PX = 8
"""Side of the square blocks whose means are compared [px]."""

Box = tuple[int, int, int, int]
"""(x0, y0, x1, y1) of an image, stop values exclusive [px]."""


def block_means(image: np.ndarray) -> np.ndarray:
    """Return the means of the image's BLOCK_PX x BLOCK_PX blocks in 8-bit grey levels.

    Args:
        image: Raw grey image (H, W), uint8 or uint16 (or float in 0..255).

    Returns:
        (H // BLOCK_PX, W // BLOCK_PX) float32 means; the last partial row and column of
        blocks is left out.
    """
    height, width = image.shape[:2]
    rows, columns = height // BLOCK_PX, width // BLOCK_PX
    if rows == 0 or columns == 0:
        return np.zeros((0, 0), np.float32)
    cropped = image[:rows * BLOCK_PX, :columns * BLOCK_PX]
    scale = 1.0 / 257.0 if cropped.dtype == np.uint16 else 1.0
    means = cv2.resize(cropped, (columns, rows), interpolation=cv2.INTER_AREA)
    return np.asarray(means, np.float32) * np.float32(scale)


def block_box(box: Box, shape: tuple[int, int]) -> Box:
    """Return the blocks (x0, y0, x1, y1) that hold any pixel of the pixel `box`.

    Args:
        box: (x0, y0, x1, y1) [px].
        shape: (rows, columns) of the block means.
    """
    x0, y0, x1, y1 = box
    rows, columns = shape
    return (min(max(0, x0 // BLOCK_PX), columns), min(max(0, y0 // BLOCK_PX), rows),
            min(max(0, -(-x1 // BLOCK_PX)), columns), min(max(0, -(-y1 // BLOCK_PX)), rows))


def changed_blocks(now: np.ndarray, before: np.ndarray, grey_levels: float) -> np.ndarray:
    """Return which blocks changed by more than `grey_levels` between two block means.

    The median change is taken off first (a lighting or exposure change of the whole image).

    Args:
        now: Block means of this pair (block_means).
        before: Block means of the earlier pair, the same shape.
        grey_levels: Largest change of a block's mean that is not a change [grey levels].

    Returns:
        Boolean mask of the blocks' shape.

    Raises:
        ValueError: When the shapes differ.
    """
    if now.shape != before.shape:
        raise ValueError(f'block means of shape {now.shape} and {before.shape} differ')
    difference = now - before
    if difference.size:
        difference -= np.float32(np.median(difference))
    changed: np.ndarray = np.abs(difference) > grey_levels
    return changed


def changed_share_inside(now: np.ndarray, before: np.ndarray | None, box: Box,
                         grey_levels: float) -> float:
    """Return the share of the blocks holding `box` [px] that changed.

    0 when that is unknown (no earlier means, means of another image size, a box outside the
    image): the region is then tried, and its check decides. The median change is that of the
    whole image's blocks.
    """
    if before is None or before.shape != now.shape:
        return 0.0
    bx0, by0, bx1, by1 = block_box(box, now.shape)
    if bx1 <= bx0 or by1 <= by0:
        return 0.0
    inside = changed_blocks(now, before, grey_levels)[by0:by1, bx0:bx1]
    return float(np.count_nonzero(inside)) / inside.size


def changed_outside(now: np.ndarray, before: np.ndarray | None, box: Box,
                    grey_levels: float) -> int:
    """Return how many blocks outside those holding `box` [px] changed (all when unknown)."""
    if before is None or before.shape != now.shape:
        return int(now.size)
    changed = changed_blocks(now, before, grey_levels)
    bx0, by0, bx1, by1 = block_box(box, now.shape)
    changed[by0:by1, bx0:bx1] = False
    return int(np.count_nonzero(changed))
