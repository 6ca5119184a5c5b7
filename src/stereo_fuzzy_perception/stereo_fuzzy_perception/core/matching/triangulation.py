"""Triangulation of rectified matches: the chapter's Eq. 1 for rectified cameras.

With rectified projections P_left = [[f, 0, cx_l, Tx_l], [0, f_y, c_y, 0], [0, 0, 1, 0]] and
P_right the same with cx_r and Tx_r = Tx_l - f B, a point (X, Y, Z) in the left rectified frame
projects to u_l - u_r = (cx_l - cx_r) + f B / Z, so

    Z = (Tx_l - Tx_r) / (d - (cx_l - cx_r)),   X = ((u_l - cx_l) Z - Tx_l) / f,
    Y = (v - c_y) Z / f_y,

which is Z = f B / d when both principal points agree (what the chapter's Eq. 1 turns into once
rectification has undone Eqs. 2-6). The point is then rotated back from the left rectified frame
to the left camera's optical frame with R_left^T, the frame StereoMatches carries.

The pass over the pixels is the matcher kernel's triangulate() (one loop over the disparity map,
valid pixels only), which writes each point as the row (x, y, z, u_left, v_left, u_right, score)
of one float32 block: the points' columns are views of that block, and a PointCloud2 with the
fields in that order is the block's bytes (conversions.matched_points_to_cloud copies them once).
The block is reused once nothing refers to the previous points any more.

ROS-free: numpy and the C kernel only.
"""

from __future__ import annotations

import sys
import threading

import numpy as np

from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.matched_points import MatchedPoints
from stereo_fuzzy_perception.core.matching import _window_matcher_kernel as _kernel

# The block's columns, in the order of conversions.MATCH_FIELDS.
POINT_COLUMNS = ('x', 'y', 'z', 'u_left', 'v_left', 'u_right', 'score')


def triangulate(disparity: np.ndarray, score: np.ndarray, rectified: StereoCalibration,
                stride: int = 1) -> MatchedPoints:
    """Turn a dense disparity map into 3D points in the left camera's optical frame.

    Args:
        disparity: (H, W) disparity [px] (left x minus right x), NaN where invalid.
        score: (H, W) score of each match, copied to the points.
        rectified: Rectified calibration (K = P[:3, :3], R = rectification rotation, P).
        stride: Keep every stride-th row and column (1 keeps every valid pixel).

    Returns:
        One point per valid pixel with a positive depth; xyz [m] in the left optical frame.
    """
    if stride < 1:
        raise ValueError(f'stride {stride} must be >= 1')
    left_p = np.asarray(rectified.left.P, dtype=np.float64)
    right_p = np.asarray(rectified.right.P, dtype=np.float64)
    height, width = disparity.shape
    capacity = ((height + stride - 1) // stride) * ((width + stride - 1) // stride)
    block = _point_block(capacity)
    count = _kernel.triangulate(
        np.ascontiguousarray(disparity, dtype=np.float32),
        np.ascontiguousarray(score, dtype=np.float32), block, stride=int(stride),
        fx=float(left_p[0, 0]), fy=float(left_p[1, 1]), cx=float(left_p[0, 2]),
        cy=float(left_p[1, 2]), tx=float(left_p[0, 3]), ty=float(left_p[1, 3]),
        numerator=float(left_p[0, 3] - right_p[0, 3]),  # f B [px m]
        principal_shift=float(left_p[0, 2] - right_p[0, 2]),
        rotation=tuple(float(value) for value in
                       np.asarray(rectified.left.R, dtype=np.float64).ravel()))
    rows = block[:count]
    return MatchedPoints(xyz=rows[:, 0:3], u_left=rows[:, 3], v_left=rows[:, 4],
                         u_right=rows[:, 5], score=rows[:, 6])


_blocks = threading.local()


def _point_block(capacity: int) -> np.ndarray:
    """Return a (capacity, 7) float32 block: this thread's last one when nothing refers to it."""
    previous: np.ndarray | None = getattr(_blocks, 'block', None)
    # 3 = the attribute, this name and getrefcount's argument: no points view it any more
    if previous is not None and previous.shape[0] >= capacity and sys.getrefcount(previous) <= 3:
        return previous
    block = np.empty((capacity, len(POINT_COLUMNS)), np.float32)
    _blocks.block = block
    return block


def depth_from_disparity(disparity: np.ndarray | float, rectified: StereoCalibration
                         ) -> np.ndarray:
    """Return the depth Z [m] in the left rectified frame for disparities [px] (Eq. 1)."""
    left_p, right_p = np.asarray(rectified.left.P), np.asarray(rectified.right.P)
    effective = np.asarray(disparity, dtype=np.float64) - (left_p[0, 2] - right_p[0, 2])
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.where(effective > 0, (left_p[0, 3] - right_p[0, 3]) / effective, np.nan)
