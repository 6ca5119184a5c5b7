"""The work surface measured from each pair's points, and each point's depth uncertainty.

ROS-free: numpy only.

Depth noise. A match of disparity d (left u minus right u, less the principal points' shift)
lies at p = c + v, v = Z_rect / f along the pixel's ray, Z_rect = f B / d. A disparity error of
sigma_d moves it along the ray by dp = -v / d * sigma_d (sigma_Z = Z^2 / (f B) * sigma_d for the
depth), so its height above a plane of unit normal n moves by |n . v| / d * sigma_d. That
factor, `height_per_disparity` [m/px], turns every threshold in sigmas into metres for each
point: at 0.3 m it is a few tenths of a millimetre per pixel, at 0.9 m several millimetres.

The plane. Points within `search_m` of the plane z = 0 the rig pose predicts are the
candidates. Residuals are compared in disparity pixels (height residual / height_per_disparity),
where the noise is the same for every point. A least-quantile-of-squares search over random
3-point planes tilted at most MAX_TILT_DEG (a fixed seed, so the same points give the same
plane) finds the surface even when an object or a noise sheet holds up to half of the
candidates; weighted least squares on
the points within INLIER_SIGMAS of it then refines it, and the spread of those residuals gives
sigma_d, the disparity noise of this pair.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SURFACE_MEASURED = 'measured'
SURFACE_ASSUMED = 'assumed'
SURFACE_PLAIN = 'plain'
"""The surface's matches are sensor noise (a plain surface): the plane is assumed, z = 0."""

HYPOTHESES = 60
"""Random 3-point planes tried by the least-quantile search."""

SEARCH_SAMPLE = 1000
"""Candidates (evenly spread) on which the hypotheses are scored."""

SEARCH_QUANTILE = 0.3
"""A hypothesis is scored by this quantile of its absolute residuals (least quantile of
squares): the surface wins while it holds more than this share of the candidates, and a plane
through the surface and a low object beside it, which halves the residuals of both, loses to
the plane that fits the surface alone."""

SEARCH_QUANTILE_SIGMAS = 0.385
"""That quantile of |N(0, 1)|, in standard deviations."""

INLIER_SIGMAS = 3.0
"""Refinement keeps candidates within this many sigmas of the plane."""

MAD_SCALE = 1.4826
"""Median absolute deviation of a normal distribution, in standard deviations."""

MAX_TILT_DEG = 2.0
"""Planes tilted more than this from the one the rig pose predicts are not the surface: a rig
pose is off by a fraction of a degree, while a plane through the surface and the top of a low
object next to it is tilted by several."""

FIT_SAMPLE = 8000
"""Candidates (evenly spread) the plane is refined on: more add time, not precision."""

MIN_SURFACE_POINTS = 50
"""Fewer candidates than this and the plane is assumed (z = 0), not measured."""


@dataclass(frozen=True)
class SurfacePlane:
    """The work surface, z = slope_x x + slope_y y + offset in `world`, and the pair's noise.

    Attributes:
        source: SURFACE_MEASURED, SURFACE_ASSUMED when too few points showed it, or
            SURFACE_PLAIN when its matches were sensor noise (correlation_area.py).
        slope_x: dz/dx [-].
        slope_y: dz/dy [-].
        offset_m: z of the plane at x = y = 0 [m].
        disparity_sigma_px: Disparity noise of the pair's matches on the surface [px].
        inliers: Points that measured the plane (0 when assumed).
    """

    source: str
    slope_x: float
    slope_y: float
    offset_m: float
    disparity_sigma_px: float
    inliers: int

    @property
    def normal(self) -> np.ndarray:
        """Return the unit normal (pointing up)."""
        normal = np.array([-self.slope_x, -self.slope_y, 1.0])
        return normal / float(np.linalg.norm(normal))

    @property
    def tilt_deg(self) -> float:
        """Return the angle between the plane's normal and world z [deg]."""
        return math.degrees(math.atan(math.hypot(self.slope_x, self.slope_y)))

    def height_at(self, x: float, y: float) -> float:
        """Return z of the plane at (x, y) [m]."""
        return self.slope_x * x + self.slope_y * y + self.offset_m

    def heights(self, world: np.ndarray) -> np.ndarray:
        """Return the signed distances [m] of (3, N) world points from the plane (up > 0)."""
        below = world[2] - self.slope_x * world[0] - self.slope_y * world[1] - self.offset_m
        distance: np.ndarray = below / math.sqrt(1.0 + self.slope_x ** 2 + self.slope_y ** 2)
        return distance


def height_per_disparity(world: np.ndarray, camera_centre: np.ndarray, disparity: np.ndarray,
                         normal: np.ndarray) -> np.ndarray:
    """Return how far [m] a 1 px disparity error moves each point along `normal`.

    Args:
        world: (3, N) points in `world` [m].
        camera_centre: (3,) left optical centre in `world` [m].
        disparity: (N,) effective disparity f B / Z_rect of each point [px], positive.
        normal: (3,) unit normal of the surface the heights are measured from.
    """
    ray = world - np.asarray(camera_centre, dtype=float).reshape(3, 1)
    along: np.ndarray = np.abs(np.asarray(normal, dtype=float) @ ray) / disparity
    return along


def _planes_through(points: np.ndarray) -> np.ndarray:
    """Return (K, 3) (slope_x, slope_y, offset) of the planes through (K, 3, 3) point triples
    (rows: points; columns: x, y, z), leaving out degenerate triples."""
    design = np.concatenate([points[:, :, :2], np.ones(points.shape[:2] + (1,))], axis=2)
    usable = np.abs(np.linalg.det(design)) > 1e-12
    solution: np.ndarray = np.linalg.solve(design[usable], points[usable, :, 2:])[..., 0]
    return solution


def _weighted_fit(world: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Return (slope_x, slope_y, offset) by least squares on z, residuals divided by scale.

    By the normal equations, centred on the points' weighted mean so that they stay well
    conditioned: three unknowns over thousands of points need a 2x2 solve, not an SVD of the
    whole design matrix. Points on one line (a peer's message can hold anything) give the
    least-norm slopes instead of an error.
    """
    weight = 1.0 / scale ** 2
    total = float(np.sum(weight))
    mean = (world @ weight) / total
    centred = world - mean[:, None]
    x, y, z = centred[0], centred[1], centred[2]
    wx, wy = weight * x, weight * y
    normal = np.array([[wx @ x, wx @ y], [wx @ y, wy @ y]])
    slopes = np.linalg.lstsq(normal, np.array([wx @ z, wy @ z]), rcond=None)[0]
    return np.array([slopes[0], slopes[1], mean[2] - slopes[0] * mean[0] - slopes[1] * mean[1]])


def fit_work_surface(world: np.ndarray, per_disparity: np.ndarray, search_m: float,
                     min_sigma_px: float, assumed_sigma_px: float) -> SurfacePlane:
    """Measure the work surface among points near z = 0.

    Args:
        world: (3, N) points in `world` [m].
        per_disparity: (N,) height change per pixel of disparity of each point [m/px]
            (height_per_disparity with the normal of z = 0).
        search_m: Only points with |z| within this are candidates [m].
        min_sigma_px: Lower bound of the measured disparity noise [px].
        assumed_sigma_px: Disparity noise used when the plane cannot be measured [px].

    Returns:
        The plane and the pair's disparity noise; SURFACE_ASSUMED (z = 0, assumed_sigma_px)
        when fewer than MIN_SURFACE_POINTS candidates or no plane is found.
    """
    assumed = SurfacePlane(SURFACE_ASSUMED, 0.0, 0.0, 0.0, max(assumed_sigma_px, min_sigma_px),
                           0)
    candidate = np.flatnonzero(np.abs(world[2]) <= search_m)
    if len(candidate) < MIN_SURFACE_POINTS:
        return assumed
    # In a canonical order (by x), so the order of the points cannot change the plane.
    candidate = candidate[np.argsort(world[0, candidate], kind='stable')]
    if len(candidate) > FIT_SAMPLE:
        candidate = candidate[np.linspace(0, len(candidate) - 1, FIT_SAMPLE).astype(int)]
    points = world[:, candidate]
    scale = per_disparity[candidate]
    sample = np.linspace(0, len(candidate) - 1, min(SEARCH_SAMPLE, len(candidate))).astype(int)
    sample_points, sample_scale = points[:, sample], scale[sample]
    triples = np.random.default_rng(0).integers(0, len(sample), size=(HYPOTHESES, 3))
    hypotheses = _planes_through(sample_points.T[triples])
    level = np.hypot(hypotheses[:, 0], hypotheses[:, 1]) <= math.tan(math.radians(MAX_TILT_DEG))
    hypotheses = hypotheses[level]
    if not len(hypotheses):
        return assumed
    residual = (sample_points[2] - hypotheses[:, :1] * sample_points[0]
                - hypotheses[:, 1:2] * sample_points[1] - hypotheses[:, 2:]) / sample_scale
    rank = int(SEARCH_QUANTILE * (residual.shape[1] - 1))
    quantiles = np.partition(np.abs(residual), rank, axis=1)[:, rank]
    best = int(np.argmin(quantiles))
    plane = hypotheses[best]
    sigma = max(float(quantiles[best]) / SEARCH_QUANTILE_SIGMAS, min_sigma_px)
    inside = np.zeros(0, dtype=int)
    for _ in range(3):
        residual = (points[2] - plane[0] * points[0] - plane[1] * points[1] - plane[2]) / scale
        inside = np.flatnonzero(np.abs(residual) <= INLIER_SIGMAS * sigma)
        if len(inside) < MIN_SURFACE_POINTS:
            return assumed
        plane = _weighted_fit(points[:, inside], scale[inside])
        residual = (points[2, inside] - plane[0] * points[0, inside]
                    - plane[1] * points[1, inside] - plane[2]) / scale[inside]
        # The median absolute residual of the inliers: a cut at 3 sigma hardly shrinks it,
        # and an object among the candidates cannot widen it.
        sigma = max(MAD_SCALE * float(np.median(np.abs(residual))), min_sigma_px)
    return SurfacePlane(SURFACE_MEASURED, float(plane[0]), float(plane[1]), float(plane[2]),
                        sigma, len(inside))
