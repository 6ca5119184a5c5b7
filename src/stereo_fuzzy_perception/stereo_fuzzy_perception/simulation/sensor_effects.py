"""Light and sensors: the renderer's lighting, and what the cameras add to the ideal image.

Sensors add Gaussian noise, and a gain and offset of the right camera relative to the left; the
lenses' distortion coefficients are part of the sensor model too (render_camera applies them).
The lighting is mostly ambient so flat tops never saturate.

ROS-free: numpy and OpenCV only.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class SensorModel:
    """What the two cameras add to the ideal image.

    Attributes:
        noise_std: Standard deviation of additive Gaussian noise [grey levels of 255].
        right_gain: Right camera's gain relative to the left [-].
        right_offset: Right camera's offset relative to the left [grey levels of 255].
        distortion: plumb_bob coefficients (k1, k2, p1, p2, k3), the same for both lenses.
    """

    noise_std: float = 0.0
    right_gain: float = 1.0
    right_offset: float = 0.0
    distortion: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)

    @property
    def distorted(self) -> bool:
        """Return True when the lenses distort."""
        return any(value != 0.0 for value in self.distortion)


@dataclass(frozen=True)
class Lighting:
    """TinyRenderer light: mostly ambient so textured tops keep their contrast.

    Attributes:
        direction: Direction toward the light in `world` [-].
        ambient: Ambient coefficient [-].
        diffuse: Diffuse coefficient [-].
        specular: Specular coefficient [-].
    """

    direction: tuple[float, float, float] = (0.3, -0.5, 1.0)
    ambient: float = 0.55
    diffuse: float = 0.4
    specular: float = 0.0


def apply_sensor(image: np.ndarray, rng: np.random.Generator, gain: float, offset: float,
                 noise_std: float) -> np.ndarray:
    """Return `image` times `gain` plus `offset` and noise (itself when all are neutral)."""
    if gain == 1.0 and offset == 0.0 and noise_std == 0.0:
        return image
    values = image.astype(np.float32) * gain + offset
    if noise_std > 0.0:
        values += rng.normal(0.0, noise_std, size=values.shape).astype(np.float32)
    return np.clip(np.round(values), 0, 255).astype(np.uint8)


def to_encoding(rgb: np.ndarray, encoding: str) -> np.ndarray:
    """Return the RGB image `rgb` in `encoding` (rgb8, bgr8 or mono8)."""
    if encoding == 'rgb8':
        return np.ascontiguousarray(rgb)
    if encoding == 'bgr8':
        return cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
    return cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
