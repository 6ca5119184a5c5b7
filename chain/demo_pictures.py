"""Draw what the chain decided about one object onto the left camera image.

A sample of the matched points (coloured by correlation score), the four border points of the
correlation area (magenta), the split into four areas (Fig. 4 of the chapter) with their centres
numbered 1-4, the best point (red) and the ground truth (white). Points are projected with the
raw left camera model (K, D) from the pair, so the picture shows the image as the camera took it.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from stereo_fuzzy_perception.core.rig_geometry import StereoRig
from stereo_fuzzy_perception.nodes.conversions import (
    camera_info_to_calibration,
    cloud_to_matched_points,
    image_to_array,
)

RIG_FIELDS = ('baseline_m', 'alpha_deg', 'theta_deg', 'x0_m', 'y0_m', 'z0_m', 'vergence_deg')


def rig_from_params(params: dict) -> StereoRig:
    """Return the rig that fuzzy_best_point_node is configured with in a parameter file."""
    node_params = params.get('fuzzy_best_point_node', {}).get('ros__parameters', {})
    rig_params = node_params.get('rig', {})
    return StereoRig(**{name: float(rig_params[name]) for name in RIG_FIELDS
                        if name in rig_params})


def _project(points_camera: np.ndarray, K: np.ndarray, D: np.ndarray) -> np.ndarray:
    if len(points_camera) == 0:
        return np.zeros((0, 2))
    pixels, _ = cv2.projectPoints(points_camera.reshape(-1, 1, 3).astype(np.float64),
                                  np.zeros(3), np.zeros(3), K, D)
    return pixels.reshape(-1, 2)


def draw_scene(record: object, params: dict, path: Path) -> bool:
    """Write the picture of one scene record to `path`; return False when there is no image."""
    if record.pair is None:
        return False
    image = image_to_array(record.pair.left_image)
    encoding = record.pair.left_image.encoding
    if image.ndim == 2:
        canvas = cv2.cvtColor(cv2.convertScaleAbs(image, alpha=255.0 / max(1, image.max()))
                              if image.dtype != np.uint8 else image, cv2.COLOR_GRAY2BGR)
    elif encoding.startswith('rgb'):
        canvas = cv2.cvtColor(image[:, :, :3], cv2.COLOR_RGB2BGR)
    else:
        canvas = np.ascontiguousarray(image[:, :, :3])
    calibration = camera_info_to_calibration(record.pair.left_info)
    camera_from_world = np.linalg.inv(rig_from_params(params).world_from_left_camera())

    def to_pixels(points_world: np.ndarray) -> np.ndarray:
        camera = points_world @ camera_from_world[:3, :3].T + camera_from_world[:3, 3]
        return _project(camera, calibration.K, calibration.D)

    if record.matches is not None:
        # A sample of the matches, blended, so the image stays visible underneath.
        matches = cloud_to_matched_points(record.matches.points)
        step = max(1, len(matches) // 4000)
        pixels = _project(matches.xyz[::step], calibration.K, calibration.D)
        overlay = canvas.copy()
        for (u, v), score in zip(pixels, matches.score[::step], strict=True):
            green = int(np.clip(score, 0.0, 1.0) * 255)
            cv2.circle(overlay, (int(round(u)), int(round(v))), 1, (0, green, 255 - green), -1)
        canvas = cv2.addWeighted(overlay, 0.45, canvas, 0.55, 0.0)
    decision = record.decision
    border = np.zeros((0, 2))
    if decision is not None and decision.points_used > 0:
        border = to_pixels(np.array([[p.x, p.y, p.z] for p in decision.border_points]))
        border = border[np.all(np.isfinite(border), axis=1)]
    if decision is not None and len(border) > 0:
        low, high = border.min(axis=0), border.max(axis=0)
        middle = (low + high) / 2
        box = [tuple(int(round(c)) for c in corner) for corner in (low, high)]
        cv2.rectangle(canvas, box[0], box[1], (255, 255, 0), 1)
        cv2.line(canvas, (int(middle[0]), box[0][1]), (int(middle[0]), box[1][1]),
                 (255, 255, 0), 1)
        cv2.line(canvas, (box[0][0], int(middle[1])), (box[1][0], int(middle[1])),
                 (255, 255, 0), 1)
        for u, v in border:
            cv2.drawMarker(canvas, (int(round(u)), int(round(v))), (255, 0, 255),
                           cv2.MARKER_DIAMOND, 10, 2)
        centres = to_pixels(np.array([[p.x, p.y, p.z] for p in decision.area_centres]))
        for number, (u, v) in enumerate(centres, start=1):
            if not (np.isfinite(u) and np.isfinite(v)):
                continue  # an empty area has no centre
            cv2.putText(canvas, str(number), (int(u) - 4, int(v) + 4), cv2.FONT_HERSHEY_SIMPLEX,
                        0.45, (255, 255, 0), 1, cv2.LINE_AA)
    marks = []
    if record.ground_truth is not None:
        marks.append((record.ground_truth, (255, 255, 255), cv2.MARKER_CROSS, 'ground truth'))
    if record.best_point is not None:
        marks.append((record.best_point, (0, 0, 255), cv2.MARKER_TILTED_CROSS, 'best point'))
    for point, colour, marker, label in marks:
        (u, v), = to_pixels(point.reshape(1, 3))
        cv2.drawMarker(canvas, (int(round(u)), int(round(v))), colour, marker, 18, 2)
        below = 22 if label == 'ground truth' else -10
        cv2.putText(canvas, label, (int(u) + 10, int(v) + below), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                    colour, 1, cv2.LINE_AA)
    status = decision.status if decision is not None else 'no decision'
    cv2.putText(canvas, f'{decision.selector if decision else ""}: {status}', (8, 20),
                cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), canvas)
    return True
