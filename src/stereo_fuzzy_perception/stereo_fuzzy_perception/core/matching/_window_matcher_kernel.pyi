"""Types of the matcher's C kernel (window_matcher_kernel.c, which parses these keywords)."""

from typing import Final

import numpy as np

STATUS_CODES: Final[dict[str, int]]
FLAT_STD: Final[float]
MAX_THREADS: Final[int]

def correlate(left: np.ndarray, right: np.ndarray, disparity: np.ndarray, score: np.ndarray,
              status: np.ndarray, workspace: np.ndarray, *, zero_mean: bool, radius: int,
              min_disparity: int, disparity_range: int, texture_threshold: float,
              min_score: float, uniqueness_ratio: float, lr_max_diff: int, subpixel: bool,
              roi: tuple[int, int, int, int], row_step: int, bands: int, threads: int) -> None:
    """Match a rectified pair into disparity, score and status (window_matcher.match)."""

def triangulate(disparity: np.ndarray, score: np.ndarray, points: np.ndarray, *, stride: int,
                fx: float, fy: float, cx: float, cy: float, tx: float, ty: float,
                numerator: float, principal_shift: float,
                rotation: tuple[float, ...]) -> int:
    """Triangulate valid disparities into (x, y, z, u_left, v_left, u_right, score) rows."""

def workspace_bytes(*, height: int, width: int, radius: int, disparity_range: int,
                    threads: int) -> int:
    """Bytes of the workspace correlate() needs."""
