"""The simulated cameras' geometry: their calibration, pybullet view matrices, lens distortion.

Camera conventions (pybullet's OpenGL camera, mapped to the ROS pinhole model):

* fx = fy = (H / 2) / tan(vertical_fov / 2); principal point cx = W / 2, cy = H / 2 - 1.
* Camera poses come from rig_geometry.StereoRig (optical frames: x right, y down, z forward).
* The calibration is what a stereo calibration publishes: K, D, R, P of each camera from
  cv2.stereoRectify with the rig's R, T.
* Lens distortion is applied after rendering: the ideal image is resampled with cv2.remap so that
  cv2.undistort with the published D recovers it.

ROS-free: numpy and OpenCV only.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from stereo_fuzzy_perception.core.camera_model import CameraCalibration, StereoCalibration
from stereo_fuzzy_perception.core.rig_geometry import StereoRig
from stereo_fuzzy_perception.simulation.scene_model import SimulatedCamera

LEFT_FRAME_ID = 'left_camera_optical_frame'
RIGHT_FRAME_ID = 'right_camera_optical_frame'
# OpenGL cameras look along -z with y up; optical frames look along +z with y down.
_OPTICAL_TO_GL = np.diag([1.0, -1.0, -1.0])


def stereo_calibration(camera: SimulatedCamera, rig: StereoRig,
                       distortion: tuple[float, ...] = (0.0,) * 5,
                       rectify_alpha: float = -1.0) -> StereoCalibration:
    """Return the calibration a stereo calibration of this rig would publish.

    Args:
        camera: Image size and field of view of both cameras.
        rig: Relative pose of the cameras (R, T of right <- left).
        distortion: plumb_bob coefficients of both lenses.
        rectify_alpha: cv2.stereoRectify's free scaling: -1 (OpenCV's default) keeps the
            focal length of K, 0 keeps only valid pixels (zooms in), 1 keeps all pixels.

    Returns:
        Left and right CameraCalibration with K, D, R, P; right P[0, 3] = -fx' * baseline.
    """
    K = camera.intrinsics()
    D = np.array(distortion, dtype=float)
    rotation, translation = rig.right_from_left()
    size = (camera.width, camera.height)
    R1, R2, P1, P2, _, _, _ = cv2.stereoRectify(
        K, D, K, D, size, rotation, translation.reshape(3, 1),
        flags=cv2.CALIB_ZERO_DISPARITY, alpha=rectify_alpha)
    common: dict[str, Any] = {'width': camera.width, 'height': camera.height, 'K': K, 'D': D}
    return StereoCalibration(
        left=CameraCalibration(R=R1, P=P1, frame_id=LEFT_FRAME_ID, **common),
        right=CameraCalibration(R=R2, P=P2, frame_id=RIGHT_FRAME_ID, **common))


def view_matrix(world_from_camera: np.ndarray) -> list[float]:
    """Return pybullet's view matrix (column-major) of a camera at `world_from_camera`."""
    gl_pose = np.eye(4)
    gl_pose[:3, :3] = world_from_camera[:3, :3] @ _OPTICAL_TO_GL
    gl_pose[:3, 3] = world_from_camera[:3, 3]
    return np.linalg.inv(gl_pose).flatten(order='F').tolist()


def distortion_maps(camera: SimulatedCamera, distortion: tuple[float, ...]
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Return (map_x, map_y): for each distorted pixel, where it lies in the ideal image [px].

    cv2.remap(ideal, map_x, map_y) then gives the image a lens with `distortion` would see.
    """
    K = camera.intrinsics()
    u, v = np.meshgrid(np.arange(camera.width, dtype=np.float64),
                       np.arange(camera.height, dtype=np.float64))
    distorted = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-9)
    ideal = cv2.undistortPoints(distorted, K, np.array(distortion, dtype=float), R=np.eye(3),
                                P=K, criteria=criteria).reshape(camera.height, camera.width, 2)
    return ideal[..., 0].astype(np.float32), ideal[..., 1].astype(np.float32)
