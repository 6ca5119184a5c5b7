"""Draw what the chain decided about one scene: one picture of four panels and a title.

- camera: the left image as the camera took it, the zoomed region outlined;
- zoom: the object, enlarged, with a light sample of the matched points (coloured by correlation
  score), the correlation area's four border points (magenta) and its split into four areas
  (Fig. 4 of the chapter) with their centres numbered 1-4, the best point (red x) and the ground
  truth (white +);
- disparity: the disparity image correlation_node computed (stereo/disparity), where the object
  stands out from the work surface;
- top view: the work area from above, the object's footprint, the gantry's path up to this scene
  and where it stopped, the best point and the ground truth.

The title names the object type and the error [mm]. Points are projected with the raw left
camera model (K, D) from the pair. Also writes the disparity image alone (disparity_NN.png).
"""

from __future__ import annotations

from collections.abc import Sequence
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
PANEL = 480  # side of the zoom and top-view panels [px]
TITLE_HEIGHT = 44
OBJECT_RISE_PX = 0.4  # disparity above the row's surface that outlines an object [px]
FONT = cv2.FONT_HERSHEY_SIMPLEX
WHITE, RED, MAGENTA, CYAN = (255, 255, 255), (0, 0, 255), (255, 0, 255), (255, 255, 0)
GREY, YELLOW = (150, 150, 150), (0, 220, 255)


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


def _text(canvas: np.ndarray, text: str, origin: tuple[int, int], scale: float = 0.5,
          colour: tuple[int, int, int] = WHITE, thickness: int = 1) -> None:
    """Write text on a dark box, readable on any background."""
    (width, height), baseline = cv2.getTextSize(text, FONT, scale, thickness)
    x, y = origin
    box = canvas[max(0, y - height - 3):y + baseline + 1, max(0, x - 3):x + width + 3]
    box[:] = (box * 0.35).astype(canvas.dtype)
    cv2.putText(canvas, text, origin, FONT, scale, colour, thickness, cv2.LINE_AA)


def _to_bgr(image: np.ndarray, encoding: str) -> np.ndarray:
    if image.ndim == 2:
        if image.dtype != np.uint8:
            image = cv2.convertScaleAbs(image, alpha=255.0 / max(1, float(image.max())))
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    if encoding.startswith('rgb'):
        return cv2.cvtColor(image[:, :, :3], cv2.COLOR_RGB2BGR)
    return np.ascontiguousarray(image[:, :, :3])


def _point(value: object) -> np.ndarray:
    return np.array([value.x, value.y, value.z], dtype=float)


def object_type(record: object) -> str:
    """Return the scene's object type (the ground-truth marker's text), or '' if unknown."""
    marker = getattr(record, 'object_marker', None)
    if marker is None:
        return ''
    return marker.text or marker.ns


def error_mm(record: object) -> float | None:
    """Return |best point - ground truth| [mm], or None without both."""
    if record.best_point is None or record.ground_truth is None:
        return None
    return float(np.linalg.norm(record.best_point - record.ground_truth) * 1000)


def _zoom_window(pixels: np.ndarray, shape: Sequence[int]) -> tuple[int, int, int]:
    """Return (left, top, side) of a square around `pixels` with a margin, inside the image."""
    height, width = shape[:2]
    finite = pixels[np.all(np.isfinite(pixels), axis=1)]
    if len(finite) == 0:
        side = min(width, height) // 2
        return (width - side) // 2, (height - side) // 2, side
    low, high = finite.min(axis=0), finite.max(axis=0)
    side = int(max(80, 1.8 * float(np.max(high - low)) + 40))
    side = min(side, width, height)
    centre = (low + high) / 2
    left = int(np.clip(centre[0] - side / 2, 0, width - side))
    top = int(np.clip(centre[1] - side / 2, 0, height - side))
    return left, top, side


def _camera_and_zoom(record: object, params: dict) -> tuple[np.ndarray, np.ndarray]:
    """Return the camera panel and the zoom panel."""
    pair = record.pair
    canvas = _to_bgr(image_to_array(pair.left_image), pair.left_image.encoding)
    calibration = camera_info_to_calibration(pair.left_info)
    camera_from_world = np.linalg.inv(rig_from_params(params).world_from_left_camera())

    def to_pixels(points_world: np.ndarray) -> np.ndarray:
        camera = points_world @ camera_from_world[:3, :3].T + camera_from_world[:3, 3]
        return _project(camera, calibration.K, calibration.D)

    decision = record.decision
    border = np.zeros((0, 2))
    centres = np.zeros((0, 2))
    if decision is not None and decision.points_used > 0:
        border = to_pixels(np.array([_point(p) for p in decision.border_points]))
        centres = to_pixels(np.array([_point(p) for p in decision.area_centres]))
    marks = []  # (pixel, colour, marker)
    if record.ground_truth is not None:
        marks.append((to_pixels(record.ground_truth.reshape(1, 3))[0], WHITE, cv2.MARKER_CROSS))
    if record.best_point is not None:
        marks.append((to_pixels(record.best_point.reshape(1, 3))[0], RED,
                      cv2.MARKER_TILTED_CROSS))
    interesting = np.vstack([border, *[m[0].reshape(1, 2) for m in marks]]) if (
        len(border) or marks) else np.zeros((0, 2))
    left, top, side = _zoom_window(interesting, canvas.shape)
    scale = PANEL / side
    zoom = cv2.resize(canvas[top:top + side, left:left + side], (PANEL, PANEL),
                      interpolation=cv2.INTER_CUBIC)

    def in_zoom(pixel: np.ndarray) -> tuple[int, int]:
        return (int(round((pixel[0] - left) * scale)), int(round((pixel[1] - top) * scale)))

    if record.matches is not None:
        matches = cloud_to_matched_points(record.matches.points)
        pixels = _project(matches.xyz, calibration.K, calibration.D)
        inside = np.flatnonzero((pixels[:, 0] >= left) & (pixels[:, 0] < left + side)
                                & (pixels[:, 1] >= top) & (pixels[:, 1] < top + side))
        inside = inside[::max(1, len(inside) // 600)]
        overlay = zoom.copy()
        for index in inside:
            green = int(np.clip(matches.score[index], 0.0, 1.0) * 255)
            cv2.circle(overlay, in_zoom(pixels[index]), 2, (0, green, 255 - green), -1)
        zoom = cv2.addWeighted(overlay, 0.35, zoom, 0.65, 0.0)
    finite_border = border[np.all(np.isfinite(border), axis=1)]
    if len(finite_border):
        low, high = finite_border.min(axis=0), finite_border.max(axis=0)
        middle = (low + high) / 2
        corners = [in_zoom(low), in_zoom(high)]
        cv2.rectangle(zoom, corners[0], corners[1], CYAN, 1, cv2.LINE_AA)
        cv2.line(zoom, in_zoom(np.array([middle[0], low[1]])),
                 in_zoom(np.array([middle[0], high[1]])), CYAN, 1, cv2.LINE_AA)
        cv2.line(zoom, in_zoom(np.array([low[0], middle[1]])),
                 in_zoom(np.array([high[0], middle[1]])), CYAN, 1, cv2.LINE_AA)
        for pixel in finite_border:
            cv2.drawMarker(zoom, in_zoom(pixel), MAGENTA, cv2.MARKER_DIAMOND, 14, 2)
        for number, pixel in enumerate(centres, start=1):
            if np.all(np.isfinite(pixel)):  # an empty area has no centre
                u, v = in_zoom(pixel)
                _text(zoom, str(number), (u - 5, v + 6), 0.55, CYAN)
    for pixel, colour, marker in marks:
        if colour == WHITE:
            cv2.circle(zoom, in_zoom(pixel), 11, colour, 1, cv2.LINE_AA)
        cv2.drawMarker(zoom, in_zoom(pixel), colour, marker, 26 if colour == WHITE else 18, 2)
        cv2.drawMarker(canvas, (int(round(pixel[0])), int(round(pixel[1]))), colour, marker,
                       12, 1)
    cv2.rectangle(canvas, (left, top), (left + side - 1, top + side - 1), YELLOW, 1)
    _legend(zoom, [('ground truth', WHITE), ('best point', RED), ('border points', MAGENTA),
                   ('areas 1-4', CYAN)])
    _text(canvas, 'left camera', (8, 20))
    _text(zoom, f'zoom x{scale:.1f}', (8, 20))
    return canvas, zoom


def _legend(canvas: np.ndarray, entries: list[tuple[str, tuple[int, int, int]]]) -> None:
    y = canvas.shape[0] - 10 - 18 * (len(entries) - 1)
    for label, colour in entries:
        cv2.rectangle(canvas, (8, y - 9), (18, y + 1), colour, -1)
        _text(canvas, label, (24, y), 0.45)
        y += 18


def disparity_picture(record: object, size: tuple[int, int]) -> np.ndarray | None:
    """Return the scene's disparity image, colour-mapped (near = warm), or None."""
    message = getattr(record, 'disparity', None)
    if message is None:
        return None
    image = message.image
    if image.encoding != '32FC1' or image.height * image.width == 0:
        return None
    row = np.frombuffer(bytes(image.data), dtype='>f4' if image.is_bigendian else '<f4')
    disparity = row.reshape(image.height, image.step // 4)[:, :image.width]
    valid = np.isfinite(disparity) & (disparity >= message.min_disparity)
    picture = np.zeros((*disparity.shape, 3), np.uint8)
    if valid.any():
        low, high = float(message.min_disparity), float(message.max_disparity)
        scaled = np.clip((disparity - low) / max(high - low, 1e-6) * 255, 0, 255)
        coloured = cv2.applyColorMap(scaled.astype(np.uint8), cv2.COLORMAP_TURBO)
        picture[valid] = coloured[valid]
        # What rises above the work surface: more disparity than the row's median (in the
        # rectified image the surface's disparity changes with the row only), outlined white.
        masked = np.where(valid, disparity, np.nan)
        rows_with_data = valid.any(axis=1)
        surface = np.zeros(disparity.shape[0], np.float32)
        surface[rows_with_data] = np.nanmedian(masked[rows_with_data], axis=1)
        above = (valid & (disparity - surface[:, None] > OBJECT_RISE_PX)).astype(np.uint8)
        above = cv2.morphologyEx(above, cv2.MORPH_OPEN, np.ones((5, 5), np.uint8))
        contours, _ = cv2.findContours(above, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        cv2.drawContours(picture, [c for c in contours if cv2.contourArea(c) >= 150], -1, WHITE,
                         1, cv2.LINE_AA)
    picture = cv2.resize(picture, size, interpolation=cv2.INTER_NEAREST)
    _text(picture, f'disparity {message.min_disparity:.0f}-{message.max_disparity:.0f} px '
                   f'(rectified left; black: no match; white: > {OBJECT_RISE_PX:g} px above '
                   'the surface)', (8, 20))
    return picture


def _top_view(record: object, gantry_path: np.ndarray) -> np.ndarray:
    """Return the top view: object footprint, gantry path, best point, ground truth."""
    canvas = np.full((PANEL, PANEL, 3), 32, np.uint8)
    points = [p for p in (record.best_point, record.ground_truth) if p is not None]
    marker = getattr(record, 'object_marker', None)
    footprint = None
    if marker is not None:
        centre = _point(marker.pose.position)[:2]
        half = np.array([marker.scale.x, marker.scale.y]) / 2
        q = marker.pose.orientation
        yaw = float(np.arctan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z)))
        footprint = (centre, half, marker.type, yaw)
        points += [np.append(centre - half, 0.0), np.append(centre + half, 0.0)]
    xy = [np.asarray(p)[:2] for p in points] + list(gantry_path[:, :2])
    if not xy:
        _text(canvas, 'top view: nothing to show', (8, 20))
        return canvas
    xy_array = np.array(xy)
    low, high = xy_array.min(axis=0), xy_array.max(axis=0)
    span = float(max(np.max(high - low), 0.05)) * 1.2
    centre_xy = (low + high) / 2
    scale = (PANEL - 60) / span

    def to_canvas(point: np.ndarray) -> tuple[int, int]:  # x right, y up
        return (int(round(PANEL / 2 + (point[0] - centre_xy[0]) * scale)),
                int(round(PANEL / 2 - (point[1] - centre_xy[1]) * scale)))

    # a 1 cm grid
    step = 0.01 if span < 0.3 else 0.05
    for value in np.arange(np.floor((centre_xy[0] - span) / step) * step,
                           centre_xy[0] + span, step):
        x = to_canvas(np.array([value, centre_xy[1]]))[0]
        cv2.line(canvas, (x, 0), (x, PANEL), (48, 48, 48), 1)
    for value in np.arange(np.floor((centre_xy[1] - span) / step) * step,
                           centre_xy[1] + span, step):
        y = to_canvas(np.array([centre_xy[0], value]))[1]
        cv2.line(canvas, (0, y), (PANEL, y), (48, 48, 48), 1)
    if footprint is not None:
        centre, half, kind, yaw = footprint
        corners = np.array([[-half[0], -half[1]], [half[0], -half[1]], [half[0], half[1]],
                            [-half[0], half[1]]])
        rotation = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
        if kind == 3:  # visualization_msgs/Marker.CYLINDER
            cv2.ellipse(canvas, to_canvas(centre), (int(half[0] * scale), int(half[1] * scale)),
                        -np.degrees(yaw), 0, 360, GREY, -1, cv2.LINE_AA)
        else:
            outline = np.array([to_canvas(centre + rotation @ c) for c in corners], np.int32)
            cv2.fillPoly(canvas, [outline], GREY, cv2.LINE_AA)
    if len(gantry_path) > 1:
        path = np.array([to_canvas(p) for p in gantry_path], np.int32)
        cv2.polylines(canvas, [path], False, YELLOW, 1, cv2.LINE_AA)
    if len(gantry_path):
        cv2.circle(canvas, to_canvas(gantry_path[-1]), 6, YELLOW, 2, cv2.LINE_AA)
    if record.ground_truth is not None:
        cv2.circle(canvas, to_canvas(record.ground_truth), 9, WHITE, 1, cv2.LINE_AA)
        cv2.drawMarker(canvas, to_canvas(record.ground_truth), WHITE, cv2.MARKER_CROSS, 22, 2)
    if record.best_point is not None:
        cv2.drawMarker(canvas, to_canvas(record.best_point), RED, cv2.MARKER_TILTED_CROSS, 14,
                       2)
    _text(canvas, f'top view (world x right, y up; grid {step * 100:.0f} cm)', (8, 20))
    _legend(canvas, [('object footprint', GREY), ('gantry path, final position', YELLOW),
                     ('ground truth', WHITE), ('best point', RED)])
    return canvas


def title_text(record: object, label: str) -> str:
    """Return the picture's title: scene label, object type, error or status."""
    kind = object_type(record) or 'object (type unknown)'
    error = error_mm(record)
    decision = record.decision
    if error is not None:
        verdict = f'error {error:.1f} mm'
    elif record.best_point is not None:
        verdict = 'best point at ({:.1f}, {:.1f}, {:.1f}) mm (no ground truth)'.format(
            *(record.best_point * 1000))
    else:
        verdict = f'no best point: {decision.status if decision is not None else "no decision"}'
    selector = f' [{decision.selector}]' if decision is not None else ''
    return f'{label}: {kind}, {verdict}{selector}'


def draw_scene(record: object, params: dict, path: Path, label: str = '',
               gantry_path: np.ndarray | None = None) -> bool:
    """Write the picture of one scene record to `path` (and the disparity image beside it as
    disparity_<suffix>.png); return False when there is no image.

    Args:
        record: The scene (chain.demo_monitor.SceneRecord).
        params: The demo's parameters (the rig of fuzzy_best_point_node).
        path: Where to write the PNG.
        label: The scene's name in the title.
        gantry_path: The gantry's world positions [m] up to this scene, in order (N x 3).
    """
    if record.pair is None:
        return False
    camera, zoom = _camera_and_zoom(record, params)
    height, width = camera.shape[:2]
    disparity = disparity_picture(record, (width, height))
    if disparity is None:
        disparity = np.zeros_like(camera)
        _text(disparity, 'no disparity image received', (8, 20))
    top = _top_view(record, np.zeros((0, 3)) if gantry_path is None else gantry_path)
    right_column = [cv2.resize(panel, (PANEL, PANEL)) for panel in (zoom, top)]
    rows = [np.hstack([cv2.resize(camera, (width * PANEL // height, PANEL)), right_column[0]]),
            np.hstack([cv2.resize(disparity, (width * PANEL // height, PANEL)),
                       right_column[1]])]
    body = np.vstack(rows)
    title = np.full((TITLE_HEIGHT, body.shape[1], 3), 24, np.uint8)
    _text(title, title_text(record, label or path.stem), (10, 29), 0.7, WHITE, 2)
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), np.vstack([title, body]))
    if getattr(record, 'disparity', None) is not None:
        name = path.stem.split('_')[-1]
        cv2.imwrite(str(path.with_name(f'disparity_{name}.png')),
                    disparity_picture(record, (width, height)))
    return True
