"""A pair matched again at another point stride, from the rectified parts its matches carry.

At the demo's point_stride 3 a top face holds only a ninth of the matches it holds at stride 1,
and a small printed or low-texture top can be left with fewer than min_points of them although
the same pair at stride 1 gives its point. The fuzzy stage has what it needs to match
such a pair again, without the raw images: the parts of both rectified images the matcher read
(StereoMatches' left_rectified and right_rectified), the rectified calibration and the matcher's
settings. Matched with the same settings over the same region, the pair's stride-1 matches are
those correlation_node would have published at stride 1 (the matcher decides each row alone).
ROS-free: numpy and the matcher's C kernel.
"""

from __future__ import annotations

import numpy as np

from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.matched_points import MatchedPoints, RectifiedImage
from stereo_fuzzy_perception.core.matching.matcher_config import MatcherInputError
from stereo_fuzzy_perception.core.matching.triangulation import triangulate
from stereo_fuzzy_perception.core.matching.window_matcher import MatcherConfig, match


def matched_again(points: MatchedPoints, rectified: StereoCalibration, config: MatcherConfig,
                  stride: int = 1, threads: int | None = None) -> MatchedPoints | None:
    """Return the pair's matches at `stride`, matched again from the rectified parts.

    Args:
        points: Matches that carry the parts of the left and right rectified images the
            matcher read (left_image, right_image).
        rectified: Calibration of the rectified images (their size, K, R and P).
        config: The matcher settings the points were produced with (its roi included).
        stride: Point stride of the result (every stride-th row and column).
        threads: The matcher's threads; window_matcher.default_threads() when None.

    Returns:
        The matches at `stride`, carrying the same image parts; None when the points carry no
        image part to match.

    Raises:
        MatcherInputError: When the parts do not lie inside the rectified image, or the region
            matched (config.roi) does not.
    """
    left, right = points.left_image, points.right_image
    if left is None or right is None:
        return None
    size = (int(rectified.left.height), int(rectified.left.width))
    full_left, full_right = (_in_full_image(part, size) for part in (left, right))
    disparity_map = match(full_left, full_right, config, row_step=stride, threads=threads)
    again = triangulate(disparity_map.disparity, disparity_map.score, rectified, stride)
    again.left_image, again.right_image = left, right
    again.left_colour, again.right_colour = points.left_colour, points.right_colour
    return again


def _in_full_image(part: RectifiedImage, size: tuple[int, int]) -> np.ndarray:
    """Return the part pasted at its place in an image of `size` (rows, columns), zero
    elsewhere: the matcher reads only the pixels the part holds."""
    height, width = part.pixels.shape
    if (part.x < 0 or part.y < 0 or part.x + width > size[1] or part.y + height > size[0]):
        raise MatcherInputError(
            f'a rectified part {width}x{height} at ({part.x}, {part.y}) does not lie inside '
            f'the {size[1]}x{size[0]} rectified image')
    full = np.zeros(size, dtype=part.pixels.dtype)
    full[part.y:part.y + height, part.x:part.x + width] = part.pixels
    return full
