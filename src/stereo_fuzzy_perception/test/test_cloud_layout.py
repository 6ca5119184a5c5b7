"""PointCloud2 layouts are checked in full before a byte is read (issue #15 item 8).

An x field declared FLOAT64 over float32 data, a duplicate x field, fields outside point_step,
unknown datatypes or counts, a short row_step or buffer: each is a CloudLayoutError naming the
problem, never a silently wrong point. The property test: for any field table and steps,
cloud_to_matched_points refuses with CloudLayoutError or returns the points that were packed.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

pytestmark = pytest.mark.ros


def cloud(count: int = 5):
    from std_msgs.msg import Header
    from stereo_fuzzy_perception.core.matched_points import MatchedPoints
    from stereo_fuzzy_perception.nodes.conversions import matched_points_to_cloud

    rng = np.random.default_rng(0)
    points = MatchedPoints(xyz=rng.uniform(-1, 1, (count, 3)), u_left=rng.uniform(0, 9, count),
                           v_left=rng.uniform(0, 9, count), u_right=rng.uniform(0, 9, count),
                           score=rng.uniform(0, 1, count))
    return matched_points_to_cloud(points, Header()), points


def field(name: str, offset: int, datatype: int = 7, count: int = 1):
    from sensor_msgs.msg import PointField

    return PointField(name=name, offset=offset, datatype=datatype, count=count)


def refused(message: str, change) -> None:
    from stereo_fuzzy_perception.nodes.conversions import CloudLayoutError, cloud_to_matched_points

    msg, _ = cloud()
    change(msg)
    with pytest.raises(CloudLayoutError, match=message):
        cloud_to_matched_points(msg)


def test_x_declared_float64_over_float32_data_is_an_overlap():
    refused("fields 'x' and 'y' overlap",
            lambda msg: msg.fields.__setitem__(0, field('x', 0, datatype=8)))


def test_a_duplicate_field_is_refused():
    refused('x declared twice', lambda msg: msg.fields.append(field('x', 24)))


def test_fields_outside_point_step_unknown_types_and_counts_are_refused():
    refused('does not fit point_step', lambda msg: setattr(msg, 'point_step', 20))
    refused('unknown datatype 9', lambda msg: msg.fields.__setitem__(1, field('y', 4, 9)))
    refused('count 2', lambda msg: msg.fields.__setitem__(6, field('score', 24, 7, 2)))
    refused('count 0', lambda msg: msg.fields.append(field('extra', 28, 7, 0)))
    refused('empty name', lambda msg: msg.fields.append(field('', 28)))


def test_short_steps_and_buffers_are_refused():
    refused('row_step', lambda msg: setattr(msg, 'row_step', msg.row_step - 1))
    refused('data holds', lambda msg: setattr(msg, 'data', bytes(msg.data)[:-1]))


def test_padded_rows_and_big_endian_clouds_decode_exactly():
    from stereo_fuzzy_perception.nodes.conversions import cloud_to_matched_points

    msg, points = cloud(6)
    data = np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(2, 3 * 28)
    padded = np.zeros((2, 3 * 28 + 5), dtype=np.uint8)
    padded[:, :3 * 28] = data
    msg.height, msg.width, msg.row_step, msg.data = 2, 3, 3 * 28 + 5, padded.tobytes()
    decoded = cloud_to_matched_points(msg)
    np.testing.assert_allclose(decoded.xyz, points.xyz.astype(np.float32))
    swapped = np.frombuffer(bytes(cloud(6)[0].data), dtype='<f4').astype('>f4')
    msg.height, msg.width, msg.row_step = 1, 6, 6 * 28
    msg.is_bigendian, msg.data = True, swapped.tobytes()
    np.testing.assert_allclose(cloud_to_matched_points(msg).score,
                               points.score.astype(np.float32))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.sampled_from(['x', 'y', 'z', 'u_left', 'v_left', 'u_right',
                                           'score', 'rgb']),
                          st.integers(0, 40), st.integers(0, 10), st.integers(0, 3)),
                max_size=10),
       st.integers(0, 48), st.integers(0, 3), st.integers(0, 3), st.integers(0, 200),
       st.booleans(), st.binary(max_size=400))
def test_any_layout_is_refused_or_decoded_within_the_buffer(fields, point_step, width, height,
                                                           row_step, bigendian, data):
    from sensor_msgs.msg import PointCloud2
    from stereo_fuzzy_perception.nodes.conversions import CloudLayoutError, cloud_to_matched_points

    msg = PointCloud2(height=height, width=width, point_step=point_step, row_step=row_step,
                      is_bigendian=bigendian, data=data,
                      fields=[field(*entry) for entry in fields])
    try:
        points = cloud_to_matched_points(msg)
    except CloudLayoutError as error:
        assert str(error)
        return
    assert len(points) == width * height
    names = [entry[0] for entry in fields]
    assert len(names) == len(set(names))  # a duplicate could never be accepted
