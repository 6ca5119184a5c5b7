"""Image encodings the chain accepts, and their conversion to one grey channel (and, for
colour encodings, to RGB).

ROS-free: arrays in, arrays out. Names follow sensor_msgs/image_encodings.
"""

from __future__ import annotations

import cv2
import numpy as np

# encoding -> (numpy dtype, channels)
SUPPORTED_ENCODINGS: dict[str, tuple[np.dtype, int]] = {
    'mono8': (np.dtype(np.uint8), 1),
    '8UC1': (np.dtype(np.uint8), 1),
    'mono16': (np.dtype(np.uint16), 1),
    '16UC1': (np.dtype(np.uint16), 1),
    'rgb8': (np.dtype(np.uint8), 3),
    'bgr8': (np.dtype(np.uint8), 3),
    '8UC3': (np.dtype(np.uint8), 3),
    'rgba8': (np.dtype(np.uint8), 4),
    'bgra8': (np.dtype(np.uint8), 4),
}


class ImageEncodingError(ValueError):
    """An image whose encoding or layout the chain cannot use."""


def check_encoding(encoding: str) -> None:
    """Raise ImageEncodingError naming `encoding` and the accepted ones if it is unsupported."""
    if encoding not in SUPPORTED_ENCODINGS:
        raise ImageEncodingError(
            f'unsupported image encoding {encoding!r}; accepted: '
            + ', '.join(SUPPORTED_ENCODINGS))


def to_gray(image: np.ndarray, encoding: str) -> np.ndarray:
    """Convert an image of `encoding` to one channel, keeping its dtype (uint8 or uint16).

    Args:
        image: HxW or HxWxC array as decoded from the message.
        encoding: Its sensor_msgs encoding.

    Returns:
        HxW array.

    Raises:
        ImageEncodingError: For an unsupported encoding.
    """
    check_encoding(encoding)
    if image.ndim == 2:
        return image
    if encoding in ('rgb8',):
        return cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    if encoding in ('rgba8',):
        return cv2.cvtColor(image, cv2.COLOR_RGBA2GRAY)
    if encoding in ('bgra8',):
        return cv2.cvtColor(image, cv2.COLOR_BGRA2GRAY)
    return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)


def to_rgb(image: np.ndarray, encoding: str) -> np.ndarray | None:
    """Return an image of a colour encoding as HxWx3 RGB (its dtype kept), or None for a grey
    one (the chain then has no colour to look at). 8UC3 is taken as bgr8, as OpenCV writes it.

    Raises:
        ImageEncodingError: For an unsupported encoding.
    """
    check_encoding(encoding)
    if image.ndim == 2 or SUPPORTED_ENCODINGS[encoding][1] == 1:
        return None
    if encoding == 'rgb8':
        return image
    if encoding == 'rgba8':
        return np.ascontiguousarray(image[..., :3])
    if encoding == 'bgra8':
        return cv2.cvtColor(image, cv2.COLOR_BGRA2RGB)
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
