"""The chapter's optional preprocessing before correlation (Fig. 8): edges or binary images.

ROS-free: numpy and OpenCV only.
"""

from __future__ import annotations

import cv2
import numpy as np

from stereo_fuzzy_perception.core.matching.matcher_config import (
    PREPROCESS_MODES,
    MatcherConfigError,
)


def preprocess_image(image: np.ndarray, mode: str) -> np.ndarray:
    """Apply the chapter's optional preprocessing (Fig. 8) to a grey image.

    Args:
        image: (H, W) grey image, uint8, uint16 or float.
        mode: `none` (returned as is), `edges` (Sobel gradient magnitude, uint8, scaled so
            that a full-range step reads 255) or `binary` (Otsu threshold, 0 or 255).

    Returns:
        The preprocessed (H, W) image.

    Raises:
        MatcherConfigError: For an unknown mode.
    """
    if mode == 'none':
        return image
    if mode not in PREPROCESS_MODES:
        raise MatcherConfigError(
            f'preprocess {mode!r} is not one of {", ".join(PREPROCESS_MODES)}')
    grey8 = _to_uint8(image)
    if mode == 'binary':
        binary: np.ndarray
        _, binary = cv2.threshold(grey8, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
        return binary
    gx = cv2.Sobel(grey8, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(grey8, cv2.CV_32F, 0, 1, ksize=3)
    # Integer gradients: the sum of squares is exact in float32 and numpy's sqrt is correctly
    # rounded. cv2.magnitude is not: its SIMD and scalar paths differ in the last bit, so an
    # image's edges changed by 1 grey level with the array's address (and so did matches).
    magnitude = np.sqrt(gx * gx + gy * gy) * np.float32(255.0 / (4.0 * 255.0))
    edges: np.ndarray = np.clip(np.rint(magnitude), 0, 255).astype(np.uint8)
    return edges


def _to_uint8(image: np.ndarray) -> np.ndarray:
    if image.dtype == np.uint8:
        return image
    if image.dtype == np.uint16:
        return (image >> 8).astype(np.uint8)
    clipped: np.ndarray = np.clip(np.rint(image), 0, 255).astype(np.uint8)
    return clipped
