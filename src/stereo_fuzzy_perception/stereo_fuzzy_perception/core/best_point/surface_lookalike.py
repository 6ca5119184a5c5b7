"""A face that barely stands out of the surface and looks like it is the surface. ROS-free.

On a table whose texture repeats itself (wood grain, woven fabric), the matcher takes a repeat
off over a patch of the table now and then, and that patch's matches stand together above the
surface as an object's top would. Most such patches stand only just past the object test
(`object_sigmas`, the area test below it), and so do real tops that are low or far: a 5 mm disc
on a far rig stands as little out of the noise. What tells them apart is the image: an object's
top has a texture or a shade of its own and differs from the table around it, while the patch
is the table's own texture. So a face standing less than LOW_FACE_SIGMAS out is refused as no
object when its appearance overlaps the ring around it by more than MAX_OVERLAP: the
Bhattacharyya coefficient of the histograms (APPEARANCE_BINS x APPEARANCE_BINS, on quantiles of
both) of smoothed grey and log contrast over 5 x 5 px, inside the face's convex hull in the
left image and in the ring RING_INNER_PX to RING_OUTER_PX outside it. What it changes,
measured: benchmarks/EXPERIMENTS.md, twenty-seventh session. ROS-free: numpy and OpenCV.
"""

from __future__ import annotations

import cv2
import numpy as np

from stereo_fuzzy_perception.core.best_point.object_segmentation import local_contrast
from stereo_fuzzy_perception.core.matched_points import RectifiedImage

LOW_FACE_SIGMAS = 6.2
"""Faces standing less than this out of the surface's noise (CorrelationArea.
object_height_sigmas) are looked at: where nearly all the faces given on bare tables stood
(the measurements: benchmarks/EXPERIMENTS.md, twenty-seventh session)."""

MAX_OVERLAP = 0.85
"""Such a face whose appearance overlaps its ring's by more than this is the surface."""

RING_INNER_PX = 6
"""The ring starts this far outside the face's hull [px] (past a correlation window's reach)..."""

RING_OUTER_PX = 14
"""...and ends this far outside it [px]."""

APPEARANCE_BINS = 8
"""Bins per axis of the appearance histograms."""

CROP_MARGIN_PX = RING_OUTER_PX + 10
"""The crop reaches this far past the face's pixels [px]: the ring, plus the reach of the
grey's smoothing (4 px) and of the contrast's square (2 px), with room to spare."""


def overlap_with_surroundings(u_left: np.ndarray, v_left: np.ndarray, image: RectifiedImage
                              ) -> float:
    """Return the Bhattacharyya coefficient (0: nothing alike, 1: the same) of the appearance
    inside the convex hull of the face's pixels (u_left, v_left) and in the ring around it;
    1.0 when either holds no pixel of the image part (nothing tells them apart)."""
    if image.pixels.ndim != 2 or len(u_left) < 3:
        return 1.0
    columns = np.asarray(u_left, dtype=float) - image.x
    rows = np.asarray(v_left, dtype=float) - image.y
    # Only the pixels around the face are smoothed: CROP_MARGIN_PX past the ring holds all
    # that the ring's smoothed grey and contrast read, so the crop changes no value.
    height, width = image.pixels.shape
    left = max(int(np.floor(columns.min())) - CROP_MARGIN_PX, 0)
    top = max(int(np.floor(rows.min())) - CROP_MARGIN_PX, 0)
    right = min(int(np.ceil(columns.max())) + CROP_MARGIN_PX + 1, width)
    bottom = min(int(np.ceil(rows.max())) + CROP_MARGIN_PX + 1, height)
    if right <= left or bottom <= top:
        return 1.0
    pixels = image.pixels[top:bottom, left:right]
    hull = cv2.convexHull(np.column_stack([columns - left, rows - top]).astype(np.float32))
    inside = np.zeros(pixels.shape, np.uint8)
    cv2.fillPoly(inside, [np.round(hull).astype(np.int32)], 1)
    outside = cv2.distanceTransform(1 - inside, cv2.DIST_L2, 3)
    ring = (outside > RING_INNER_PX) & (outside <= RING_OUTER_PX)
    face = inside.astype(bool)
    if not np.any(face) or not np.any(ring):
        return 1.0
    smooth = cv2.GaussianBlur(pixels.astype(np.float32), (0, 0), 1.0)
    contrast = np.log1p(local_contrast(smooth, 5))
    both = face | ring
    edges = [np.quantile(values[both], np.linspace(0.0, 1.0, APPEARANCE_BINS + 1))
             for values in (smooth, contrast)]
    for edge in edges:
        edge[0], edge[-1] = edge[0] - 1.0, edge[-1] + 1.0
    shares = []
    for part in (face, ring):
        histogram = np.histogram2d(smooth[part], contrast[part], edges)[0]
        shares.append(histogram / histogram.sum())
    return float(np.sum(np.sqrt(shares[0] * shares[1])))


def looks_like_the_surface(u_left: np.ndarray, v_left: np.ndarray, height_sigmas: float,
                           image: RectifiedImage) -> float | None:
    """Return the face's overlap with its surroundings when it stands less than
    LOW_FACE_SIGMAS out and overlaps them by more than MAX_OVERLAP, else None."""
    if not height_sigmas < LOW_FACE_SIGMAS:
        return None
    overlap = overlap_with_surroundings(u_left, v_left, image)
    return overlap if overlap > MAX_OVERLAP else None
