"""Matched stereo points: the output of correlation, the input of the fuzzy stage. ROS-free."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RectifiedImage:
    """The part of a rectified image (left or right) that matches were found in.

    Attributes:
        pixels: (H, W) grey image, uint8 or uint16; or (H, W, 3) RGB for the colour image.
        x: Column of pixels[0, 0] in the rectified image [px].
        y: Row of pixels[0, 0] [px].
        window_size: Side of the correlation window the matches were found with [px].
    """

    pixels: np.ndarray
    x: int = 0
    y: int = 0
    window_size: int = 9


@dataclass
class MatchedPoints:
    """Valid matches of one stereo pair, one row per point.

    Attributes:
        xyz: (N, 3) positions [m] in the left camera's optical frame.
        u_left: (N,) column in the left rectified image [px].
        v_left: (N,) row in both rectified images [px].
        u_right: (N,) column in the right rectified image [px].
        score: (N,) correlation score at the match (Eq. 8 coefficient, -1..1).
        left_image: The left rectified image the matches were found in (the part the matcher
            read), when it came with them: the fuzzy stage takes the top face's outline from
            it (face_outline.py).
        right_image: The right rectified image, the part the matcher read, when it came with
            them: a plain top's height is measured from where its plain region lies in it
            (plain_face.py).
        left_colour: The same part of the left rectified image in colour (RGB), when the
            cameras gave colour: the fuzzy stage takes the object's silhouette from it
            (colour_silhouette.py).
        right_colour: The same part of the right rectified image as right_image, in colour:
            where the silhouette's rim lies in it gives the top's height.
    """

    xyz: np.ndarray
    u_left: np.ndarray
    v_left: np.ndarray
    u_right: np.ndarray
    score: np.ndarray
    left_image: RectifiedImage | None = None
    right_image: RectifiedImage | None = None
    left_colour: RectifiedImage | None = None
    right_colour: RectifiedImage | None = None

    def __len__(self) -> int:
        return int(self.xyz.shape[0])

    @classmethod
    def empty(cls) -> MatchedPoints:
        """Return a set with no points."""
        zero = np.zeros(0, dtype=np.float32)
        return cls(np.zeros((0, 3), dtype=np.float32), zero, zero.copy(), zero.copy(),
                   zero.copy())

    def subset(self, mask: np.ndarray) -> MatchedPoints:
        """Return the points selected by a boolean mask or index array."""
        return MatchedPoints(self.xyz[mask], self.u_left[mask], self.v_left[mask],
                             self.u_right[mask], self.score[mask], self.left_image,
                             self.right_image, self.left_colour, self.right_colour)
