"""Rectification of a raw stereo pair with its calibration (K, D, R, P of each camera).

How the chapter's geometry maps onto this module:

* Eqs. 2-6 describe the 3P robot's cameras as rotated by theta about z and alpha about x
  (R = R_alpha R_theta, Eq. 3) and offset by z0 (Eq. 4), which makes the image coordinates
  x1, x2 of a point non-linear functions of X, Y, Z (Eqs. 5, 6). A stereo calibration measures
  these rotations (and the lens distortion the chapter ignores); the rectification rotation R
  of each camera turns both onto a common image plane parallel to the baseline. Rectification
  is therefore what undoes Eqs. 2-6: after `cv2.remap` with maps from K, D, R, P, corresponding
  points lie on the same row and the cameras behave as the chapter's reference case
  (alpha = theta = 0, "these equations reduce to Eq. 1").
* Eq. 1 (Z = lambda - lambda B / (x2 + x1), with image coordinates measured from each camera's own
  axis and the lens distance lambda) becomes, for rectified pinhole cameras with focal length f
  [px] and disparity d = x_left - x_right [px], Z = f B / d (see triangulation.py, which also
  rotates the point back from the rectified frame to the camera's optical frame with R^T).

ROS-free: numpy and OpenCV only.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import cv2
import numpy as np

from stereo_fuzzy_perception.core.camera_model import (
    CalibrationError,
    CameraCalibration,
    StereoCalibration,
)


class RectificationError(ValueError):
    """Images that do not fit the calibration they come with."""


def rectified_camera(camera: CameraCalibration) -> CameraCalibration:
    """Return the calibration of `camera`'s rectified image.

    K = P[:3, :3], no distortion, R kept as the rectification rotation (rectified frame <-
    camera optical frame), P unchanged: what a rectified image's CameraInfo carries.
    """
    projection = np.asarray(camera.P, dtype=float)
    return CameraCalibration(
        width=camera.width, height=camera.height, K=projection[:3, :3].copy(),
        D=np.zeros(5), R=np.asarray(camera.R, dtype=float).copy(), P=projection.copy(),
        distortion_model='plumb_bob', frame_id=camera.frame_id)


def rectified_stereo(calibration: StereoCalibration) -> StereoCalibration:
    """Return the rectified calibration of both cameras (see rectified_camera)."""
    return StereoCalibration(rectified_camera(calibration.left),
                             rectified_camera(calibration.right))


def is_already_rectified(camera: CameraCalibration) -> bool:
    """Return True when remapping would not change the image (D = 0, R = I, K = P[:3, :3])."""
    return (not np.any(camera.D) and np.allclose(camera.R, np.eye(3))
            and np.allclose(camera.K, np.asarray(camera.P)[:3, :3]))


Block = tuple[int, int, int, int]
"""(first row, stop row, first column, stop column) of an image [px]."""


@dataclass(frozen=True)
class RectificationMaps:
    """cv2.remap maps of one camera (None when the image is already rectified).

    map_x and map_y are (H, W) float32: for each rectified pixel, where it lies in the raw image
    [px].
    """

    map_x: np.ndarray | None
    map_y: np.ndarray | None

    def apply(self, image: np.ndarray) -> np.ndarray:
        """Rectify `image` (bilinear; pixels from outside the raw image are 0)."""
        if self.map_x is None or self.map_y is None:
            return image
        return cv2.remap(image, self.map_x, self.map_y, cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=0)

    def apply_part(self, image: np.ndarray, block: Block, out: np.ndarray | None,
                   done: Block | None) -> tuple[np.ndarray, Block | None]:
        """Rectify `block` of `image` into `out` (made when None or of another shape).

        Args:
            image: The raw image.
            block: (first row, stop row, first column, stop column) to rectify [px].
            out: The rectified image to write into, or None.
            done: A block of `out` that already holds this image rectified, or None.

        Returns:
            `out` (or `image` itself when already rectified), a full-size image of which only
            `block` (and `done`) are this image's, and the block that now holds it.
        """
        if self.map_x is None or self.map_y is None:
            return image, None
        shape = self.map_x.shape[:2] + image.shape[2:]
        if out is None or out.shape != shape or out.dtype != image.dtype:
            out, done = np.zeros(shape, image.dtype), None
        for first, stop, start, end in missing_blocks(done, block):
            # remap reads the maps' and writes the output's views in place (row strides kept)
            cv2.remap(image, self.map_x[first:stop, start:end], self.map_y[first:stop, start:end],
                      cv2.INTER_LINEAR, dst=out[first:stop, start:end],
                      borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        return out, grown_block(done, block)


def missing_blocks(done: Block | None, wanted: Block) -> list[Block]:
    """Return the blocks of `wanted` outside `done`: all of it unless one holds the other."""
    first, stop, start, end = wanted
    if first >= stop or start >= end:
        return []
    if done is None:
        return [wanted]
    done_first, done_stop, done_start, done_end = done
    if (done_first <= first and stop <= done_stop and done_start <= start
            and end <= done_end):
        return []
    if not (first <= done_first and done_stop <= stop and start <= done_start
            and done_end <= end):
        return [wanted]
    parts = [(first, done_first, start, end), (done_stop, stop, start, end),
             (done_first, done_stop, start, done_start), (done_first, done_stop, done_end, end)]
    return [part for part in parts if part[0] < part[1] and part[2] < part[3]]


def grown_block(done: Block | None, wanted: Block) -> Block:
    """Return the block that holds the image once `missing_blocks(done, wanted)` are done."""
    if done is not None and not missing_blocks(done, wanted):
        return done
    return wanted


def rectification_maps(camera: CameraCalibration) -> RectificationMaps:
    """Compute the remap maps of one camera from K, D, R, P.

    Float maps, not OpenCV's fixed-point ones: with float maps cv2.remap hands the bilinear
    interpolation to Intel IPP (OpenCV's wheels ship it), which is faster here
    (benchmarks/correlation_benchmark.py, the stage's rectify part), and interpolates at the
    map's exact coordinates instead of 1/32 px.

    Raises:
        CalibrationError: When the calibration is unusable.
    """
    reason = camera.problem()
    if reason:
        raise CalibrationError(reason)
    if is_already_rectified(camera):
        return RectificationMaps(None, None)
    size = (int(camera.width), int(camera.height))
    K = np.asarray(camera.K, dtype=np.float64)
    D = np.asarray(camera.D, dtype=np.float64)
    R = np.asarray(camera.R, dtype=np.float64)
    P = np.asarray(camera.P, dtype=np.float64)
    if camera.distortion_model == 'equidistant':
        map_x, map_y = cv2.fisheye.initUndistortRectifyMap(K, D[:4], R, P, size, cv2.CV_32FC1)
    else:
        map_x, map_y = cv2.initUndistortRectifyMap(K, D, R, P, size, cv2.CV_32FC1)
    return RectificationMaps(map_x, map_y)


class StereoRectifier:
    """Rectify pairs, keeping the maps until the calibration changes (thread-safe)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._calibration: StereoCalibration | None = None
        self._maps: tuple[RectificationMaps, RectificationMaps] | None = None
        self._rectified: StereoCalibration | None = None
        self.map_builds = 0
        self._row_buffers = threading.local()

    def _maps_for(self, calibration: StereoCalibration
                  ) -> tuple[tuple[RectificationMaps, RectificationMaps], StereoCalibration]:
        with self._lock:
            cached = self._calibration
            if (cached is None or self._maps is None or self._rectified is None
                    or not cached.left.same_as(calibration.left)
                    or not cached.right.same_as(calibration.right)):
                calibration.require_valid()
                self._maps = (rectification_maps(calibration.left),
                              rectification_maps(calibration.right))
                self._rectified = rectified_stereo(calibration)
                self._calibration = calibration
                self.map_builds += 1
            return self._maps, self._rectified

    def maps(self, calibration: StereoCalibration
             ) -> tuple[RectificationMaps, RectificationMaps]:
        """Return the left and right maps of the pair's calibration (built once per
        calibration): for images beside the grey ones that are matched (colour)."""
        return self._maps_for(calibration)[0]

    def raw_box(self, calibration: StereoCalibration, roi: tuple[int, int, int, int]
                ) -> tuple[int, int, int, int]:
        """Return the box (x0, y0, x1, y1) of the raw left image a rectified ROI is made from.

        Args:
            calibration: The pair's calibration.
            roi: (x, y, width, height) in the left rectified image [px].

        Returns:
            The smallest box holding every raw pixel the ROI's border pixels interpolate from
            (a rectification map is smooth: its extremes over a rectangle lie on the border),
            clipped to the image (stop values exclusive) [px].

        Raises:
            CalibrationError: When the calibration is unusable.
        """
        (left_maps, _), _ = self._maps_for(calibration)
        width, height = calibration.left.width, calibration.left.height
        x, y, roi_width, roi_height = roi
        x0, y0 = max(0, x), max(0, y)
        x1, y1 = min(width, x + roi_width), min(height, y + roi_height)
        if left_maps.map_x is None or left_maps.map_y is None or x1 <= x0 or y1 <= y0:
            return x0, y0, x1, y1
        low, high = [], []
        for axis_map in (left_maps.map_x, left_maps.map_y):
            block = axis_map[y0:y1, x0:x1]
            border = np.floor(np.concatenate([block[0], block[-1], block[:, 0], block[:, -1]]))
            low.append(border.min())
            high.append(border.max())
        return (max(0, int(low[0])), max(0, int(low[1])),
                min(width, int(high[0]) + 2), min(height, int(high[1]) + 2))

    @staticmethod
    def check_sizes(left: np.ndarray, right: np.ndarray,
                      calibration: StereoCalibration) -> None:
        """Check that each image has its calibration's size.

        Raises:
            RectificationError: When an image's size differs from its calibration.
        """
        for side, image, camera in (('left', left, calibration.left),
                                    ('right', right, calibration.right)):
            height, width = image.shape[:2]
            if (width, height) != (camera.width, camera.height):
                raise RectificationError(
                    f'{side} image is {width}x{height} but its calibration is '
                    f'{camera.width}x{camera.height}')

    def rectify(self, left: np.ndarray, right: np.ndarray, calibration: StereoCalibration
                ) -> tuple[np.ndarray, np.ndarray, StereoCalibration]:
        """Rectify a raw pair; return both rectified images and the rectified calibration.

        Args:
            left: Raw left image (H, W) or (H, W, C), any dtype cv2.remap takes.
            right: Raw right image, same layout.
            calibration: The pair's calibration.

        Returns:
            (left_rectified, right_rectified, rectified_calibration).

        Raises:
            CalibrationError: When the calibration is unusable.
            RectificationError: When an image's size differs from its calibration.
        """
        self.check_sizes(left, right, calibration)
        (left_maps, right_maps), rectified = self._maps_for(calibration)
        return left_maps.apply(left), right_maps.apply(right), rectified

    def rectify_part(self, left: np.ndarray, right: np.ndarray, calibration: StereoCalibration,
                     rows: tuple[int, int], columns: tuple[tuple[int, int], tuple[int, int]],
                     continued: bool = False
                     ) -> tuple[np.ndarray, np.ndarray, StereoCalibration]:
        """Rectify only some rows and columns of a raw pair (what a match reads, pixels_read).

        The rectified images are buffers this rectifier keeps for the next call (in the
        calling thread): pixels outside the block hold an earlier pair's, and the images are
        overwritten by the next call. Otherwise as `rectify`.

        Args:
            left: Raw left image.
            right: Raw right image.
            calibration: The pair's calibration.
            rows: (start, stop) of the rows to rectify in both images [px].
            columns: (start, stop) of the columns to rectify in the left and the right image.
            continued: The previous call of this thread rectified part of the same pair (the
                same arrays, unchanged since): only what it did not is rectified now.
        """
        self.check_sizes(left, right, calibration)
        maps, rectified = self._maps_for(calibration)
        state = self._row_buffers
        previous = getattr(state, 'source', None)
        same = (continued and previous is not None and previous[0] is left
                and previous[1] is right and previous[2] is maps)
        images = getattr(state, 'images', (None, None))
        done = getattr(state, 'done', (None, None)) if same else (None, None)
        results = [side_maps.apply_part(image, (*rows, *side_columns), buffer, side_done)
                   for side_maps, image, side_columns, buffer, side_done
                   in zip(maps, (left, right), columns, images, done, strict=True)]
        state.images = (results[0][0], results[1][0])
        state.done = (results[0][1], results[1][1])
        # the raw arrays are held, so that no later pair's arrays can be taken for them
        state.source = (left, right, maps)
        return results[0][0], results[1][0], rectified
