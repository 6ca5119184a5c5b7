"""The fuzzy stage's BestPointDecision -> FuzzyDecision, PointStamped and MarkerArray.

The decision message carries everything the stage knew (surface, border points, areas, rule
firing); the best point goes to the gantry as a PointStamped in `world`; the markers draw the
correlation area, its border points, the four areas and the best point for RViz or Foxglove.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from geometry_msgs.msg import Point, PointStamped, Vector3
from std_msgs.msg import Header
from visualization_msgs.msg import Marker, MarkerArray

from stereo_fuzzy_msgs.msg import FuzzyDecision

if TYPE_CHECKING:  # annotations only: nodes that never decide need not import scipy
    from stereo_fuzzy_perception.core.best_point.point_selectors import BestPointDecision


def _point(values: np.ndarray | None) -> Point:
    """Return a geometry_msgs/Point; NaN (unknown) stays NaN, None gives the origin."""
    if values is None:
        return Point()
    return Point(x=float(values[0]), y=float(values[1]), z=float(values[2]))


def decision_to_message(decision: BestPointDecision, header: Header,
                        camera_frame_id: str) -> FuzzyDecision:
    """Return a FuzzyDecision (header.frame_id should be `world`) for one BestPointDecision.

    Unknown values (no correlation area, empty areas) are NaN; rule arrays are empty for
    selectors without rules.
    """
    msg = FuzzyDecision()
    msg.header = header
    msg.selector = decision.selector
    msg.rule_base = decision.rule_base
    msg.has_best_point = decision.has_best_point
    msg.status = decision.status_text()
    msg.best_point_world = _point(decision.best_point_world)
    msg.best_point_camera = _point(decision.best_point_camera)
    msg.camera_frame_id = camera_frame_id
    msg.points_in = int(decision.points_in)
    msg.points_valid = int(decision.points_valid)
    msg.clusters_found = int(decision.clusters_found)
    msg.points_used = int(decision.points_used)
    msg.top_height = float(decision.top_height)
    surface = decision.surface
    msg.surface_source = surface.source
    msg.surface_offset_m = float(surface.offset_m)
    msg.surface_tilt_deg = float(surface.tilt_deg)
    normal = surface.normal
    msg.surface_normal = Vector3(x=float(normal[0]), y=float(normal[1]), z=float(normal[2]))
    msg.surface_points = int(surface.inliers)
    msg.disparity_sigma_px = float(surface.disparity_sigma_px)
    msg.object_height_sigmas = float(decision.object_height_sigmas)
    msg.border_points = [_point(row) for row in decision.border_points]
    msg.border_distances = [float(value) for value in decision.border_distances]
    msg.area_centres = [_point(row) for row in decision.area_centres]
    msg.area_centres_u_left = [float(value) for value in decision.area_centres_u_left]
    msg.area_centres_v_left = [float(value) for value in decision.area_centres_v_left]
    msg.area_centres_u_right = [float(value) for value in decision.area_centres_u_right]
    msg.area_point_counts = [int(value) for value in decision.area_point_counts]
    msg.d1 = [float(value) for value in decision.d1]
    msg.d2 = [float(value) for value in decision.d2]
    msg.ratio = [float(value) for value in decision.ratio]
    msg.rule_names = list(decision.rule_names)
    msg.membership_degrees = [float(value) for value in decision.membership_degrees]
    msg.firing_strengths = [float(value) for value in decision.firing_strengths]
    return msg


def best_point_to_point_stamped(decision: BestPointDecision, header: Header) -> PointStamped:
    """Return the decision's best point in `world` as a PointStamped (header: world, stamp).

    Raises:
        ValueError: When the decision has no best point.
    """
    if decision.best_point_world is None:
        raise ValueError(f'decision has no best point ({decision.status_text()})')
    return PointStamped(header=header, point=_point(decision.best_point_world))


# --- markers (visualization_msgs/MarkerArray) -------------------------------------------------

MARKER_NAMESPACE = 'best_point'
# RGBA of each kind of marker
_AREA_POINTS_COLOUR = (0.3, 0.6, 1.0, 0.8)
_BORDER_COLOUR = (1.0, 0.5, 0.0, 1.0)
_CENTRE_COLOUR = (1.0, 1.0, 0.0, 1.0)
_BEST_POINT_COLOUR = (0.0, 1.0, 0.0, 1.0)


def _marker(header: Header, kind: int, marker_id: int, namespace: str,
            scale: float, colour: tuple[float, float, float, float]) -> Marker:
    marker = Marker(header=header, ns=namespace, id=marker_id, type=kind, action=Marker.ADD)
    marker.pose.orientation.w = 1.0
    marker.scale.x = marker.scale.y = marker.scale.z = scale
    marker.color.r, marker.color.g, marker.color.b, marker.color.a = colour
    return marker


def _finite_points(values: np.ndarray) -> list[Point]:
    rows = np.asarray(values, dtype=float).reshape(-1, 3)
    return [_point(row) for row in rows if np.all(np.isfinite(row))]


def decision_to_markers(decision: BestPointDecision, header: Header,
                        namespace: str = MARKER_NAMESPACE) -> MarkerArray:
    """Return markers of one decision in header.frame_id (`world`), for RViz or Foxglove.

    A DELETEALL first clears the previous decision's markers, then (what is known of): the
    correlation area's points (POINTS, id 0), the four border points (SPHERE_LIST, id 1), the
    four areas' centres (SPHERE, ids 2-5) with their numbers as in Fig. 4 (TEXT_VIEW_FACING
    '1'..'4', ids 6-9), and the best point (SPHERE, id 10).
    """
    markers = [Marker(header=header, ns=namespace, action=Marker.DELETEALL)]
    area = _marker(header, Marker.POINTS, 0, namespace, 0.0015, _AREA_POINTS_COLOUR)
    area.points = _finite_points(decision.area_points_world)
    if area.points:
        markers.append(area)
    border = _marker(header, Marker.SPHERE_LIST, 1, namespace, 0.004, _BORDER_COLOUR)
    border.points = _finite_points(decision.border_points)
    if border.points:
        markers.append(border)
    for index, centre in enumerate(np.asarray(decision.area_centres, dtype=float)):
        if not np.all(np.isfinite(centre)):
            continue
        sphere = _marker(header, Marker.SPHERE, 2 + index, namespace, 0.004, _CENTRE_COLOUR)
        sphere.pose.position = _point(centre)
        label = _marker(header, Marker.TEXT_VIEW_FACING, 6 + index, namespace, 0.012,
                        _CENTRE_COLOUR)
        label.pose.position = _point(centre + np.array([0.0, 0.0, 0.008]))
        label.text = str(index + 1)
        markers += [sphere, label]
    if decision.best_point_world is not None:
        best = _marker(header, Marker.SPHERE, 10, namespace, 0.008, _BEST_POINT_COLOUR)
        best.pose.position = _point(decision.best_point_world)
        markers.append(best)
    return MarkerArray(markers=markers)
