"""A low object's top face from its appearance, inside against around (step 1, last).

The image outline (face_outline.py) moves each point of the matches' outline to the strongest
edge across it. On a low object, a disc a few millimetres high, the top's own texture edges
near the rim (wood grain, a print's patches) can be stronger than the rim's, and the outline
follows them a few pixels into the face or out into the table: on a face 25-60 px across, a
centre a few millimetres off. The face's texture differs from the table's as a whole,
though: its grey levels and their local contrast come from another distribution than the
surroundings'. So, when the face stands so low that its side wall covers less than
LOW_WALL_PX of the image (a taller object's wall, of the top's texture in another shade,
would join the face):

1. Two appearance models, histograms of (smoothed grey level, log of the local contrast):
   the face's, from the face eroded by CORE_EROSION_PX, and the surroundings', from a ring
   RING_INNER_PX to RING_OUTER_PX outside it.
2. A pixel within REACH_PX of the face is the face's where the log-likelihood ratio of the two
   models, smoothed over LIKELIHOOD_SMOOTHING_PX, is positive; the face is the connected
   region of those pixels that holds most of the core, opened by a pixel, and its convex hull
   (the objects' tops are convex, and so are their images).
3. Its pixels, on the matches' grid, are cut with the top face's plane as the image outline's
   are (face_outline.face_within).

Where the face's models cannot be taken (a face too small for its core, a face near the edge
of the image sent, no region holding the core), the face stands as it was. ROS-free: numpy
and OpenCV.
"""

from __future__ import annotations

import cv2
import numpy as np

from stereo_fuzzy_perception.core.best_point.correlation_area import CorrelationArea
from stereo_fuzzy_perception.core.best_point.face_outline import (
    SUBPIXEL,
    crop_around,
    face_within,
    hull_outline,
    left_image_pixels,
)
from stereo_fuzzy_perception.core.best_point.object_segmentation import grid_step, local_contrast
from stereo_fuzzy_perception.core.camera_model import CameraCalibration
from stereo_fuzzy_perception.core.matched_points import RectifiedImage

LOW_WALL_PX = 3.0
"""A face is refined from its appearance when its side wall, from the top's height down to
the surface below the face's centre, covers less than this in the left image [px]."""

CORE_EROSION_PX = 3
"""The face's model is taken from the face eroded by this radius [px]: its rim stays out."""

RING_INNER_PX = 5
"""The surroundings' model is taken from a ring from this far outside the face [px]..."""

RING_OUTER_PX = 12
"""...to this far [px]."""

REACH_PX = 4
"""The refined face lies within this radius of the face [px]: a few pixels, what the image
outline can be off by."""

FEATURE_BINS = 12
"""Bins per feature of the appearance histograms."""

LIKELIHOOD_SMOOTHING_PX = 1.5
"""Gaussian smoothing of the log-likelihood ratio [px]: single pixels of either texture
inside the other."""

CONTRAST_SIDE_PX = 3
"""Side of the square over which a pixel's local contrast (grey-level deviation) is measured
[px]: a square straddling the rim takes the contrast of the more textured side, which then
grows by half a square, so the square is kept small."""

GREY_SMOOTHING_PX = 1.0
"""Gaussian smoothing of the grey level as a feature [px]: sensor noise."""

MIN_MODEL_PIXELS = 30
"""Fewest pixels of the core and of the ring a model is taken from."""


def side_wall_px(area: CorrelationArea, left: CameraCalibration,
                 world_from_camera: np.ndarray) -> float:
    """Return how far apart [px] the left image shows the face's centre and the surface
    point below it: the image height of the side wall the cameras may see.

    Args:
        area: A correlation area, status ok.
        left: Rectified calibration of the left image.
        world_from_camera: 4x4 pose of the left optical frame in `world`.
    """
    weight = area.point_weights()
    centre = (weight / weight.sum()) @ area.xyz_world
    foot = centre - area.top_height * area.surface.normal
    pixels = left_image_pixels(np.vstack([centre, foot]), left, world_from_camera)
    return float(np.linalg.norm(pixels[0] - pixels[1]))


def low_face_from_appearance(area: CorrelationArea, image: RectifiedImage,
                             left: CameraCalibration, right: CameraCalibration,
                             world_from_camera: np.ndarray, min_points: int
                             ) -> CorrelationArea | None:
    """Return a low object's face refined from its appearance, or None (the face stands).

    Args:
        area: The correlation area as decided so far, status ok.
        image: The part of the left rectified image the matches were found in.
        left: Rectified calibration of the left image.
        right: Rectified calibration of the right image.
        world_from_camera: 4x4 pose of the left optical frame in `world`.
        min_points: Fewest points of a face (AreaConfig.min_points).
    """
    # not below the limit: also a wall the projection cannot place (NaN), taken as tall
    if len(area.u_left) < 3 or not side_wall_px(area, left, world_from_camera) < LOW_WALL_PX:
        return None
    step = grid_step(area.u_left, area.v_left)
    outline = hull_outline(area.u_left, area.v_left, step)
    if outline is None:
        return None
    margin = RING_OUTER_PX + CONTRAST_SIDE_PX + int(np.ceil(3.0 * LIKELIHOOD_SMOOTHING_PX))
    around = crop_around(outline, margin, image)
    if around is None:
        return None  # the surroundings reach past the image sent
    crop, low = around
    face = np.zeros(crop.shape, np.uint8)
    cv2.fillConvexPoly(face, np.round((outline - low) * (1 << SUBPIXEL)).astype(np.int32), 1,
                       shift=SUBPIXEL)
    hull = _appearance_hull(face, crop)
    if hull is None:
        return None
    return face_within(area, hull + low, step, left, right, world_from_camera, min_points)


def _disc(radius: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))


def _appearance_hull(face: np.ndarray, crop: np.ndarray) -> np.ndarray | None:
    """Return the hull (K, 2) [crop px] of the pixels that look like the face, or None.

    Args:
        face: (H, W) uint8 mask of the face as decided so far.
        crop: (H, W) float32 grey levels around it.
    """
    core = cv2.erode(face, _disc(CORE_EROSION_PX)).astype(bool)
    ring = (cv2.dilate(face, _disc(RING_OUTER_PX)).astype(bool)
            & ~cv2.dilate(face, _disc(RING_INNER_PX)).astype(bool))
    if np.count_nonzero(core) < MIN_MODEL_PIXELS or np.count_nonzero(ring) < MIN_MODEL_PIXELS:
        return None
    grey = cv2.GaussianBlur(crop, (0, 0), GREY_SMOOTHING_PX)
    contrast = np.log1p(local_contrast(crop, CONTRAST_SIDE_PX))
    modelled = core | ring
    bins = np.zeros(crop.shape, np.int64)
    for feature in (grey, contrast):
        # bins over the central 98 % of the modelled pixels' values, the extremes clipped
        lowest, highest = np.percentile(feature[modelled], [1.0, 99.0])
        scaled = (feature - lowest) / max(float(highest - lowest), 1e-6) * FEATURE_BINS
        bins = bins * FEATURE_BINS + np.clip(scaled.astype(np.int64), 0, FEATURE_BINS - 1)
    cells = FEATURE_BINS * FEATURE_BINS

    def model(pixels: np.ndarray) -> np.ndarray:
        counts = np.bincount(bins[pixels], minlength=cells).reshape(FEATURE_BINS, FEATURE_BINS)
        # smoothed over neighbouring bins, never zero: a few hundred pixels fill 144 bins thinly
        density = cv2.GaussianBlur(counts.astype(np.float32), (0, 0), 1.0) + 1e-3
        probability: np.ndarray = (density / density.sum()).reshape(-1)
        return probability

    ratio = np.log(model(core)[bins] / model(ring)[bins]).astype(np.float32)
    ratio = cv2.GaussianBlur(ratio, (0, 0), LIKELIHOOD_SMOOTHING_PX)
    near = cv2.dilate(face, _disc(REACH_PX)).astype(bool)
    looks_like_face = ((ratio > 0.0) & near) | core
    opened = cv2.morphologyEx(looks_like_face.astype(np.uint8), cv2.MORPH_OPEN, _disc(1))
    count, labels = cv2.connectedComponents(opened, connectivity=8)
    held = np.bincount(labels[core], minlength=count)
    held[0] = 0
    if held.max() == 0:
        return None
    rows, columns = np.nonzero(labels == int(np.argmax(held)))
    hull: np.ndarray = cv2.convexHull(np.column_stack([columns, rows]).astype(np.float32))
    return hull.reshape(-1, 2).astype(float)
