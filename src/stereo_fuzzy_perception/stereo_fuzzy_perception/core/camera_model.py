"""Camera calibration as standard stereo calibration publishes it (K, D, R, P per camera).

ROS-free: plain numpy. `conversions.py` turns sensor_msgs/CameraInfo into these types.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


class CalibrationError(ValueError):
    """A camera calibration that cannot be used, with what is wrong in the message."""


@dataclass(frozen=True)
class CameraCalibration:
    """Intrinsics, distortion, rectification and projection of one camera.

    Attributes:
        width: Image width [px].
        height: Image height [px].
        K: 3x3 intrinsic matrix of the raw image [px].
        D: Distortion coefficients (plumb_bob: k1, k2, t1, t2, k3).
        R: 3x3 rectification rotation (rectified frame <- camera optical frame).
        P: 3x4 projection matrix of the rectified image [px]; P[0, 3] = -fx * baseline for the
            right camera of a stereo pair.
        distortion_model: `plumb_bob`, `rational_polynomial` or `equidistant`.
        frame_id: The camera's optical frame.
    """

    width: int
    height: int
    K: np.ndarray
    D: np.ndarray
    R: np.ndarray = field(default_factory=lambda: np.eye(3))
    P: np.ndarray = field(default_factory=lambda: np.zeros((3, 4)))
    distortion_model: str = 'plumb_bob'
    frame_id: str = ''

    def problem(self) -> str | None:
        """Return why this calibration is unusable, or None if it is usable."""
        if self.width <= 0 or self.height <= 0:
            return f'image size {self.width}x{self.height} is not positive'
        if np.asarray(self.K).shape != (3, 3) or not np.any(self.K):
            return 'K is all zero: the camera is not calibrated'
        if not np.all(np.isfinite(self.K)) or not np.all(np.isfinite(self.P)):
            return 'K or P holds NaN or infinity'
        if np.asarray(self.P).shape != (3, 4) or not np.any(self.P):
            return 'P is all zero: no rectified projection'
        if self.K[0, 0] <= 0 or self.K[1, 1] <= 0:
            return f'focal lengths fx={self.K[0, 0]}, fy={self.K[1, 1]} must be positive'
        return None

    def same_as(self, other: CameraCalibration) -> bool:
        """Return True when both calibrations would give the same rectification maps."""
        return (
            self.width == other.width and self.height == other.height
            and self.distortion_model == other.distortion_model
            and np.array_equal(self.K, other.K) and np.array_equal(self.D, other.D)
            and np.array_equal(self.R, other.R) and np.array_equal(self.P, other.P)
        )


@dataclass(frozen=True)
class StereoCalibration:
    """Calibration of a stereo pair: left and right cameras, rectified to a common plane."""

    left: CameraCalibration
    right: CameraCalibration

    @property
    def baseline_m(self) -> float:
        """Distance between the rectified optical centres [m], from the right P's Tx."""
        return float(-self.right.P[0, 3] / self.right.P[0, 0])

    def problem(self) -> str | None:
        """Return why this pair cannot be rectified and triangulated, or None."""
        for side, camera in (('left', self.left), ('right', self.right)):
            reason = camera.problem()
            if reason:
                return f'{side} camera_info: {reason}'
        if (self.left.width, self.left.height) != (self.right.width, self.right.height):
            return (f'left calibration is {self.left.width}x{self.left.height} but right is '
                    f'{self.right.width}x{self.right.height}')
        tx = float(self.right.P[0, 3])
        if tx >= 0.0:
            return (f'right projection Tx = P[0,3] = {tx} must be negative (-fx * baseline): '
                    'this is not the right camera of a calibrated stereo pair')
        return None

    def require_valid(self) -> None:
        """Raise CalibrationError with the reason when the pair is unusable."""
        reason = self.problem()
        if reason:
            raise CalibrationError(reason)
