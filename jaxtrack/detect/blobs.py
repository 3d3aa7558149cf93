"""Foreground masks to blobs: morphology, connected components, boxes, ellipses, scores.

A blob is an 8-connected component of the cleaned mask. Its box is the tight pixel box
``(x, y, w, h)`` (``x, y`` the top-left pixel, ``w, h`` pixel counts, so a filled rectangle
drawn over columns ``x0..x1`` gives ``w = x1 - x0 + 1``); its ellipse is the one with the
same second moments as its pixels (centre, full major and minor axis lengths ``4 sqrt(l)`` of
the covariance eigenvalues ``l``, angle of the major axis in degrees from the x axis).
"""

from __future__ import annotations

from typing import NamedTuple

import cv2
import numpy as np

from jaxtrack.errors import InputError


class Blobs(NamedTuple):
    """The blobs of one mask.

    Attributes:
        boxes: ``(x, y, w, h)``, ``[num_blobs, 4]`` float64.
        ellipses: ``(cx, cy, major, minor, angle_deg)``, ``[num_blobs, 5]`` float64.
        areas: foreground pixels of each blob, ``[num_blobs]`` int64.
        crops: the blob's own pixels inside its box, one bool ``[h, w]`` array each.
    """

    boxes: np.ndarray
    ellipses: np.ndarray
    areas: np.ndarray
    crops: list[np.ndarray]

    def __len__(self) -> int:
        return int(self.boxes.shape[0])


def clean_mask(
    mask: np.ndarray, open_size: tuple[int, int] = (1, 5), close_size: tuple[int, int] = (3, 11)
) -> np.ndarray:
    """Opening (removes specks and thin lines) then closing (joins a person's parts).

    Args:
        mask: ``[height, width]`` bool.
        open_size: ``(width, height)`` of the rectangular opening element; a vertical line
            removes horizontal structures thinner than its height; ``(1, 1)``: none.
        close_size: ``(width, height)`` of the elliptic closing element; taller than wide,
            since people break apart horizontally (belt, legs); ``(1, 1)``: none.

    Returns:
        The cleaned ``[height, width]`` bool mask.
    """
    image = mask.astype(np.uint8)
    if max(open_size) > 1:
        kernel = np.ones((open_size[1], open_size[0]), np.uint8)
        image = cv2.morphologyEx(image, cv2.MORPH_OPEN, kernel)
    if max(close_size) > 1:
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, tuple(close_size))
        image = cv2.morphologyEx(image, cv2.MORPH_CLOSE, kernel)
    return image.astype(bool)


def extract_blobs(mask: np.ndarray, min_area: int = 1) -> Blobs:
    """Connected components of a bool mask with at least ``min_area`` pixels.

    Args:
        mask: ``[height, width]`` bool (or 0/non-0) foreground mask.
        min_area: smallest blob kept, pixels.

    Returns:
        The blobs, in the order of their top-left scan position.

    Raises:
        InputError: the mask is not two-dimensional.
    """
    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise InputError(f"mask must be [height, width], got shape {mask.shape}")
    _count, labels, stats, _ = cv2.connectedComponentsWithStats(
        mask.astype(np.uint8), connectivity=8, ltype=cv2.CV_32S
    )
    keep = np.flatnonzero(stats[1:, cv2.CC_STAT_AREA] >= min_area) + 1
    stats = stats[keep].astype(np.int64)
    boxes = stats[:, :4].astype(np.float64)
    areas = stats[:, cv2.CC_STAT_AREA]
    crops = [
        labels[y : y + h, x : x + w] == label
        for label, (x, y, w, h) in zip(keep, stats[:, :4], strict=True)
    ]
    ellipses = np.array(
        [crop_ellipse(crop, x, y) for crop, (x, y) in zip(crops, boxes[:, :2], strict=True)]
    )
    return Blobs(boxes, ellipses.reshape(-1, 5), areas, crops)


def crop_ellipse(crop: np.ndarray, x: float = 0.0, y: float = 0.0) -> np.ndarray:
    """The second-moment ellipse ``(cx, cy, major, minor, angle_deg)`` of a crop's pixels.

    Args:
        crop: ``[h, w]`` bool, at least one pixel set.
        x: image column of the crop's left edge.
        y: image row of the crop's top edge.

    Returns:
        The ellipse in image coordinates (pixel centres at integer positions): the
        eigenvalues of the pixel covariance are ``(var_x + var_y) / 2 +- sqrt(((var_x -
        var_y) / 2)^2 + cov_xy^2)``, the major axis at ``atan2(2 cov_xy, var_x - var_y) / 2``.
    """
    moments = cv2.moments(crop.astype(np.uint8), binaryImage=True)
    count = moments["m00"]
    cx, cy = moments["m10"] / count, moments["m01"] / count
    var_x, var_y, cov_xy = moments["mu20"] / count, moments["mu02"] / count, moments["mu11"] / count
    half_trace, half_gap = (var_x + var_y) / 2, np.hypot((var_x - var_y) / 2, cov_xy)
    major = 4.0 * np.sqrt(max(half_trace + half_gap, 0.0))
    minor = 4.0 * np.sqrt(max(half_trace - half_gap, 0.0))
    angle = np.degrees(0.5 * np.arctan2(2 * cov_xy, var_x - var_y)) % 180.0
    return np.array([x + cx, y + cy, major, minor, angle])
