"""Triangulation of rectified matches: the chapter's Eq. 1 for rectified cameras.

With rectified projections P_left = [[f, 0, cx_l, Tx_l], [0, f_y, c_y, 0], [0, 0, 1, 0]] and
P_right the same with cx_r and Tx_r = Tx_l - f B, a point (X, Y, Z) in the left rectified frame
projects to u_l - u_r = (cx_l - cx_r) + f B / Z, so

    Z = (Tx_l - Tx_r) / (d - (cx_l - cx_r)),   X = ((u_l - cx_l) Z - Tx_l) / f,
    Y = (v - c_y) Z / f_y,

which is Z = f B / d when both principal points agree (what the chapter's Eq. 1 turns into once
rectification has undone Eqs. 2-6). The point is then rotated back from the left rectified frame
to the left camera's optical frame with R_left^T, the frame StereoMatches carries.

ROS-free: numpy only.
"""

from __future__ import annotations

import numpy as np

from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.matched_points import MatchedPoints


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
    fx, fy = left_p[0, 0], left_p[1, 1]
    cx_left, cy = left_p[0, 2], left_p[1, 2]
    tx_left, ty_left = left_p[0, 3], left_p[1, 3]
    numerator = tx_left - right_p[0, 3]  # f B [px m]
    principal_shift = cx_left - right_p[0, 2]

    sampled = disparity[::stride, ::stride]
    rows, columns = np.nonzero(np.isfinite(sampled))
    d = sampled[rows, columns].astype(np.float64)
    rows, columns = rows * stride, columns * stride
    effective = d - principal_shift
    in_front = effective > 0.0
    rows, columns, d, effective = rows[in_front], columns[in_front], d[in_front], effective[
        in_front]
    u_left = columns.astype(np.float64)
    v = rows.astype(np.float64)
    z = numerator / effective
    x = ((u_left - cx_left) * z - tx_left) / fx
    y = ((v - cy) * z - ty_left) / fy
    rectified_xyz = np.stack([x, y, z], axis=1)
    # optical <- rectified is R^T; for row vectors p_opt^T = p_rect^T R.
    optical_xyz = rectified_xyz @ np.asarray(rectified.left.R, dtype=np.float64)
    return MatchedPoints(
        xyz=optical_xyz.astype(np.float32), u_left=u_left.astype(np.float32),
        v_left=v.astype(np.float32), u_right=(u_left - d).astype(np.float32),
        score=score[rows, columns].astype(np.float32))


def depth_from_disparity(disparity: np.ndarray | float, rectified: StereoCalibration
                         ) -> np.ndarray:
    """Return the depth Z [m] in the left rectified frame for disparities [px] (Eq. 1)."""
    left_p, right_p = np.asarray(rectified.left.P), np.asarray(rectified.right.P)
    effective = np.asarray(disparity, dtype=np.float64) - (left_p[0, 2] - right_p[0, 2])
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.where(effective > 0, (left_p[0, 3] - right_p[0, 3]) / effective, np.nan)
