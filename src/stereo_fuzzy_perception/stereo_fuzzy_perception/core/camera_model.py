"""Camera calibration as standard stereo calibration publishes it (K, D, R, P per camera).

ROS-free: plain numpy. `nodes/conversions/images.py` turns sensor_msgs/CameraInfo into these
types.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

MAX_IMAGE_SIDE = 32767
"""Largest image side [px]: cv2.remap works on map coordinates as int16 (its fixed-point path)."""
ROTATION_TOLERANCE = 0.01
"""Largest |(R R^T - I)_ij| accepted for a rectification rotation (files round R)."""
DISTORTION_LENGTHS: dict[str, tuple[int, ...]] = {
    'plumb_bob': (0, 4, 5),
    'rational_polynomial': (0, 8),
    'equidistant': (4,),
}
"""Distortion models this package rectifies, with the D lengths each takes (0: no distortion)."""


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
        binning_x: CameraInfo binning_x (0 and 1: none; more is refused by problem()).
        binning_y: CameraInfo binning_y.
        roi: CameraInfo roi (x, y, width, height); all zero or the full image, else refused.
    """

    width: int
    height: int
    K: np.ndarray
    D: np.ndarray
    R: np.ndarray = field(default_factory=lambda: np.eye(3))
    P: np.ndarray = field(default_factory=lambda: np.zeros((3, 4)))
    distortion_model: str = 'plumb_bob'
    frame_id: str = ''
    binning_x: int = 0
    binning_y: int = 0
    roi: tuple[int, int, int, int] = (0, 0, 0, 0)

    def problem(self) -> str | None:
        """Return why this calibration is unusable, or None if it is usable.

        Checks, in order: the image size (positive, at most MAX_IMAGE_SIDE), the shapes of K,
        R and P, every number finite, the distortion model known and D of its length, K and P
        with positive focal lengths, the principal points inside the image and a last row
        (0, 0, 1), R a rotation, and binning / ROI unset (neither is applied downstream, so a
        binned or cropped calibration would give wrong points silently).
        """
        if self.width <= 0 or self.height <= 0:
            return f'image size {self.width}x{self.height} is not positive'
        if self.width > MAX_IMAGE_SIDE or self.height > MAX_IMAGE_SIDE:
            return (f'image size {self.width}x{self.height}: a side above {MAX_IMAGE_SIDE} px '
                    'cannot be rectified (OpenCV remap)')
        for name, matrix, shape in (('K', self.K, (3, 3)), ('R', self.R, (3, 3)),
                                    ('P', self.P, (3, 4))):
            if np.shape(matrix) != shape:
                return f'{name} has shape {np.shape(matrix)}, expected {shape}'
        K, R, P = (np.asarray(m, dtype=float) for m in (self.K, self.R, self.P))
        D = np.asarray(self.D, dtype=float)
        if not np.any(K):
            return 'K is all zero: the camera is not calibrated'
        if not np.any(P):
            return 'P is all zero: no rectified projection'
        for name, matrix in (('K', K), ('D', D), ('R', R), ('P', P)):
            if not np.all(np.isfinite(matrix)):
                return f'{name} holds NaN or infinity'
        lengths = DISTORTION_LENGTHS.get(self.distortion_model)
        if lengths is None:
            return (f'distortion model {self.distortion_model!r} is not one of '
                    f'{", ".join(DISTORTION_LENGTHS)}')
        if D.ndim != 1 or D.size not in lengths:
            return (f'D has {D.size} coefficients; {self.distortion_model} takes '
                    + ' or '.join(str(n) for n in lengths))
        if K[0, 0] <= 0 or K[1, 1] <= 0:
            return f'focal lengths fx={K[0, 0]}, fy={K[1, 1]} must be positive'
        if P[0, 0] <= 0 or P[1, 1] <= 0:
            return f'projection focal lengths P fx={P[0, 0]}, fy={P[1, 1]} must be positive'
        for name, cx, cy in (('K', K[0, 2], K[1, 2]), ('P', P[0, 2], P[1, 2])):
            if not (0.0 <= cx <= self.width and 0.0 <= cy <= self.height):
                return (f'{name} principal point ({cx:g}, {cy:g}) lies outside the '
                        f'{self.width}x{self.height} image')
        if not np.allclose(K[2], (0.0, 0.0, 1.0)) or not np.allclose(P[2, :3], (0.0, 0.0, 1.0)):
            return 'the last row of K and of P[:, :3] must be (0, 0, 1)'
        # Tolerance for files written with 3 decimals; huge entries overflow: not a rotation.
        with np.errstate(over='ignore', invalid='ignore'):
            rotation = bool(np.allclose(R @ R.T, np.eye(3), atol=ROTATION_TOLERANCE)
                            and np.linalg.det(R) > 0.0)
        if not rotation:
            return 'R is not a rotation (R R^T = I, det R = 1)'
        if self.binning_x > 1 or self.binning_y > 1:
            return (f'binning {self.binning_x}x{self.binning_y} is not supported: publish '
                    'unbinned images, or a calibration of the binned size with binning 0')
        if any(self.roi) and tuple(self.roi) != (0, 0, self.width, self.height):
            return (f'ROI {tuple(self.roi)} (x, y, width, height) is not supported: publish '
                    'full images, or a calibration of the cropped image with no ROI')
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
