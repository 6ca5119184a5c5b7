"""The left camera's pose in `world` from a checkerboard lying on the work surface (PnP).

The board lies flat on the surface at a known place: its printed corner (the outer corner of
its dark corner square) at (origin_x, origin_y, surface_z) in `world`, its x axis (along the
`columns` inner corners) turned by `yaw` from world x, its y axis along the rows, z up. Inner
corner (i, j) is then at origin + Rz(yaw) ((i + 1) s, (j + 1) s, 0) for square size s.

The calibrated camera sees it; OpenCV finds the inner corners (refined to sub-pixel), and
solvePnP with the camera's own K and D (the raw image, not the rectified one) gives camera <-
world, so its inverse is the pose of the camera's optical frame in `world`, the transform the
pose file holds.

A checkerboard's corner grid looks the same turned by 180 degrees, and OpenCV may list the
corners from either end. So the board must have an even number of squares one way and an odd
number the other (inner corners: one count odd, one even): turned by 180 degrees its colours
swap, and the colour of the square at the first corner tells the two orders apart. Mirrored
orders are told apart by the camera ending up below the surface.

ROS-free: numpy and OpenCV only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from stereo_fuzzy_perception.core.camera_model import CameraCalibration
from stereo_fuzzy_perception.core.rig_geometry import rotation_z

MAX_REFINE_HALF_WINDOW_PX = 9


class BoardPoseError(ValueError):
    """A board or an image from which no camera pose can be had; the message says why."""


@dataclass(frozen=True)
class CheckerBoard:
    """A checkerboard lying on the work surface at a known place.

    Attributes:
        columns: Inner corners along the board's x axis.
        rows: Inner corners along the board's y axis.
        square_m: Side of one square [m].
        origin_x_m: World x of the board's printed corner at its dark corner square [m].
        origin_y_m: World y of that corner [m].
        yaw_deg: Angle of the board's x axis from world x, about world z [deg].
        surface_z_m: World z of the board's top face (the surface plus its thickness) [m].
    """

    columns: int = 9
    rows: int = 6
    square_m: float = 0.025
    origin_x_m: float = 0.0
    origin_y_m: float = 0.0
    yaw_deg: float = 0.0
    surface_z_m: float = 0.0

    def problem(self) -> str | None:
        """Return why this board cannot give an unambiguous pose, or None."""
        if self.columns < 3 or self.rows < 3:
            return f'board of {self.columns}x{self.rows} inner corners: need at least 3x3'
        if (self.columns + self.rows) % 2 == 0:
            return (f'board of {self.columns}x{self.rows} inner corners looks the same turned '
                    'by 180 degrees; use one odd and one even count (e.g. 9x6)')
        if not self.square_m > 0.0:
            return f'square size {self.square_m} m must be positive'
        return None

    @property
    def size_m(self) -> tuple[float, float]:
        """Return the printed board's (width, height) [m]: (columns + 1, rows + 1) squares."""
        return (self.columns + 1) * self.square_m, (self.rows + 1) * self.square_m

    def world_from_board(self) -> np.ndarray:
        """Return the 4x4 pose of the board frame (printed dark corner, z up) in `world`."""
        pose = np.eye(4)
        pose[:3, :3] = rotation_z(math.radians(self.yaw_deg))
        pose[:3, 3] = (self.origin_x_m, self.origin_y_m, self.surface_z_m)
        return pose

    def corners_board(self) -> np.ndarray:
        """Return the (columns * rows, 3) inner corners in the board frame, row by row [m]."""
        i, j = np.meshgrid(np.arange(self.columns), np.arange(self.rows))
        return np.stack([(i.ravel() + 1) * self.square_m, (j.ravel() + 1) * self.square_m,
                         np.zeros(i.size)], axis=1)

    def corners_world(self) -> np.ndarray:
        """Return the inner corners in `world`, in the order corners_board lists them [m]."""
        pose = self.world_from_board()
        corners: np.ndarray = self.corners_board() @ pose[:3, :3].T + pose[:3, 3]
        return corners

    def texture(self, pixels_per_square: int = 64, margin_squares: int = 1) -> np.ndarray:
        """Return the printed board as an RGB image, its dark corner square at the top left.

        Image rows run along the board's y axis, columns along its x axis; a white margin of
        `margin_squares` surrounds the squares.
        """
        squares_x, squares_y = self.columns + 1, self.rows + 1
        i, j = np.meshgrid(np.arange(squares_x), np.arange(squares_y))
        board = np.where((i + j) % 2 == 0, 0, 255).astype(np.uint8)
        board = np.kron(board, np.ones((pixels_per_square, pixels_per_square), dtype=np.uint8))
        pad = margin_squares * pixels_per_square
        board = np.pad(board, pad, constant_values=255)
        return np.repeat(board[:, :, None], 3, axis=2)


@dataclass(frozen=True)
class BoardPose:
    """What one view of the board gives.

    Attributes:
        world_from_camera: 4x4 pose of the camera's optical frame in `world`.
        reprojection_rms_px: RMS distance between found and reprojected corners [px].
        reprojection_max_px: Largest such distance [px].
        corners_px: (N, 2) found corners in the board's order [px].
    """

    world_from_camera: np.ndarray
    reprojection_rms_px: float
    reprojection_max_px: float
    corners_px: np.ndarray


def find_board_corners(image: np.ndarray, board: CheckerBoard) -> np.ndarray:
    """Return the board's inner corners in `image` to sub-pixel, in OpenCV's order [px].

    Raises:
        BoardPoseError: When the board is not found.
    """
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    gray = np.ascontiguousarray(gray, dtype=np.uint8)
    pattern = (board.columns, board.rows)
    found, corners = cv2.findChessboardCorners(
        gray, pattern, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not found:
        found, corners = cv2.findChessboardCornersSB(gray, pattern)
        if not found:
            raise BoardPoseError(
                f'no {board.columns}x{board.rows} checkerboard (inner corners) in the '
                f'{gray.shape[1]}x{gray.shape[0]} image')
        return np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    # The widest refinement window that stays inside the squares around each corner: more edge
    # pixels average out noise and the staircase of sharp edges.
    grid = corners.reshape(board.rows, board.columns, 2)
    spacing = min(float(np.linalg.norm(np.diff(grid, axis=0), axis=2).min()),
                  float(np.linalg.norm(np.diff(grid, axis=1), axis=2).min()))
    half_window = int(max(2, min(MAX_REFINE_HALF_WINDOW_PX, 0.35 * spacing)))
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-4)
    refined = cv2.cornerSubPix(gray, corners.astype(np.float32), (half_window, half_window),
                               (-1, -1), criteria)
    return np.asarray(refined, dtype=np.float64).reshape(-1, 2)


def _orders(board: CheckerBoard) -> list[np.ndarray]:
    """Return the four index orders the detector may list corners in (mapped to ours)."""
    grid = np.arange(board.columns * board.rows).reshape(board.rows, board.columns)
    return [grid.ravel(), grid[::-1, ::-1].ravel(), grid[::-1, :].ravel(), grid[:, ::-1].ravel()]


def _dark_first_square(gray: np.ndarray, corners_px: np.ndarray, board: CheckerBoard) -> bool:
    """Return True when the square inside the first four corners is the darker colour."""
    grid = corners_px.reshape(board.rows, board.columns, 2)

    def level(row: int, column: int) -> float:
        centre = grid[row:row + 2, column:column + 2].reshape(-1, 2).mean(axis=0)
        x, y = (int(round(value)) for value in centre)
        height, width = gray.shape
        patch = gray[max(y - 1, 0):min(y + 2, height), max(x - 1, 0):min(x + 2, width)]
        return float(patch.mean()) if patch.size else math.nan

    # Square (1, 1) of the print has the corner square's colour; (1, 2) has the other one.
    return level(0, 0) < level(0, 1)


def board_pose(image: np.ndarray, calibration: CameraCalibration,
               board: CheckerBoard) -> BoardPose:
    """Return the pose of the camera that took `image` of `board`.

    Args:
        image: The camera's raw (distorted, unrectified) image, grey or RGB.
        calibration: The camera's calibration; K and D are used.
        board: The board and where it lies in `world`.

    Returns:
        The camera's optical frame in `world` and the reprojection error.

    Raises:
        BoardPoseError: When the board is ambiguous, not found, or no pose explains it.
    """
    problem = board.problem() or calibration.problem()
    if problem:
        raise BoardPoseError(problem)
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    found = find_board_corners(gray, board)
    K = np.asarray(calibration.K, dtype=np.float64)
    D = np.asarray(calibration.D, dtype=np.float64)
    world = board.corners_world()
    best: BoardPose | None = None
    for order in _orders(board):
        corners_px = np.empty_like(found)
        corners_px[order] = found
        if not _dark_first_square(gray, corners_px, board):
            continue
        candidate = _solve(world, corners_px, K, D)
        if candidate is None or candidate.world_from_camera[2, 3] <= board.surface_z_m:
            continue  # a mirrored order puts the camera under the surface
        if best is None or candidate.reprojection_rms_px < best.reprojection_rms_px:
            best = candidate
    if best is None:
        raise BoardPoseError('no camera pose above the surface explains the corners found; '
                             'is the board lying with its dark corner square at the origin?')
    return best


def _solve(world: np.ndarray, corners_px: np.ndarray, K: np.ndarray,
           D: np.ndarray) -> BoardPose | None:
    ok, rvec, tvec = cv2.solvePnP(world, corners_px, K, D, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        return None
    rvec, tvec = cv2.solvePnPRefineLM(world, corners_px, K, D, rvec, tvec)
    projected, _ = cv2.projectPoints(world, rvec, tvec, K, D)
    residuals = np.linalg.norm(projected.reshape(-1, 2) - corners_px, axis=1)
    camera_from_world = np.eye(4)
    camera_from_world[:3, :3] = cv2.Rodrigues(rvec)[0]
    camera_from_world[:3, 3] = tvec.ravel()
    return BoardPose(world_from_camera=np.linalg.inv(camera_from_world),
                     reprojection_rms_px=float(np.sqrt(np.mean(residuals ** 2))),
                     reprojection_max_px=float(residuals.max()), corners_px=corners_px)
