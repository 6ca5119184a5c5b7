"""The one module that converts between ROS messages and this package's domain types.

Images <-> numpy arrays (what cv_bridge does), CameraInfo <-> CameraCalibration,
MatchedPoints <-> PointCloud2, the fuzzy stage's BestPointDecision -> FuzzyDecision /
PointStamped / MarkerArray, and rig_pose.Transform <-> TransformStamped / TFMessage.
Everything else in the package works on domain types.
"""

from __future__ import annotations

import array as array_module
import sys
from typing import TYPE_CHECKING

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, PointStamped, TransformStamped, Vector3
from sensor_msgs.msg import CameraInfo, Image, PointCloud2, PointField, RegionOfInterest
from std_msgs.msg import Header
from stereo_msgs.msg import DisparityImage
from visualization_msgs.msg import Marker, MarkerArray

from stereo_fuzzy_msgs.msg import FuzzyDecision, StereoMatches, StereoPair
from stereo_fuzzy_perception.core.camera_model import (
    MAX_IMAGE_SIDE,
    CameraCalibration,
    StereoCalibration,
)
from stereo_fuzzy_perception.core.image_encoding import (
    SUPPORTED_ENCODINGS,
    ImageEncodingError,
    check_encoding,
    to_gray,
)
from stereo_fuzzy_perception.core.matched_points import MatchedPoints
from stereo_fuzzy_perception.core.rig_pose import Transform
from tf2_msgs.msg import TFMessage

if TYPE_CHECKING:  # annotations only: nodes that never decide need not import scipy
    from stereo_fuzzy_perception.core.best_point.point_selectors import BestPointDecision
    from stereo_fuzzy_perception.core.matching.window_matcher import DisparityMap, MatcherConfig

# --- images ----------------------------------------------------------------------------------


def image_to_array(msg: Image) -> np.ndarray:
    """Decode a sensor_msgs/Image into an HxW or HxWxC array (a copy, native byte order).

    Raises:
        ImageEncodingError: For an unsupported encoding or a buffer that does not match
            width, height and step.
    """
    check_image_layout(msg)
    dtype, channels = SUPPORTED_ENCODINGS[msg.encoding]
    row_bytes = msg.width * channels * dtype.itemsize
    buffer = np.frombuffer(bytes(msg.data), dtype=np.uint8, count=msg.step * msg.height)
    rows = buffer.reshape(msg.height, msg.step)[:, :row_bytes]
    byte_order = '>' if msg.is_bigendian else '<'
    array = rows.copy().view(dtype.newbyteorder(byte_order) if dtype.itemsize > 1 else dtype)
    array = array.astype(dtype, copy=False)
    return array.reshape(msg.height, msg.width) if channels == 1 else array.reshape(
        msg.height, msg.width, channels)


def array_to_image(array: np.ndarray, encoding: str, header: Header | None = None) -> Image:
    """Encode an array as a sensor_msgs/Image of `encoding` (dense rows, little-endian)."""
    check_encoding(encoding)
    dtype, channels = SUPPORTED_ENCODINGS[encoding]
    expected_ndim = 2 if channels == 1 else 3
    if array.ndim != expected_ndim or (channels > 1 and array.shape[2] != channels):
        raise ImageEncodingError(f'array of shape {array.shape} does not fit {encoding}')
    contiguous = np.ascontiguousarray(array, dtype=dtype)
    msg = Image()
    if header is not None:
        msg.header = header
    msg.height, msg.width = int(contiguous.shape[0]), int(contiguous.shape[1])
    msg.encoding = encoding
    msg.is_bigendian = 0
    msg.step = int(msg.width * channels * dtype.itemsize)
    msg.data = contiguous.tobytes()
    return msg


def check_image_layout(msg: Image) -> None:
    """Check what image_to_array checks (encoding, size, step, buffer) without decoding.

    Raises:
        ImageEncodingError: For an unsupported encoding, an empty image, a step shorter than
            a row, or data shorter than step * height.
    """
    check_encoding(msg.encoding)
    dtype, channels = SUPPORTED_ENCODINGS[msg.encoding]
    row_bytes = msg.width * channels * dtype.itemsize
    if msg.width == 0 or msg.height == 0:
        raise ImageEncodingError(f'image is empty ({msg.width}x{msg.height})')
    if msg.step < row_bytes:
        raise ImageEncodingError(
            f'step {msg.step} is shorter than a row of {msg.width} {msg.encoding} pixels '
            f'({row_bytes} bytes)')
    if len(msg.data) < msg.step * msg.height:
        raise ImageEncodingError(
            f'data holds {len(msg.data)} bytes, expected step*height = {msg.step * msg.height}')


class ImageSizeError(ImageEncodingError):
    """An image larger than the node accepts (max_image_pixels, or a side OpenCV cannot remap)."""


def image_size_problem(width: int, height: int, max_pixels: int) -> str | None:
    """Return why a width x height image is too large to process, or None.

    Args:
        width: Image width [px].
        height: Image height [px].
        max_pixels: Most pixels accepted per image (the node's max_image_pixels).
    """
    if width > MAX_IMAGE_SIDE or height > MAX_IMAGE_SIDE:
        return (f'image is {width}x{height}: a side above {MAX_IMAGE_SIDE} px cannot be '
                'rectified (OpenCV remap)')
    if width * height > max_pixels:
        return (f'image is {width}x{height} = {width * height} pixels, more than '
                f'max_image_pixels {max_pixels}')
    return None


def check_pair_size(pair: StereoPair, max_pixels: int) -> None:
    """Refuse a pair with an image above the size limits before anything is decoded.

    Raises:
        ImageSizeError: Naming the side, its size and the limit.
    """
    for side, image in (('left', pair.left_image), ('right', pair.right_image)):
        problem = image_size_problem(int(image.width), int(image.height), max_pixels)
        if problem:
            raise ImageSizeError(f'{side} {problem}')


def stamp_to_ns(stamp: Time) -> int:
    """Convert a builtin_interfaces/Time to integer nanoseconds [ns]."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


# --- camera calibration ----------------------------------------------------------------------


def camera_info_to_calibration(msg: CameraInfo) -> CameraCalibration:
    """Read K, D, R, P and the image size of a CameraInfo (not validated: see .problem())."""
    return CameraCalibration(
        width=int(msg.width),
        height=int(msg.height),
        K=np.array(msg.k, dtype=float).reshape(3, 3),
        D=np.array(msg.d, dtype=float),
        R=np.array(msg.r, dtype=float).reshape(3, 3),
        P=np.array(msg.p, dtype=float).reshape(3, 4),
        distortion_model=msg.distortion_model or 'plumb_bob',
        frame_id=msg.header.frame_id,
        binning_x=int(msg.binning_x),
        binning_y=int(msg.binning_y),
        roi=(int(msg.roi.x_offset), int(msg.roi.y_offset), int(msg.roi.width),
             int(msg.roi.height)),
    )


def calibration_to_camera_info(calibration: CameraCalibration,
                               header: Header | None = None) -> CameraInfo:
    """Write a CameraCalibration into a CameraInfo (binning and ROI as it holds them)."""
    msg = CameraInfo()
    if header is not None:
        msg.header = header
    else:
        msg.header.frame_id = calibration.frame_id
    msg.width, msg.height = int(calibration.width), int(calibration.height)
    msg.distortion_model = calibration.distortion_model
    msg.d = [float(value) for value in np.asarray(calibration.D).ravel()]
    msg.k = [float(value) for value in np.asarray(calibration.K).ravel()]
    msg.r = [float(value) for value in np.asarray(calibration.R).ravel()]
    msg.p = [float(value) for value in np.asarray(calibration.P).ravel()]
    msg.binning_x, msg.binning_y = int(calibration.binning_x), int(calibration.binning_y)
    x, y, width, height = (int(value) for value in calibration.roi)
    msg.roi = RegionOfInterest(x_offset=x, y_offset=y, width=width, height=height)
    return msg


# --- matched points --------------------------------------------------------------------------

MATCH_FIELDS = ('x', 'y', 'z', 'u_left', 'v_left', 'u_right', 'score')
_FLOAT32_POINT = np.dtype([(name, '<f4') for name in MATCH_FIELDS])


def matched_points_to_cloud(points: MatchedPoints, header: Header) -> PointCloud2:
    """Pack matched points into an unordered PointCloud2 with float32 fields MATCH_FIELDS.

    Points from triangulation.triangulate are already the cloud's rows: their bytes are copied
    once into the message. Other points are interleaved first, column by column.
    """
    rows = _point_rows(points)
    if rows is None:
        rows = np.empty(len(points), dtype=_FLOAT32_POINT)
        rows['x'], rows['y'], rows['z'] = points.xyz[:, 0], points.xyz[:, 1], points.xyz[:, 2]
        rows['u_left'], rows['v_left'] = points.u_left, points.v_left
        rows['u_right'], rows['score'] = points.u_right, points.score
    # check_fields: the data setter then keeps the array.array it is given instead of copying it
    cloud = PointCloud2(check_fields=True)
    cloud.header = header
    cloud.height, cloud.width = 1, len(points)
    cloud.fields = [
        PointField(name=name, offset=4 * index, datatype=PointField.FLOAT32, count=1)
        for index, name in enumerate(MATCH_FIELDS)
    ]
    cloud.is_bigendian = False
    cloud.point_step = _FLOAT32_POINT.itemsize
    cloud.row_step = cloud.point_step * len(points)
    cloud.is_dense = True
    cloud.data = _byte_array(rows)
    return cloud


def _point_rows(points: MatchedPoints) -> np.ndarray | None:
    """Return the (N, 7) float32 rows the points' columns are views of, in MATCH_FIELDS order
    (little-endian), or None when they are not laid out so."""
    block = points.xyz.base
    count = len(points)
    if (sys.byteorder != 'little' or not isinstance(block, np.ndarray)
            or block.dtype != np.float32 or block.ndim != 2
            or block.shape[1] != len(MATCH_FIELDS) or not block.flags.c_contiguous
            or block.shape[0] < count or points.xyz.shape != (count, 3)):
        return None
    start = block.ctypes.data
    columns = (points.xyz, points.u_left, points.v_left, points.u_right, points.score)
    for column, offset in zip(columns, (0, 12, 16, 20, 24), strict=True):
        if (column.base is not block or column.dtype != np.float32
                or column.strides[0] != block.strides[0] or column.shape[0] != count
                or column.ctypes.data != start + offset):
            return None
    rows: np.ndarray = block[:count]
    return rows


def _byte_array(array: np.ndarray) -> array_module.array:
    """Return a C-contiguous array's bytes as the array.array('B') a uint8[] field holds."""
    data = array_module.array('B')
    data.frombytes(np.ascontiguousarray(array).reshape(-1).view(np.uint8))
    return data


_POINT_FIELD_TYPES = {
    PointField.INT8: 'i1', PointField.UINT8: 'u1', PointField.INT16: 'i2',
    PointField.UINT16: 'u2', PointField.INT32: 'i4', PointField.UINT32: 'u4',
    PointField.FLOAT32: 'f4', PointField.FLOAT64: 'f8',
}


class CloudLayoutError(ValueError):
    """A PointCloud2 whose fields, steps or buffer do not describe a consistent layout."""


def check_cloud_layout(cloud: PointCloud2) -> None:
    """Check that a PointCloud2's layout is consistent before any byte of it is read.

    Every field has a unique, non-empty name, a known datatype and a count of at least 1, lies
    inside point_step and overlaps no other field; is_bigendian is 0 or 1; row_step holds a
    row of width points, and data holds height rows. The fields MATCH_FIELDS must be present
    as single values.

    Raises:
        CloudLayoutError: Naming the first inconsistency found.
    """
    names = [field.name for field in cloud.fields]
    duplicates = sorted({name for name in names if names.count(name) > 1})
    if duplicates:
        raise CloudLayoutError(f'point cloud field(s) {", ".join(duplicates)} declared twice')
    missing = [name for name in MATCH_FIELDS if name not in names]
    if missing:
        raise CloudLayoutError(f'point cloud lacks field(s) {", ".join(missing)}; has '
                               f'{", ".join(names) or "none"}')
    if cloud.is_bigendian not in (0, 1, False, True):
        raise CloudLayoutError(f'is_bigendian {cloud.is_bigendian!r} is not a boolean')
    point_step = int(cloud.point_step)
    spans = []
    for field in cloud.fields:
        if not field.name:
            raise CloudLayoutError('a point cloud field has an empty name')
        if field.datatype not in _POINT_FIELD_TYPES:
            raise CloudLayoutError(f'field {field.name!r} has unknown datatype '
                                   f'{field.datatype} (1..8 are defined)')
        if field.count < 1 or (field.name in MATCH_FIELDS and field.count != 1):
            raise CloudLayoutError(f'field {field.name!r} has count {field.count}; expected '
                                   f'{1 if field.name in MATCH_FIELDS else "at least 1"}')
        size = np.dtype(_POINT_FIELD_TYPES[field.datatype]).itemsize * int(field.count)
        end = int(field.offset) + size
        if end > point_step:
            raise CloudLayoutError(f'field {field.name!r} (bytes {field.offset}..{end - 1}) does '
                                   f'not fit point_step {point_step}')
        spans.append((int(field.offset), end, field.name))
    spans.sort()
    for (_, first_end, first), (second_start, _, second) in zip(spans, spans[1:], strict=False):
        if second_start < first_end:
            raise CloudLayoutError(f'fields {first!r} and {second!r} overlap')
    width, height = int(cloud.width), int(cloud.height)
    if width * height == 0:
        return
    if int(cloud.row_step) < width * point_step:
        raise CloudLayoutError(f'row_step {cloud.row_step} is shorter than a row of {width} '
                               f'points of {point_step} bytes')
    if len(cloud.data) < height * int(cloud.row_step):
        raise CloudLayoutError(f'point cloud data holds {len(cloud.data)} bytes, expected '
                               f'height*row_step = {height * int(cloud.row_step)}')


def cloud_to_matched_points(cloud: PointCloud2) -> MatchedPoints:
    """Unpack a PointCloud2 with fields MATCH_FIELDS (any order, offsets or numeric types).

    The layout is checked first (check_cloud_layout); rows may be padded (row_step).

    Raises:
        CloudLayoutError: When the layout is inconsistent (see check_cloud_layout).
    """
    check_cloud_layout(cloud)
    width, height = int(cloud.width), int(cloud.height)
    if width * height == 0:
        return MatchedPoints.empty()
    fields = {field.name: field for field in cloud.fields}
    byte_order = '>' if cloud.is_bigendian else '<'
    dtype = np.dtype({
        'names': list(MATCH_FIELDS),
        'formats': [byte_order + _POINT_FIELD_TYPES[fields[name].datatype]
                    for name in MATCH_FIELDS],
        'offsets': [int(fields[name].offset) for name in MATCH_FIELDS],
        'itemsize': int(cloud.point_step),
    })
    row_step = int(cloud.row_step)
    buffer = np.frombuffer(bytes(cloud.data), dtype=np.uint8, count=height * row_step)
    rows = buffer.reshape(height, row_step)[:, :width * dtype.itemsize]
    records = np.ascontiguousarray(rows).view(dtype).reshape(-1)
    column = {name: records[name].astype(np.float64) for name in MATCH_FIELDS}
    return MatchedPoints(
        xyz=np.stack([column['x'], column['y'], column['z']], axis=1),
        u_left=column['u_left'], v_left=column['v_left'], u_right=column['u_right'],
        score=column['score'])


# --- fuzzy best-point decisions --------------------------------------------------------------


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


# --- correlation stage -----------------------------------------------------------------------


def stereo_pair_to_domain(pair: StereoPair) -> tuple[np.ndarray, np.ndarray, StereoCalibration]:
    """Decode a StereoPair into grey left and right arrays and the pair's calibration.

    The calibration is not validated here (see StereoCalibration.problem()).

    Raises:
        ImageEncodingError: For an unsupported encoding or a malformed image buffer.
    """
    left = to_gray(image_to_array(pair.left_image), pair.left_image.encoding)
    right = to_gray(image_to_array(pair.right_image), pair.right_image.encoding)
    calibration = StereoCalibration(camera_info_to_calibration(pair.left_info),
                                    camera_info_to_calibration(pair.right_info))
    return left, right, calibration


def stereo_matches_message(header: Header, rectified: StereoCalibration, points: MatchedPoints,
                           config: MatcherConfig) -> StereoMatches:
    """Pack triangulated matches, the rectified calibration and the matcher settings."""
    msg = StereoMatches()
    msg.header = header
    msg.left_info = calibration_to_camera_info(rectified.left, header)
    msg.right_info = calibration_to_camera_info(rectified.right, header)
    msg.points = matched_points_to_cloud(points, header)
    msg.method = config.method
    msg.window_size = int(config.window_size)
    msg.min_disparity = int(config.min_disparity)
    msg.disparity_range = int(config.disparity_range)
    return msg


def disparity_image_message(disparity_map: DisparityMap, rectified: StereoCalibration,
                            header: Header) -> DisparityImage:
    """Pack a disparity map as stereo_msgs/DisparityImage (32FC1), as stereo_image_proc does.

    Disparities are shifted by the principal-point difference, d - (cx_l - cx_r), as the message
    defines them; invalid pixels get min_disparity - 1 (below the searched range).
    """
    shift = float(rectified.left.P[0, 2] - rectified.right.P[0, 2])
    config = disparity_map.config
    low = float(config.min_disparity) - shift
    image = disparity_map.disparity - np.float32(shift)
    image[~np.isfinite(image)] = low - 1.0
    msg = DisparityImage()
    msg.header = header
    msg.image = Image(header=header, height=image.shape[0], width=image.shape[1],
                      encoding='32FC1', is_bigendian=int(sys.byteorder == 'big'),
                      step=4 * image.shape[1], check_fields=True)
    msg.image.data = _byte_array(image)
    msg.f = float(rectified.left.P[0, 0])
    msg.t = float(rectified.baseline_m)
    x, y, width, height = disparity_map.roi
    msg.valid_window = RegionOfInterest(x_offset=x, y_offset=y, width=width, height=height)
    msg.min_disparity = low
    msg.max_disparity = float(config.max_disparity) - shift
    msg.delta_d = 1.0 / 16.0 if config.subpixel else 1.0
    return msg


# --- transforms (tf2_msgs/TFMessage on /tf and /tf_static) ------------------------------------


def transform_to_message(transform: Transform, stamp: Time) -> TransformStamped:
    """Return a geometry_msgs/TransformStamped (parent frame in the header) of `transform`."""
    msg = TransformStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = transform.frame_id
    msg.child_frame_id = transform.child_frame_id
    msg.transform.translation.x, msg.transform.translation.y, msg.transform.translation.z = (
        float(value) for value in transform.translation)
    rotation = msg.transform.rotation
    rotation.x, rotation.y, rotation.z, rotation.w = (float(value)
                                                      for value in transform.rotation)
    return msg


def transforms_to_tf_message(transforms: list[Transform], stamp: Time) -> TFMessage:
    """Return a tf2_msgs/TFMessage holding `transforms`, all stamped `stamp`."""
    return TFMessage(transforms=[transform_to_message(t, stamp) for t in transforms])


def transform_from_message(msg: TransformStamped) -> Transform:
    """Return the Transform of a TransformStamped (not validated: see Transform.problem())."""
    translation, rotation = msg.transform.translation, msg.transform.rotation
    return Transform(msg.header.frame_id, msg.child_frame_id,
                     (float(translation.x), float(translation.y), float(translation.z)),
                     (float(rotation.x), float(rotation.y), float(rotation.z),
                      float(rotation.w)))


def tf_message_to_transforms(msg: TFMessage) -> list[Transform]:
    """Return the usable transforms of a TFMessage; those with a problem() are left out."""
    transforms = [transform_from_message(item) for item in msg.transforms]
    return [transform for transform in transforms if transform.problem() is None]


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
