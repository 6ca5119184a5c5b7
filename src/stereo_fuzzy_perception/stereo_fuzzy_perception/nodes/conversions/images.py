"""sensor_msgs/Image and CameraInfo <-> numpy arrays and CameraCalibration; header stamps.

What cv_bridge does for images (any encoding of image_encoding.SUPPORTED_ENCODINGS, padded rows,
either byte order), the image size limits a node enforces before decoding, and the camera model
a CameraInfo carries (K, D, R, P, binning, ROI).
"""

from __future__ import annotations

import array as array_module

import numpy as np
from builtin_interfaces.msg import Time
from sensor_msgs.msg import CameraInfo, Image, RegionOfInterest
from std_msgs.msg import Header

from stereo_fuzzy_perception.core.camera_model import MAX_IMAGE_SIDE, CameraCalibration
from stereo_fuzzy_perception.core.image_encoding import (
    SUPPORTED_ENCODINGS,
    ImageEncodingError,
    check_encoding,
)


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


def stamp_to_ns(stamp: Time) -> int:
    """Convert a builtin_interfaces/Time to integer nanoseconds [ns]."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def byte_array(array: np.ndarray) -> array_module.array:
    """Return a C-contiguous array's bytes as the array.array('B') a uint8[] field holds."""
    data = array_module.array('B')
    data.frombytes(np.ascontiguousarray(array).reshape(-1).view(np.uint8))
    return data


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

