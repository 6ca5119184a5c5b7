"""FuzzyDecision -> the correlation area correlation_node searches next (area_search.TrackedArea).

Kept apart from conversions.py: only correlation_node reads a decision back.
"""

from __future__ import annotations

import numpy as np

from stereo_fuzzy_msgs.msg import FuzzyDecision
from stereo_fuzzy_perception.core.matching.area_search import TrackedArea


def stamp_seconds(stamp: object) -> float:
    """Return a builtin_interfaces/Time as seconds [s]."""
    return int(stamp.sec) + 1e-9 * int(stamp.nanosec)


def decision_to_tracked_area(msg: FuzzyDecision) -> TrackedArea | None:
    """Return the decision's correlation area, or None when it found no object (or no area).

    Returns:
        The area with its border points, top height, surface plane and noise; None for a
        decision without a best point or whose values are not usable (area.problem()).
    """
    if not msg.has_best_point or msg.status != FuzzyDecision.STATUS_OK:
        return None
    area = TrackedArea(
        stamp_s=stamp_seconds(msg.header.stamp),
        border_points=np.array([[point.x, point.y, point.z] for point in msg.border_points],
                               dtype=float),
        top_height_m=float(msg.top_height),
        surface_point=(0.0, 0.0, float(msg.surface_offset_m)),
        surface_normal=(float(msg.surface_normal.x), float(msg.surface_normal.y),
                        float(msg.surface_normal.z)),
        disparity_sigma_px=float(msg.disparity_sigma_px))
    return None if area.problem() else area


def decision_points(msg: FuzzyDecision) -> tuple[np.ndarray, np.ndarray]:
    """Return the best point in world and in the camera frame [m] (to check a pose with)."""
    world, camera = msg.best_point_world, msg.best_point_camera
    return (np.array([world.x, world.y, world.z], dtype=float),
            np.array([camera.x, camera.y, camera.z], dtype=float))
