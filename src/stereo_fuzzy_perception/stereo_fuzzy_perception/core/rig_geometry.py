"""The 3P robot's stereo rig: camera poses in `world` from the chapter's alpha, theta, z0.

The chapter (Eqs. 2-4) rotates the cameras by theta about z and alpha about x, R = R_alpha R_theta,
and places them at height z0 (C translates by -z0). Here that is generalised to a full rig pose:

* `world` is the gantry base frame: x and y along the gantry's axes, z up, the work surface at
  z = 0, SI units (REP 103).
* A camera with alpha = theta = 0 looks straight down: optical x = world x, optical y = -world y,
  optical z = -world z (REP 103 optical frame: z forward, x right, y down in the image).
* alpha tilts the rig about its optical x axis, so the cameras look toward +y (alpha = 45 deg:
  halfway between down and horizontal); theta then pans it about world z.
* (x0, y0, z0) is the midpoint between the two optical centres; the cameras sit at -+ baseline/2
  along the rig's x axis, each toed in about its own y axis by vergence/2.

ROS-free: numpy only. The scene simulator places its cameras with these functions and
fuzzy_best_point_node maps matched points to `world` with the same ones.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def rotation_x(angle: float) -> np.ndarray:
    """Return the rotation matrix about x by `angle` [rad]."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rotation_y(angle: float) -> np.ndarray:
    """Return the rotation matrix about y by `angle` [rad]."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rotation_z(angle: float) -> np.ndarray:
    """Return the rotation matrix about z by `angle` [rad]."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# world <- optical frame of a camera looking straight down (alpha = theta = 0)
LOOKING_DOWN = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])


def pose_matrix(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    """Return the 4x4 homogeneous transform [R | t]."""
    pose = np.eye(4)
    pose[:3, :3] = rotation
    pose[:3, 3] = translation
    return pose


@dataclass(frozen=True)
class StereoRig:
    """Pose and shape of the stereo rig in `world`.

    Attributes:
        baseline_m: Distance between the two optical centres [m].
        alpha_deg: Tilt about the rig's x axis [deg] (the chapter's alpha).
        theta_deg: Pan about world z [deg] (the chapter's theta).
        x0_m: x of the midpoint between the optical centres [m].
        y0_m: y of that midpoint [m].
        z0_m: Height of that midpoint above the work surface [m] (the chapter's z0).
        vergence_deg: Total toe-in between the optical axes [deg]; 0 for parallel cameras.
    """

    baseline_m: float = 0.06
    alpha_deg: float = 45.0
    theta_deg: float = 0.0
    x0_m: float = 0.20
    y0_m: float = -0.25
    z0_m: float = 0.40
    vergence_deg: float = 6.0

    def rig_rotation(self) -> np.ndarray:
        """Return world <- rig rotation (the optical frame of a camera with no vergence)."""
        rotation: np.ndarray = (rotation_z(math.radians(self.theta_deg)) @ LOOKING_DOWN
                                @ rotation_x(math.radians(self.alpha_deg)))
        return rotation

    def _camera_pose(self, side: float) -> np.ndarray:
        rig = self.rig_rotation()
        midpoint = np.array([self.x0_m, self.y0_m, self.z0_m])
        centre = midpoint + side * 0.5 * self.baseline_m * rig[:, 0]
        # Toe in: the left camera (side -1) turns its optical axis toward +x, the right toward -x.
        toe_in = rotation_y(-side * 0.5 * math.radians(self.vergence_deg))
        return pose_matrix(rig @ toe_in, centre)

    def world_from_left_camera(self) -> np.ndarray:
        """Return the 4x4 pose of the left camera's optical frame in `world`."""
        return self._camera_pose(-1.0)

    def world_from_right_camera(self) -> np.ndarray:
        """Return the 4x4 pose of the right camera's optical frame in `world`."""
        return self._camera_pose(+1.0)

    def right_from_left(self) -> tuple[np.ndarray, np.ndarray]:
        """Return (R, T): right optical frame <- left optical frame, as cv2.stereoRectify takes."""
        relative = np.linalg.inv(self.world_from_right_camera()) @ self.world_from_left_camera()
        return relative[:3, :3], relative[:3, 3]


def transform_points(pose: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a 4x4 transform to (N, 3) points and return (N, 3)."""
    transformed: np.ndarray = points @ pose[:3, :3].T + pose[:3, 3]
    return transformed
