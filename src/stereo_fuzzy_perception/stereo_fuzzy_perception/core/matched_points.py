"""Matched stereo points: the output of correlation, the input of the fuzzy stage. ROS-free."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class MatchedPoints:
    """Valid matches of one stereo pair, one row per point.

    Attributes:
        xyz: (N, 3) positions [m] in the left camera's optical frame.
        u_left: (N,) column in the left rectified image [px].
        v_left: (N,) row in both rectified images [px].
        u_right: (N,) column in the right rectified image [px].
        score: (N,) correlation score at the match (Eq. 8 coefficient, -1..1).
    """

    xyz: np.ndarray
    u_left: np.ndarray
    v_left: np.ndarray
    u_right: np.ndarray
    score: np.ndarray

    def __len__(self) -> int:
        return int(self.xyz.shape[0])

    @classmethod
    def empty(cls) -> MatchedPoints:
        """Return a set with no points."""
        zero = np.zeros(0, dtype=np.float32)
        return cls(np.zeros((0, 3), dtype=np.float32), zero, zero.copy(), zero.copy(),
                   zero.copy())

    def subset(self, mask: np.ndarray) -> MatchedPoints:
        """Return the points selected by a boolean mask or index array."""
        return MatchedPoints(self.xyz[mask], self.u_left[mask], self.v_left[mask],
                             self.u_right[mask], self.score[mask])
