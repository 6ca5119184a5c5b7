"""Message <-> domain conversions round-trip and reject malformed messages clearly."""

import numpy as np
import pytest

pytestmark = pytest.mark.ros


def test_image_round_trip_for_every_supported_encoding():
    from stereo_fuzzy_perception.core.image_encoding import SUPPORTED_ENCODINGS
    from stereo_fuzzy_perception.nodes.conversions import array_to_image, image_to_array

    rng = np.random.default_rng(1)
    for encoding, (dtype, channels) in SUPPORTED_ENCODINGS.items():
        shape = (5, 7) if channels == 1 else (5, 7, channels)
        array = rng.integers(0, np.iinfo(dtype).max, size=shape, dtype=dtype)
        assert np.array_equal(image_to_array(array_to_image(array, encoding)), array), encoding


def test_image_with_padded_rows_and_big_endian_mono16_decodes():
    from sensor_msgs.msg import Image
    from stereo_fuzzy_perception.nodes.conversions import image_to_array

    values = np.arange(6, dtype='>u2').reshape(2, 3)
    padded = np.zeros((2, 8), dtype=np.uint8)
    padded[:, :6] = values.view(np.uint8).reshape(2, 6)
    msg = Image(height=2, width=3, encoding='mono16', is_bigendian=1, step=8,
                data=padded.tobytes())
    assert np.array_equal(image_to_array(msg), values.astype(np.uint16))


def test_unsupported_encoding_and_short_buffer_are_named():
    from sensor_msgs.msg import Image
    from stereo_fuzzy_perception.core.image_encoding import ImageEncodingError
    from stereo_fuzzy_perception.nodes.conversions import image_to_array

    with pytest.raises(ImageEncodingError, match='yuv422'):
        image_to_array(Image(height=2, width=2, encoding='yuv422', step=4, data=b'\0' * 8))
    with pytest.raises(ImageEncodingError, match='data holds 3 bytes'):
        image_to_array(Image(height=2, width=2, encoding='mono8', step=2, data=b'\0' * 3))


def test_matched_points_round_trip_through_point_cloud():
    from std_msgs.msg import Header
    from stereo_fuzzy_perception.core.matched_points import MatchedPoints
    from stereo_fuzzy_perception.nodes.conversions import (
        cloud_to_matched_points,
        matched_points_to_cloud,
    )

    rng = np.random.default_rng(2)
    points = MatchedPoints(rng.normal(size=(10, 3)), rng.uniform(0, 640, 10),
                           rng.uniform(0, 480, 10), rng.uniform(0, 640, 10),
                           rng.uniform(-1, 1, 10))
    back = cloud_to_matched_points(matched_points_to_cloud(points, Header(frame_id='left')))
    for name in ('xyz', 'u_left', 'v_left', 'u_right', 'score'):
        assert np.allclose(getattr(back, name), getattr(points, name), atol=1e-4), name


def test_camera_info_round_trip():
    from stereo_fuzzy_perception.core.camera_model import CameraCalibration
    from stereo_fuzzy_perception.nodes.conversions import (
        calibration_to_camera_info,
        camera_info_to_calibration,
    )

    calibration = CameraCalibration(
        640, 480, np.array([[500.0, 0, 320], [0, 500, 239], [0, 0, 1]]),
        np.array([0.1, -0.05, 0, 0, 0]), np.eye(3),
        np.array([[500.0, 0, 320, -30], [0, 500, 239, 0], [0, 0, 1, 0]]), frame_id='right')
    assert camera_info_to_calibration(calibration_to_camera_info(calibration)).same_as(
        calibration)


def _matches_with_image(pixels, x, y, right=None):
    from std_msgs.msg import Header
    from stereo_fuzzy_perception.core.camera_model import StereoCalibration
    from stereo_fuzzy_perception.core.matched_points import MatchedPoints, RectifiedImage
    from stereo_fuzzy_perception.core.matching.window_matcher import MatcherConfig
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig
    from stereo_fuzzy_perception.nodes.conversions import stereo_matches_message
    from stereo_fuzzy_perception.simulation.synthetic_scenes import rectified_calibration

    points = MatchedPoints.empty()
    points.left_image = RectifiedImage(pixels, x, y, 11)
    if right is not None:
        points.right_image = RectifiedImage(right, x + 1, y, 11)
    calibration = StereoCalibration(*rectified_calibration(StereoRig(), width=64, height=48))
    return stereo_matches_message(Header(frame_id='left'), calibration, points,
                                  MatcherConfig(window_size=11))


@pytest.mark.parametrize('dtype', [np.uint8, np.uint16])
def test_the_rectified_image_travels_with_the_matches(dtype):
    from stereo_fuzzy_perception.nodes.conversions import stereo_matches_image

    pixels = np.random.default_rng(3).integers(0, np.iinfo(dtype).max, (20, 30), dtype=dtype)
    image = stereo_matches_image(_matches_with_image(pixels, 5, 7))
    assert image is not None
    np.testing.assert_array_equal(image.pixels, pixels)
    assert (image.x, image.y, image.window_size) == (5, 7, 11)


def test_the_right_rectified_image_travels_with_the_matches_too():
    from stereo_fuzzy_perception.nodes.conversions import stereo_matches_image

    rng = np.random.default_rng(4)
    left, right = (rng.integers(0, 255, (20, 30), dtype=np.uint8) for _ in range(2))
    msg = _matches_with_image(left, 5, 7, right)
    image = stereo_matches_image(msg, 'right')
    assert image is not None
    np.testing.assert_array_equal(image.pixels, right)
    assert (image.x, image.y, image.window_size) == (6, 7, 11)
    assert stereo_matches_image(_matches_with_image(left, 5, 7), 'right') is None


def test_the_matcher_settings_and_point_stride_travel_with_the_matches():
    from std_msgs.msg import Header
    from stereo_fuzzy_perception.core.camera_model import StereoCalibration
    from stereo_fuzzy_perception.core.matched_points import MatchedPoints
    from stereo_fuzzy_perception.core.matching.window_matcher import MatcherConfig
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig
    from stereo_fuzzy_perception.nodes.conversions import (
        stereo_matches_matcher,
        stereo_matches_message,
    )
    from stereo_fuzzy_perception.simulation.synthetic_scenes import rectified_calibration

    config = MatcherConfig(method='plain', window_size=11, min_disparity=7, disparity_range=40,
                           min_score=0.35, texture_threshold=1.25, uniqueness_ratio=0.1,
                           lr_check_max_diff=2, subpixel=False, preprocess='edges',
                           roi=(3, 4, 50, 30))
    calibration = StereoCalibration(*rectified_calibration(StereoRig(), width=64, height=48))
    msg = stereo_matches_message(Header(frame_id='left'), calibration, MatchedPoints.empty(),
                                 config, point_stride=3)
    assert msg.point_stride == 3
    assert stereo_matches_matcher(msg) == config
    msg.window_size = 4
    with pytest.raises(ValueError, match='window_size 4 must be odd'):
        stereo_matches_matcher(msg)


def test_a_malformed_right_image_is_named_as_the_right_one():
    from stereo_fuzzy_perception.core.image_encoding import ImageEncodingError
    from stereo_fuzzy_perception.nodes.conversions import stereo_matches_image

    pixels = np.zeros((20, 30), dtype=np.uint8)
    msg = _matches_with_image(pixels, 0, 0, pixels)
    msg.right_rectified_roi.width = 29
    with pytest.raises(ImageEncodingError, match='right_rectified is 30x20 but .* 29x20'):
        stereo_matches_image(msg, 'right')
    assert stereo_matches_image(msg) is not None, 'the left image is still fine'


def test_matches_without_an_image_have_none():
    from stereo_fuzzy_perception.nodes.conversions import stereo_matches_image

    from stereo_fuzzy_msgs.msg import StereoMatches

    assert stereo_matches_image(StereoMatches()) is None


def test_a_malformed_rectified_image_is_named():
    from sensor_msgs.msg import Image
    from stereo_fuzzy_perception.core.image_encoding import ImageEncodingError
    from stereo_fuzzy_perception.nodes.conversions import stereo_matches_image

    pixels = np.zeros((20, 30), dtype=np.uint8)
    colour = _matches_with_image(pixels, 0, 0)
    colour.left_rectified = Image(height=2, width=2, encoding='rgb8', step=6, data=b'\0' * 12)
    with pytest.raises(ImageEncodingError, match="encoding 'rgb8', need mono8 or mono16"):
        stereo_matches_image(colour)
    resized = _matches_with_image(pixels, 0, 0)
    resized.left_rectified_roi.width = 29
    with pytest.raises(ImageEncodingError, match='left_rectified is 30x20 but .* 29x20'):
        stereo_matches_image(resized)
    outside = _matches_with_image(pixels, 40, 0)  # 40 + 30 > 64
    with pytest.raises(ImageEncodingError, match='reaches past the 64x48 rectified image'):
        stereo_matches_image(outside)
    short = _matches_with_image(pixels, 0, 0)
    short.left_rectified.data = short.left_rectified.data[:100]
    with pytest.raises(ImageEncodingError, match='left_rectified: data holds 100 bytes'):
        stereo_matches_image(short)


def _matches_with_colour(colour, x, y):
    from std_msgs.msg import Header
    from stereo_fuzzy_perception.core.camera_model import StereoCalibration
    from stereo_fuzzy_perception.core.matched_points import MatchedPoints, RectifiedImage
    from stereo_fuzzy_perception.core.matching.window_matcher import MatcherConfig
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig
    from stereo_fuzzy_perception.nodes.conversions import stereo_matches_message
    from stereo_fuzzy_perception.simulation.synthetic_scenes import rectified_calibration

    points = MatchedPoints.empty()
    points.left_image = RectifiedImage(colour[..., 1].copy(), x, y, 11)
    points.left_colour = RectifiedImage(colour, x, y, 11)
    calibration = StereoCalibration(*rectified_calibration(StereoRig(), width=64, height=48))
    return stereo_matches_message(Header(frame_id='left'), calibration, points,
                                  MatcherConfig(window_size=11))


def test_the_left_colour_image_travels_with_the_matches():
    from stereo_fuzzy_perception.nodes.conversions import stereo_matches_colour

    colour = np.random.default_rng(5).integers(0, 255, (20, 30, 3), dtype=np.uint8)
    msg = _matches_with_colour(colour, 5, 7)
    assert msg.left_rectified_colour.encoding == 'rgb8'
    image = stereo_matches_colour(msg)
    assert image is not None
    np.testing.assert_array_equal(image.pixels, colour)
    assert (image.x, image.y) == (5, 7)
    assert stereo_matches_colour(_matches_with_image(colour[..., 0].copy(), 5, 7)) is None


@pytest.mark.parametrize('spoil, message', [
    (lambda msg: setattr(msg.left_rectified_colour, 'encoding', 'bgr8'),
     "left_rectified_colour: encoding 'bgr8', need rgb8"),
    (lambda msg: setattr(msg.left_rectified_roi, 'width', 29),
     'left_rectified_colour is 30x20 but left_rectified_roi says 29x20'),
    (lambda msg: setattr(msg.left_rectified_colour, 'data', b'\0' * 10),
     'left_rectified_colour: '),
])
def test_a_malformed_colour_image_is_named(spoil, message):
    from stereo_fuzzy_perception.core.image_encoding import ImageEncodingError
    from stereo_fuzzy_perception.nodes.conversions import stereo_matches_colour

    msg = _matches_with_colour(np.zeros((20, 30, 3), dtype=np.uint8), 0, 0)
    spoil(msg)
    with pytest.raises(ImageEncodingError, match=message):
        stereo_matches_colour(msg)


@pytest.mark.parametrize('encoding, order', [('rgb8', (0, 1, 2)), ('bgr8', (2, 1, 0)),
                                             ('8UC3', (2, 1, 0)), ('rgba8', (0, 1, 2)),
                                             ('bgra8', (2, 1, 0))])
def test_colour_encodings_come_out_as_rgb(encoding, order):
    from stereo_fuzzy_perception.core.image_encoding import to_rgb

    channels = 4 if encoding.endswith('a8') else 3
    image = np.zeros((2, 3, channels), dtype=np.uint8)
    for channel, value in enumerate((10, 20, 30)):
        image[..., channel] = value
    rgb = to_rgb(image, encoding)
    assert rgb is not None and rgb.shape == (2, 3, 3)
    assert tuple(int(rgb[0, 0, k]) for k in range(3)) == tuple((10, 20, 30)[k] for k in order)


def test_grey_encodings_have_no_colour():
    from stereo_fuzzy_perception.core.image_encoding import to_rgb

    assert to_rgb(np.zeros((2, 3), dtype=np.uint8), 'mono8') is None
    assert to_rgb(np.zeros((2, 3), dtype=np.uint16), 'mono16') is None
