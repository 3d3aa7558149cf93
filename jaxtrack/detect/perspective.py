"""Perspective prior of a person's size given the image row, and blob splitting with it.

A fixed camera above a ground plane sees a standing person's image height grow linearly
with the row of the feet: ``height = intercept + slope * foot_row`` (for a pinhole camera
over a plane, exact when the horizon is level). The prior is learned from the detections
themselves (:func:`fit_perspective`): a robust line through the blobs whose shape is that of
one upright person, refitted on the inliers. Blobs much wider or taller than one person at
their row are groups; :func:`split_blob` cuts them where the blob's own pixel profile is
thinnest, near the equally spaced positions the prior suggests.
"""

from __future__ import annotations

import itertools
from typing import NamedTuple

import numpy as np

from jaxtrack.errors import InputError

#: Width / height of a pedestrian box: the standard of the Caltech pedestrian benchmark
#: (Dollar et al., PAMI 2012), also used to draw full-width boxes around thin silhouettes.
PERSON_ASPECT = 0.41
#: Aspect ratios (w / h) of the blobs taken as single upright people when fitting.
SINGLE_ASPECT = (0.2, 0.6)
#: A blob is split when wider than this many single-person widths (or taller than this
#: many heights) at its row.
SPLIT_FACTOR = 1.6


class PerspectivePrior(NamedTuple):
    """Expected person size by row, ``height = intercept + slope * foot_row``.

    Attributes:
        intercept: height at row 0, pixels.
        slope: height gained per row further down.
        aspect: median width / height of the single-person blobs.
    """

    intercept: float
    slope: float
    aspect: float

    def height(self, foot_row):
        """Expected height of a person whose feet are at ``foot_row`` (at least 1 pixel)."""
        return np.maximum(self.intercept + self.slope * np.asarray(foot_row, np.float64), 1.0)


def fit_perspective(boxes: np.ndarray, iterations: int = 5) -> PerspectivePrior:
    """Fits the prior to blob boxes by trimmed least squares.

    The line is fitted to the boxes with a single-person aspect ratio
    (:data:`SINGLE_ASPECT`), then refitted ``iterations`` times on those within 2.5 robust
    standard deviations (1.4826 MAD) of the residuals.

    Args:
        boxes: ``(x, y, w, h)``, ``[num_boxes, 4]``.
        iterations: refits on the inliers.

    Returns:
        The prior.

    Raises:
        InputError: fewer than 10 single-person boxes.
    """
    boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
    aspect = boxes[:, 2] / np.maximum(boxes[:, 3], 1.0)
    single = boxes[(aspect >= SINGLE_ASPECT[0]) & (aspect <= SINGLE_ASPECT[1])]
    if len(single) < 10:
        raise InputError(
            f"only {len(single)} person-shaped blobs to learn the perspective prior from "
            "(need 10); use more frames or no blob splitting (--no-split)"
        )
    foot = single[:, 1] + single[:, 3]
    height = single[:, 3]
    inliers = np.ones(len(single), bool)
    for _ in range(iterations + 1):
        slope, intercept = np.polyfit(foot[inliers], height[inliers], 1)
        residual = height - (intercept + slope * foot)
        spread = 1.4826 * np.median(np.abs(residual[inliers])) + 1e-6
        inliers = np.abs(residual) <= 2.5 * spread
        if inliers.sum() < 10:
            break
    return PerspectivePrior(
        intercept=float(intercept),
        slope=float(slope),
        aspect=float(np.median(single[:, 2] / single[:, 3])),
    )


def split_blob(
    box: np.ndarray, crop: np.ndarray, prior: PerspectivePrior, factor: float = SPLIT_FACTOR
) -> np.ndarray:
    """Splits a blob too wide or too tall for one person into one box per person.

    Width first: a blob wider than ``factor`` expected widths is cut into ``n = round(w /
    expected_width)`` columns, each cut at the thinnest column of the blob within a quarter
    of a part's width of its equally spaced position; each part gets the tight box of its
    own pixels. Then height: a part taller than ``factor`` expected heights (at its foot
    row) is cut into ``round(h / expected_height)`` rows the same way (people one behind
    another).

    Args:
        box: ``(x, y, w, h)`` of the blob.
        crop: the blob's pixels inside its box, bool ``[h, w]``.
        prior: the perspective prior.
        factor: how many person sizes make a group.

    Returns:
        ``[num_parts, 4]`` boxes (the blob's own box when it is not split).
    """
    x, y, w, h = (float(v) for v in box)
    expected_height = float(prior.height(y + h))
    expected_width = prior.aspect * expected_height
    parts = []
    for x0, x1 in _cuts(crop.sum(axis=0), w, expected_width, factor):
        columns = crop[:, x0:x1]
        rows = np.flatnonzero(columns.any(axis=1))
        if rows.size == 0:
            continue
        top, bottom = int(rows[0]), int(rows[-1]) + 1
        part = columns[top:bottom]
        height_there = float(prior.height(y + bottom))
        for y0, y1 in _cuts(part.sum(axis=1), bottom - top, height_there, factor):
            piece = part[y0:y1]
            cols = np.flatnonzero(piece.any(axis=0))
            if cols.size == 0:
                continue
            parts.append([x + x0 + cols[0], y + top + y0, cols[-1] - cols[0] + 1, y1 - y0])
    return np.asarray(parts, np.float64).reshape(-1, 4) if parts else np.asarray([box], float)


def _cuts(profile: np.ndarray, length: float, expected: float, factor: float) -> list:
    """``(start, stop)`` index ranges cutting a profile into ``round(length / expected)``
    parts at its minima near equal spacing (one part when ``length <= factor * expected``)."""
    size = len(profile)
    if length <= factor * expected:
        return [(0, size)]
    count = max(round(length / expected), 2)
    step = size / count
    window = max(int(step / 4), 1)
    edges = [0]
    for k in range(1, count):
        centre = round(k * step)
        lo, hi = max(centre - window, edges[-1] + 1), min(centre + window + 1, size - 1)
        if lo >= hi:
            continue
        edges.append(lo + int(np.argmin(profile[lo:hi])))
    edges.append(size)
    return list(itertools.pairwise(edges))


def person_box(box: np.ndarray, prior_aspect: float = PERSON_ASPECT) -> np.ndarray:
    """Widens thin boxes to a pedestrian's aspect ratio about their centre column.

    Args:
        box: ``[..., 4]`` boxes ``(x, y, w, h)``.
        prior_aspect: the width / height to reach at least.

    Returns:
        Boxes of the same height with ``w = max(w, prior_aspect * h)``.
    """
    box = np.asarray(box, np.float64)
    width = np.maximum(box[..., 2], prior_aspect * box[..., 3])
    out = box.copy()
    out[..., 0] = box[..., 0] + (box[..., 2] - width) / 2
    out[..., 2] = width
    return out
