"""MatchedPoints <-> sensor_msgs/PointCloud2: packing the matches, and checking a cloud's layout.

A cloud is checked (fields, steps, buffer) before any byte of it is read, so a malformed message
is refused with a reason instead of reading past its data.
"""

from __future__ import annotations

import sys

import numpy as np
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Header

from stereo_fuzzy_perception.core.matched_points import MatchedPoints
from stereo_fuzzy_perception.nodes.conversions.images import byte_array

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
    cloud.data = byte_array(rows)
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

