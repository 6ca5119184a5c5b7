"""A slow, straightforward matcher with the same rules as correlation.match, for checking it.

Every score is computed from its two windows directly (Eq. 8, or Eq. 7 divided by the window
energies) in float64, into a full (H, W, D) volume, and the decisions are plain loops. Only for
small images: tests compare the fast kernel against it, the benchmark can too.

ROS-free: numpy and OpenCV only.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from stereo_fuzzy_perception.core.matching.window_matcher import (
    _FLAT_STD,
    DisparityMap,
    MatcherConfig,
    MatchStatus,
    effective_roi,
    preprocess_image,
)


def score_volume(left: np.ndarray, right: np.ndarray, config: MatcherConfig) -> np.ndarray:
    """Return scores[y, x, i] of left (x, y) against right (x - min_disparity - i, y).

    NaN where the candidate does not exist (a window leaves the image horizontally); 0 where
    either window is textureless (standard deviation below the threshold).
    """
    height, width = left.shape
    radius = config.window_size // 2
    size = config.window_size
    if config.preprocess != 'none':
        left = preprocess_image(left, config.preprocess)
        right = preprocess_image(right, config.preprocess)

    def windows(image: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        values = image.astype(np.float64)
        if image.dtype == np.uint16:
            values *= 255.0 / 65535.0
        padded = cv2.copyMakeBorder(values, radius, radius, 0, 0, cv2.BORDER_REFLECT_101)
        window = sliding_window_view(padded, (size, size))  # (H, W - 2r, size, size)
        std = window.std(axis=(2, 3))
        textured = (std >= config.texture_threshold) & (std > _FLAT_STD)
        if config.method == 'zncc':
            window = window - window.mean(axis=(2, 3), keepdims=True)
        norm = np.sqrt((window * window).sum(axis=(2, 3)))
        return window, norm, textured

    left_windows, left_norm, left_textured = windows(left)
    right_windows, right_norm, right_textured = windows(right)
    volume = np.full((height, width, config.disparity_range), np.nan)
    for index in range(config.disparity_range):
        d = config.min_disparity + index
        for x in range(radius, width - radius):
            x_right = x - d
            if not radius <= x_right <= width - 1 - radius:
                continue
            lw, rw = left_windows[:, x - radius], right_windows[:, x_right - radius]
            numerator = (lw * rw).sum(axis=(1, 2))
            denominator = left_norm[:, x - radius] * right_norm[:, x_right - radius]
            ok = left_textured[:, x - radius] & right_textured[:, x_right - radius]
            ok &= denominator > 0
            volume[:, x, index] = np.where(ok, numerator / np.where(ok, denominator, 1.0), 0.0)
    return volume


def reference_match(left: np.ndarray, right: np.ndarray,
                    config: MatcherConfig | None = None) -> DisparityMap:
    """Match like correlation.match, slowly and directly (see the module docstring)."""
    config = config or MatcherConfig()
    height, width = left.shape
    radius = config.window_size // 2
    roi_x, roi_y, roi_width, roi_height = effective_roi(config, width, height)
    volume = score_volume(left, right, config)
    valid_candidate = np.isfinite(volume)
    left_std = np.zeros((height, width))
    values = left if config.preprocess == 'none' else preprocess_image(left, config.preprocess)
    values = values.astype(np.float64) * (255.0 / 65535.0 if left.dtype == np.uint16 else 1.0)
    padded = cv2.copyMakeBorder(values, radius, radius, 0, 0, cv2.BORDER_REFLECT_101)
    left_std[:, radius:width - radius] = sliding_window_view(
        padded, (config.window_size, config.window_size)).std(axis=(2, 3))
    left_textured = (left_std >= config.texture_threshold) & (left_std > _FLAT_STD)

    # The right pixel's best score over all its candidates (for the left-right check).
    right_best = np.full((height, width), -np.inf)
    for index in range(config.disparity_range):
        d = config.min_disparity + index
        for x in range(width):
            x_right = x - d
            if valid_candidate[0, x, index]:
                right_best[:, x_right] = np.maximum(right_best[:, x_right], volume[:, x, index])

    disparity = np.full((height, width), np.nan, dtype=np.float32)
    score = np.full((height, width), np.nan, dtype=np.float32)
    status = np.full((height, width), MatchStatus.OUTSIDE_ROI, dtype=np.uint8)
    tolerance = config.lr_check_max_diff
    for y in range(roi_y, roi_y + roi_height):
        for x in range(roi_x, roi_x + roi_width):
            scores = volume[y, x]
            if not np.any(np.isfinite(scores)):
                status[y, x] = MatchStatus.NO_CANDIDATE
                continue
            chosen = int(np.nanargmax(scores))
            peak = scores[chosen]
            score[y, x] = peak
            if not left_textured[y, x]:
                status[y, x] = MatchStatus.LOW_TEXTURE
                continue
            if peak < config.min_score:
                status[y, x] = MatchStatus.LOW_SCORE
                continue
            if config.uniqueness_ratio > 0:
                others = [scores[i] for i in range(len(scores))
                          if abs(i - chosen) >= 2 and np.isfinite(scores[i])]
                second = max(others, default=-3.0)
                if 1.0 - second <= (1.0 - peak) * (1.0 + config.uniqueness_ratio):
                    status[y, x] = MatchStatus.NOT_UNIQUE
                    continue
            if tolerance >= 0:
                x_right = x - config.min_disparity - chosen
                near = max(volume[y, x + step, chosen + step]
                           for step in range(-tolerance, tolerance + 1)
                           if 0 <= x + step < width and 0 <= chosen + step < len(scores)
                           and np.isfinite(volume[y, x + step, chosen + step]))
                if near < right_best[y, x_right]:
                    status[y, x] = MatchStatus.LR_INCONSISTENT
                    continue
            offset = 0.0
            if config.subpixel and 0 < chosen < len(scores) - 1:
                below, above = scores[chosen - 1], scores[chosen + 1]
                curvature = below + above - 2.0 * peak
                if np.isfinite(below) and np.isfinite(above) and curvature < 0:
                    offset = float(np.clip(0.5 * (below - above) / curvature, -0.5, 0.5))
            status[y, x] = MatchStatus.VALID
            disparity[y, x] = config.min_disparity + chosen + offset
    return DisparityMap(disparity, score, status, (roi_x, roi_y, roi_width, roi_height), config)
