"""The correlation stage's messages: StereoPair in, StereoMatches and DisparityImage out.

A pair is size-checked before anything is decoded, then decoded into grey arrays and its
calibration; the results pack the triangulated matches (a PointCloud2), the rectified
calibration and the matcher settings.
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

import numpy as np
from sensor_msgs.msg import Image, RegionOfInterest
from std_msgs.msg import Header
from stereo_msgs.msg import DisparityImage

from stereo_fuzzy_msgs.msg import StereoMatches, StereoPair
from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.image_encoding import ImageEncodingError, to_gray, to_rgb
from stereo_fuzzy_perception.core.matched_points import MatchedPoints, RectifiedImage
from stereo_fuzzy_perception.core.matching.matcher_config import MatcherConfig
from stereo_fuzzy_perception.nodes.conversions.images import (
    ImageSizeError,
    array_to_image,
    byte_array,
    calibration_to_camera_info,
    camera_info_to_calibration,
    image_size_problem,
    image_to_array,
)
from stereo_fuzzy_perception.nodes.conversions.point_cloud import matched_points_to_cloud

if TYPE_CHECKING:  # annotations only
    from stereo_fuzzy_perception.core.matching.window_matcher import DisparityMap


def check_pair_size(pair: StereoPair, max_pixels: int) -> None:
    """Refuse a pair with an image above the size limits before anything is decoded.

    Raises:
        ImageSizeError: Naming the side, its size and the limit.
    """
    for side, image in (('left', pair.left_image), ('right', pair.right_image)):
        problem = image_size_problem(int(image.width), int(image.height), max_pixels)
        if problem:
            raise ImageSizeError(f'{side} {problem}')


def stereo_pair_to_domain(pair: StereoPair) -> tuple[np.ndarray, np.ndarray, StereoCalibration]:
    """Decode a StereoPair into grey left and right arrays and the pair's calibration.

    The calibration is not validated here (see StereoCalibration.problem()).

    Raises:
        ImageEncodingError: For an unsupported encoding or a malformed image buffer.
    """
    left, right, calibration, _ = stereo_pair_with_colour(pair)
    return left, right, calibration


def stereo_pair_with_colour(pair: StereoPair
                            ) -> tuple[np.ndarray, np.ndarray, StereoCalibration,
                                       tuple[np.ndarray | None, np.ndarray | None]]:
    """Decode a StereoPair as stereo_pair_to_domain does, with the left and right images in
    RGB too where their encoding is a colour one (None for a grey one).

    Raises:
        ImageEncodingError: For an unsupported encoding or a malformed image buffer.
    """
    raw_left = image_to_array(pair.left_image)
    raw_right = image_to_array(pair.right_image)
    left = to_gray(raw_left, pair.left_image.encoding)
    right = to_gray(raw_right, pair.right_image.encoding)
    calibration = StereoCalibration(camera_info_to_calibration(pair.left_info),
                                    camera_info_to_calibration(pair.right_info))
    return left, right, calibration, (to_rgb(raw_left, pair.left_image.encoding),
                                      to_rgb(raw_right, pair.right_image.encoding))


def stereo_matches_message(header: Header, rectified: StereoCalibration, points: MatchedPoints,
                           config: MatcherConfig, point_stride: int = 0) -> StereoMatches:
    """Pack triangulated matches, the rectified calibration and the matcher settings.

    point_stride: the points' stride (0: not said; the fuzzy stage then never matches the pair
    again, stereo_matches_matcher).
    """
    msg = StereoMatches()
    msg.header = header
    msg.left_info = calibration_to_camera_info(rectified.left, header)
    msg.right_info = calibration_to_camera_info(rectified.right, header)
    msg.points = matched_points_to_cloud(points, header)
    for side, image in (('left', points.left_image), ('right', points.right_image)):
        if image is None:
            continue
        setattr(msg, f'{side}_rectified', array_to_image(
            image.pixels, 'mono16' if image.pixels.dtype == np.uint16 else 'mono8', header))
        setattr(msg, f'{side}_rectified_roi', RegionOfInterest(
            x_offset=int(image.x), y_offset=int(image.y), width=int(image.pixels.shape[1]),
            height=int(image.pixels.shape[0])))
    for side, colour, grey in (('left', points.left_colour, points.left_image),
                               ('right', points.right_colour, points.right_image)):
        if colour is not None and grey is not None:
            setattr(msg, f'{side}_rectified_colour',
                    array_to_image(colour.pixels, 'rgb8', header))
    msg.method = config.method
    msg.window_size = int(config.window_size)
    msg.min_disparity = int(config.min_disparity)
    msg.disparity_range = int(config.disparity_range)
    msg.min_score = float(config.min_score)
    msg.texture_threshold = float(config.texture_threshold)
    msg.uniqueness_ratio = float(config.uniqueness_ratio)
    msg.lr_check_max_diff = int(config.lr_check_max_diff)
    msg.subpixel = bool(config.subpixel)
    msg.preprocess = config.preprocess
    x, y, width, height = config.roi
    msg.matched_roi = RegionOfInterest(x_offset=int(x), y_offset=int(y), width=int(width),
                                       height=int(height))
    msg.point_stride = int(point_stride)
    return msg


def stereo_matches_matcher(msg: StereoMatches) -> MatcherConfig:
    """Return the matcher settings the matches say they were produced with.

    Raises:
        MatcherConfigError: Naming the setting that is unusable (a ValueError).
    """
    roi = msg.matched_roi
    return MatcherConfig(
        method=msg.method, window_size=int(msg.window_size),
        min_disparity=int(msg.min_disparity), disparity_range=int(msg.disparity_range),
        min_score=float(msg.min_score), texture_threshold=float(msg.texture_threshold),
        uniqueness_ratio=float(msg.uniqueness_ratio),
        lr_check_max_diff=int(msg.lr_check_max_diff), subpixel=bool(msg.subpixel),
        preprocess=msg.preprocess,
        roi=(int(roi.x_offset), int(roi.y_offset), int(roi.width), int(roi.height)))


def stereo_matches_image(msg: StereoMatches, side: str = 'left') -> RectifiedImage | None:
    """Return the left (or right) rectified image that came with the matches, or None when none
    did.

    Raises:
        ImageEncodingError: An image that is not mono8 or mono16, whose buffer does not match
            its size, or whose region (left_rectified_roi, right_rectified_roi) does not give
            its size or does not lie inside the rectified image (that side's info's width and
            height).
    """
    name = f'{side}_rectified'
    image = getattr(msg, name)
    if image.width == 0 and image.height == 0 and not image.data:
        return None
    if image.encoding not in ('mono8', 'mono16'):
        raise ImageEncodingError(f'{name}: encoding {image.encoding!r}, need mono8 or '
                                 'mono16 (the matched grey image)')
    roi = getattr(msg, f'{name}_roi')
    info = getattr(msg, f'{side}_info')
    if (roi.width, roi.height) != (image.width, image.height):
        raise ImageEncodingError(
            f'{name} is {image.width}x{image.height} but {name}_roi says '
            f'{roi.width}x{roi.height}')
    if roi.x_offset + roi.width > info.width or roi.y_offset + roi.height > info.height:
        raise ImageEncodingError(
            f'{name}_roi {roi.width}x{roi.height} at ({roi.x_offset}, {roi.y_offset}) '
            f'reaches past the {info.width}x{info.height} rectified image')
    return _rectified_part(msg, name, image, roi)


def stereo_matches_colour(msg: StereoMatches, side: str = 'left') -> RectifiedImage | None:
    """Return the left (or right) rectified colour image that came with the matches, or None
    when none did (grey cameras).

    Raises:
        ImageEncodingError: An image that is not rgb8, whose buffer does not match its size,
            or that is not the size of that side's rectified_roi (the part of the image it
            shows).
    """
    name = f'{side}_rectified_colour'
    image = getattr(msg, name)
    if image.width == 0 and image.height == 0 and not image.data:
        return None
    if image.encoding != 'rgb8':
        raise ImageEncodingError(f'{name}: encoding {image.encoding!r}, need rgb8')
    roi = getattr(msg, f'{side}_rectified_roi')
    if roi.width == 0 or (roi.width, roi.height) != (image.width, image.height):
        raise ImageEncodingError(
            f'{name} is {image.width}x{image.height} but {side}_rectified_roi says '
            f'{roi.width}x{roi.height}')
    return _rectified_part(msg, name, image, roi)


def _rectified_part(msg: StereoMatches, name: str, image: Image,
                    roi: RegionOfInterest) -> RectifiedImage:
    """Return the image `name` of the matches, where `roi` places it, its pixels decoded."""
    try:
        pixels = image_to_array(image)
    except ImageEncodingError as error:
        raise ImageEncodingError(f'{name}: {error}') from None
    return RectifiedImage(pixels, int(roi.x_offset), int(roi.y_offset),
                          max(1, int(msg.window_size)))


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
    msg.image.data = byte_array(image)
    msg.f = float(rectified.left.P[0, 0])
    msg.t = float(rectified.baseline_m)
    x, y, width, height = disparity_map.roi
    msg.valid_window = RegionOfInterest(x_offset=x, y_offset=y, width=width, height=height)
    msg.min_disparity = low
    msg.max_disparity = float(config.max_disparity) - shift
    msg.delta_d = 1.0 / 16.0 if config.subpixel else 1.0
    return msg

