"""The stereo pairs a camera bag holds, decoded: what offline replays of a bag match.

A bag recorded from the cameras (or written by render_scenes) has /left and /right image_raw
and camera_info; the four messages of one pair share a stamp. Needs rclpy (to deserialize).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from stereo_fuzzy_perception.bag.bag_reader import read_messages
from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.image_encoding import to_gray

CAMERA_TOPICS = ('/left/image_raw', '/right/image_raw', '/left/camera_info',
                 '/right/camera_info')


@dataclass(frozen=True)
class RecordedPair:
    """One stereo pair of a bag.

    Attributes:
        stamp_ns: The pair's header stamp [ns].
        left: Left grey image (H, W).
        right: Right grey image (H, W).
        calibration: The pair's calibration, from its camera_info messages.
    """

    stamp_ns: int
    left: np.ndarray
    right: np.ndarray
    calibration: StereoCalibration


def read_stereo_pairs(bag: Path | str) -> list[RecordedPair]:
    """Return the bag's complete pairs (all four camera messages at one stamp), in stamp order."""
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import CameraInfo, Image

    from stereo_fuzzy_perception.nodes.conversions import (
        camera_info_to_calibration,
        image_to_array,
        stamp_to_ns,
    )

    types: dict[str, Any] = {'/left/image_raw': Image, '/right/image_raw': Image,
                             '/left/camera_info': CameraInfo, '/right/camera_info': CameraInfo}
    by_stamp: dict[int, dict[str, Any]] = {}
    for message in read_messages(bag, CAMERA_TOPICS):
        decoded = deserialize_message(message.data, types[message.topic])
        by_stamp.setdefault(stamp_to_ns(decoded.header.stamp), {})[message.topic] = decoded
    pairs = []
    for stamp in sorted(by_stamp):
        scene = by_stamp[stamp]
        if len(scene) < len(CAMERA_TOPICS):
            continue
        left, right = scene['/left/image_raw'], scene['/right/image_raw']
        pairs.append(RecordedPair(
            stamp, to_gray(image_to_array(left), left.encoding),
            to_gray(image_to_array(right), right.encoding),
            StereoCalibration(camera_info_to_calibration(scene['/left/camera_info']),
                              camera_info_to_calibration(scene['/right/camera_info']))))
    return pairs
