"""Two OpenCV captures read as one stereo pair of frames; ROS-free, used by stereo_camera_node."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np


class CaptureOpenError(ValueError):
    """A capture that cannot be opened, named with its parameter and what is allowed."""


class DeviceCapture:
    """Two OpenCV captures read as a pair: grab both first, then decode, to keep them close.

    Args:
        left_source: Device index ('0'), device path, video file or image pattern.
        right_source: Likewise for the right camera.

    Raises:
        CaptureOpenError: When a capture cannot be opened, naming it.
    """

    def __init__(self, left_source: str, right_source: str) -> None:
        self.left_source, self.right_source = left_source, right_source
        # Cameras and streams have no end; files and image patterns do.
        self.is_live = (left_source.isdigit() or left_source.startswith('/dev/')
                        or '://' in left_source)
        self._captures = self._open_both()

    def _open_both(self) -> list[Any]:
        captures: list[Any] = []
        for name, source in (('left_device', self.left_source),
                             ('right_device', self.right_source)):
            capture = cv2.VideoCapture(int(source) if source.isdigit() else source)
            if not capture.isOpened():
                for opened in captures:
                    opened.release()
                raise CaptureOpenError(
                    f'{name}={source!r}: cannot open the capture (allowed: a device index, a '
                    'device path, a video file, or an image pattern such as left_%03d.png)')
            captures.append(capture)
        return captures

    def read(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Return the next (left, right) frames, or None when either capture has none."""
        if not all(capture.grab() for capture in self._captures):
            return None
        frames = [capture.retrieve() for capture in self._captures]
        if not all(ok and frame is not None for ok, frame in frames):
            return None
        return frames[0][1], frames[1][1]

    def rewind(self) -> None:
        """Reopen both files at their first frame."""
        self.release()
        self._captures = self._open_both()

    def release(self) -> None:
        """Release both captures."""
        for capture in self._captures:
            capture.release()


def convert_frame(frame: np.ndarray, encoding: str) -> np.ndarray:
    """Convert an OpenCV frame (BGR, or grey from some backends) to `encoding`.

    Args:
        frame: HxWx3 BGR or HxW grey frame as a capture returns it.
        encoding: 'bgr8', 'rgb8' or 'mono8'.

    Returns:
        The frame in `encoding`.
    """
    if frame.ndim == 2:
        frame = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
    if encoding == 'mono8':
        return np.asarray(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY))
    if encoding == 'rgb8':
        return np.asarray(cv2.cvtColor(frame, cv2.COLOR_BGR2RGB))
    return frame
