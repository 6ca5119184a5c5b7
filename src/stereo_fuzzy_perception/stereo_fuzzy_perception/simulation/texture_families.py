"""Procedural texture families for the scene simulator: what tables and objects look like.

No photographs can be downloaded here, so every family is generated from a seed, in metres (the
caller passes what the texture spans), so a feature's size on the object does not depend on the
texture's resolution:

* `value_noise`: multi-octave value noise, 2.4-50 mm (the simulator's original texture,
  scene_renderer.random_texture).
* `wood`: growth rings 3-9 mm apart, bent by low-frequency noise, with fibres along the grain.
* `fabric`: a plain weave of 1-2.5 mm threads, each thread its own shade (nearly periodic, as
  cloth is: a trap for window correlation).
* `speckle`: dark and light dots 0.6-3 mm across on a smooth background.
* `granite`: blobs with sharp edges at two scales over fine grain (stone, terrazzo, chipboard).
* `printed`: paper with printed bars and blocks (labels, packaging): edges in few directions,
  large flat parts.
* `low_texture`: a smooth surface with 6-10 % contrast at 10-60 mm and faint fine grain (painted
  metal, plastic): most windows fail the texture test.

ROS-free: numpy and OpenCV only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

TEXTURE_FAMILIES = ('value_noise', 'wood', 'fabric', 'speckle', 'granite', 'printed',
                    'low_texture')


class TextureError(ValueError):
    """An unknown texture family, with the known ones in the message."""


@dataclass(frozen=True)
class NoiseScales:
    """Cell sizes of value noise octaves [m].

    Attributes:
        finest_feature_m: Cell size of the finest octave [m].
        coarsest_feature_m: Cell size of the coarsest octave [m].
    """

    finest_feature_m: float = 0.0024
    coarsest_feature_m: float = 0.05


def value_noise(rng: np.random.Generator, size_px: int, texel_m: float, finest_m: float,
                coarsest_m: float, persistence: float = 1.0) -> np.ndarray:
    """Return (size, size) float32 multi-octave value noise normalised to 0..1 (1-99 %).

    Args:
        rng: Generator the grids are drawn from.
        size_px: Side of the square texture [px].
        texel_m: What one texture pixel covers [m].
        finest_m: Cell size of the finest octave [m] (at least 2 texels).
        coarsest_m: Cell size of the coarsest octave [m].
        persistence: Weight of each octave relative to the next finer one.
    """
    cell_px = max(2.0, finest_m / texel_m)
    noise = np.zeros((size_px, size_px), dtype=np.float32)
    weight = 1.0
    while cell_px <= max(2.0, coarsest_m / texel_m):
        cells = int(math.ceil(size_px / cell_px)) + 3
        grid = rng.random((cells, cells), dtype=np.float32)
        grown = cv2.resize(grid, None, fx=cell_px, fy=cell_px, interpolation=cv2.INTER_CUBIC)
        offset = int(cell_px)
        noise += weight * grown[offset:offset + size_px, offset:offset + size_px]
        cell_px *= 2.0
        weight *= persistence
    return _normalised(noise)


def _normalised(values: np.ndarray) -> np.ndarray:
    low, high = np.percentile(values, (1.0, 99.0))
    result: np.ndarray = np.clip((values - low) / max(float(high - low), 1e-6), 0.0, 1.0)
    return result.astype(np.float32)


def _coordinates(size_px: int, texel_m: float) -> tuple[np.ndarray, np.ndarray]:
    axis = (np.arange(size_px, dtype=np.float32) + 0.5) * np.float32(texel_m)
    x, y = np.meshgrid(axis, axis)
    return x, y


def _wood(rng: np.random.Generator, size_px: int, texel_m: float) -> np.ndarray:
    x, y = _coordinates(size_px, texel_m)
    angle = rng.uniform(0.0, math.pi)
    across = x * math.cos(angle) + y * math.sin(angle)
    along = -x * math.sin(angle) + y * math.cos(angle)
    spacing = rng.uniform(0.003, 0.009)
    bend = value_noise(rng, size_px, texel_m, 0.02, 0.16)
    phase = (across + spacing * 2.5 * bend + 0.3 * along * rng.uniform(-0.05, 0.05)) / spacing
    rings = np.mod(phase, 1.0) ** rng.uniform(1.5, 3.0)
    fibres = _streaks(rng, size_px, texel_m, angle)
    return _normalised(0.65 * rings + 0.35 * fibres)


def _streaks(rng: np.random.Generator, size_px: int, texel_m: float, angle: float
             ) -> np.ndarray:
    """Noise stretched along the direction `angle` [rad] (fibres, brushing)."""
    fine = max(2.0, 0.0015 / texel_m)
    cells = int(math.ceil(size_px / fine)) + 3
    grid = rng.random((cells, max(4, cells // 12)), dtype=np.float32)
    grown = cv2.resize(grid, (2 * size_px, 2 * size_px), interpolation=cv2.INTER_CUBIC)
    rotation = cv2.getRotationMatrix2D((size_px, size_px), math.degrees(-angle) + 90.0, 1.0)
    rotated = cv2.warpAffine(grown, rotation, (2 * size_px, 2 * size_px),
                             borderMode=cv2.BORDER_REFLECT)
    start = size_px // 2
    return _normalised(rotated[start:start + size_px, start:start + size_px])


def _fabric(rng: np.random.Generator, size_px: int, texel_m: float) -> np.ndarray:
    x, y = _coordinates(size_px, texel_m)
    pitch = max(rng.uniform(0.001, 0.0025), 4.0 * texel_m)
    columns, rows = np.floor(x / pitch).astype(np.int64), np.floor(y / pitch).astype(np.int64)
    count = int(columns.max()) + 2
    warp_shade = rng.uniform(0.5, 1.0, size=count).astype(np.float32)
    weft_shade = rng.uniform(0.5, 1.0, size=count).astype(np.float32)
    over = (columns + rows) % 2 == 0
    fx, fy = np.mod(x / pitch, 1.0), np.mod(y / pitch, 1.0)
    profile = np.where(over, np.sin(math.pi * fx), np.sin(math.pi * fy)).astype(np.float32)
    shade = np.where(over, warp_shade[columns], weft_shade[rows]) * (0.55 + 0.45 * profile)
    slub = value_noise(rng, size_px, texel_m, 0.01, 0.08)
    return _normalised(shade * (0.8 + 0.2 * slub))


def _speckle(rng: np.random.Generator, size_px: int, texel_m: float) -> np.ndarray:
    base = 0.5 + 0.15 * (value_noise(rng, size_px, texel_m, 0.02, 0.1) - 0.5)
    canvas = np.ascontiguousarray(base, dtype=np.float32)
    area_m2 = (size_px * texel_m) ** 2
    mean_radius = rng.uniform(0.0003, 0.0015)
    count = int(0.5 * area_m2 / (math.pi * mean_radius ** 2))
    centres = rng.uniform(0, size_px, size=(count, 2))
    radii = np.maximum(1.0, rng.uniform(0.5, 1.5, size=count) * mean_radius / texel_m)
    values = rng.choice([0.05, 0.95], size=count) + rng.uniform(-0.05, 0.05, size=count)
    for (cx, cy), radius, value in zip(centres, radii, values, strict=True):
        cv2.circle(canvas, (int(cx), int(cy)), int(round(radius)), float(value), -1,
                   lineType=cv2.LINE_AA)
    return _normalised(canvas)


def _granite(rng: np.random.Generator, size_px: int, texel_m: float) -> np.ndarray:
    shade = np.zeros((size_px, size_px), dtype=np.float32)
    for finest, coarsest, share in ((0.003, 0.012, 0.45), (0.01, 0.04, 0.35)):
        blobs = value_noise(rng, size_px, texel_m, finest, coarsest)
        level = rng.uniform(0.45, 0.65)
        shade += share * (blobs > level).astype(np.float32)
    grain = value_noise(rng, size_px, texel_m, 0.0012, 0.003)
    return _normalised(shade + 0.2 * grain)


def _printed(rng: np.random.Generator, size_px: int, texel_m: float) -> np.ndarray:
    paper = 0.85 + 0.08 * value_noise(rng, size_px, texel_m, 0.002, 0.02)
    canvas = np.ascontiguousarray(paper, dtype=np.float32)
    span_m = size_px * texel_m
    for _ in range(int(rng.integers(20, 60)) * max(1, int(span_m / 0.25) ** 2)):
        width_m = rng.uniform(0.002, 0.04)
        height_m = rng.uniform(0.001, 0.008) if rng.random() < 0.7 else rng.uniform(0.01, 0.04)
        x0, y0 = rng.uniform(0, size_px, size=2)
        x1, y1 = x0 + width_m / texel_m, y0 + height_m / texel_m
        ink = float(rng.uniform(0.05, 0.6))
        cv2.rectangle(canvas, (int(x0), int(y0)), (int(x1), int(y1)), ink, -1)
    return np.clip(canvas, 0.0, 1.0)


def _low_texture(rng: np.random.Generator, size_px: int, texel_m: float) -> np.ndarray:
    contrast = rng.uniform(0.06, 0.10)
    coarse = value_noise(rng, size_px, texel_m, 0.01, 0.06)
    grain = value_noise(rng, size_px, texel_m, 0.0015, 0.003)
    return (0.5 + contrast * (coarse - 0.5) + 0.02 * (grain - 0.5)).astype(np.float32)


_FAMILIES = {'wood': _wood, 'fabric': _fabric, 'speckle': _speckle, 'granite': _granite,
             'printed': _printed, 'low_texture': _low_texture}


def family_shade(family: str, seed: int, size_px: int, span_m: float,
                 scales: NoiseScales = NoiseScales()) -> np.ndarray:
    """Return the (size, size) float32 shade 0..1 of a texture of `family`.

    Args:
        family: One of TEXTURE_FAMILIES.
        seed: Seed of the texture.
        size_px: Side of the square texture [px].
        span_m: What the texture covers [m].
        scales: Octaves of the `value_noise` family.

    Raises:
        TextureError: For an unknown family.
    """
    rng = np.random.default_rng(seed)
    texel_m = span_m / size_px
    if family == 'value_noise':
        return value_noise(rng, size_px, texel_m, scales.finest_feature_m,
                           scales.coarsest_feature_m)
    if family not in _FAMILIES:
        raise TextureError(f'unknown texture family {family!r}; expected one of '
                           + ', '.join(TEXTURE_FAMILIES))
    return _FAMILIES[family](rng, size_px, texel_m)


def tinted(shade: np.ndarray, tint: tuple[float, float, float], hue: np.ndarray,
           dark: float = 0.25) -> np.ndarray:
    """Return the RGB uint8 texture of a shade 0..1: (dark + (1 - dark) shade) (tint + hue)."""
    channels = [np.clip((dark + (1.0 - dark) * shade) * (tint[k] + hue[k]), 0.0, 1.0)
                for k in range(3)]
    return np.round(np.stack(channels, axis=2) * 255.0).astype(np.uint8)


def family_texture(family: str, seed: int, size_px: int, span_m: float,
                   tint: tuple[float, float, float], scales: NoiseScales = NoiseScales()
                   ) -> np.ndarray:
    """Return an RGB uint8 texture of `family` with mean colour about `tint` (0..1 each).

    (The renderer draws `value_noise` with scene_renderer.random_texture, so scenes rendered
    before the families existed keep their exact pixels.)

    Raises:
        TextureError: For an unknown family.
    """
    shade = family_shade(family, seed, size_px, span_m, scales)
    hue = np.random.default_rng([seed, 0x7105]).random((3,), dtype=np.float32) * 0.2 - 0.1
    return tinted(shade, tint, hue)


__all__ = ['TEXTURE_FAMILIES', 'NoiseScales', 'TextureError', 'family_shade', 'family_texture',
           'tinted', 'value_noise']
