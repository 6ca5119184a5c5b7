"""Stereo inputs for tests/hostile/: a small good pair, and calibrations spoiled one way each."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

WIDTH, HEIGHT = 96, 64
FOCAL, BASELINE = 120.0, 0.1  # [px], [m]
SHIFT = 6  # [px] disparity of the synthetic pair


def camera(width: int = WIDTH, height: int = HEIGHT, tx: float = 0.0) -> Any:
    """A usable rectified camera of `width` x `height`; tx = -fx * baseline for the right."""
    from stereo_fuzzy_perception.core.camera_model import CameraCalibration

    K = np.array([[FOCAL, 0.0, width / 2], [0.0, FOCAL, height / 2], [0.0, 0.0, 1.0]])
    P = np.hstack([K, [[tx], [0.0], [0.0]]])
    return CameraCalibration(width=width, height=height, K=K, D=np.zeros(5), P=P)


def right_camera(width: int = WIDTH, height: int = HEIGHT) -> Any:
    """The right camera of the pair (Tx = -fx * baseline)."""
    return camera(width, height, -FOCAL * BASELINE)


def spoiled_right_cameras() -> list[tuple[str, Any]]:
    """(what, right calibration) for every unusable calibration of issue #15 item 9."""
    good = right_camera()

    def with_entry(name: str, index: tuple[int, ...], value: float) -> Any:
        matrix = np.array(getattr(good, name), dtype=float)
        matrix[index] = value
        return replace(good, **{name: matrix})

    return [
        ('NaN in D', with_entry('D', (0,), math.nan)),
        ('NaN in R', with_entry('R', (1, 2), math.nan)),
        ('D of 6 for plumb_bob', replace(good, D=np.zeros(6))),
        ('unknown distortion model', replace(good, distortion_model='kannala_brandt9')),
        ('right P fx = 0', with_entry('P', (0, 0), 0.0)),
        ('principal point outside', with_entry('K', (0, 2), 10.0 * WIDTH)),
        ('binning 2', replace(good, binning_x=2, binning_y=2)),
        ('ROI set', replace(good, roi=(8, 8, 32, 32))),
    ]


def textured_pair(width: int = WIDTH, height: int = HEIGHT, shift: int = SHIFT
                  ) -> tuple[np.ndarray, np.ndarray]:
    """A rectified pair with a constant disparity: left x matches right x - shift."""
    import cv2

    rng = np.random.default_rng(0)
    scene = cv2.GaussianBlur(rng.uniform(0, 255, (height, width + shift)).astype(np.float32),
                             (0, 0), 1.2)
    scene = np.clip(128 + 3 * (scene - scene.mean()), 0, 255).astype(np.uint8)
    return scene[:, :width].copy(), scene[:, shift:shift + width].copy()


def header(stamp_sec: int, frame_id: str = 'left_camera_optical_frame') -> Any:
    """A std_msgs/Header at `stamp_sec`."""
    from std_msgs.msg import Header

    result = Header(frame_id=frame_id)
    result.stamp.sec = stamp_sec
    return result


def stereo_pair(stamp_sec: int, sequence: int = 0, right: Any = None,
                size: tuple[int, int] = (WIDTH, HEIGHT)) -> Any:
    """A StereoPair of the textured pair (size width x height) with the given right camera."""
    from stereo_fuzzy_perception.nodes.conversions import (
        array_to_image,
        calibration_to_camera_info,
    )

    from stereo_fuzzy_msgs.msg import StereoPair

    width, height = size
    left_image, right_image = textured_pair(width, height)
    head = header(stamp_sec)
    pair = StereoPair(header=head, sequence=sequence)
    pair.left_image = array_to_image(left_image, 'mono8', head)
    pair.right_image = array_to_image(right_image, 'mono8', head)
    pair.left_info = calibration_to_camera_info(camera(width, height), head)
    pair.right_info = calibration_to_camera_info(
        right if right is not None else right_camera(width, height), head)
    return pair


def camera_inputs(stamp_sec: int, right: Any = None,
                  size: tuple[int, int] = (WIDTH, HEIGHT)) -> dict[str, Any]:
    """The four inputs of stereo_sync_node (topic -> message) for one stereo pair."""
    pair = stereo_pair(stamp_sec, right=right, size=size)
    return {'left/image_raw': pair.left_image, 'left/camera_info': pair.left_info,
            'right/image_raw': pair.right_image, 'right/camera_info': pair.right_info}
