"""Box conversions and overlaps (array-API agnostic: NumPy or jax.numpy).

Boxes are ``(x, y, w, h)`` with ``(x, y)`` the top-left corner (MOTChallenge) unless a name
says ``cxcywh`` (centre, width, height: the PHD filter's measurement space).
"""

from __future__ import annotations

import numpy as np

#: float64 machine epsilon, TrackEval's tolerance for empty areas.
_EPS = float(np.finfo(np.float64).eps)


def xywh_to_cxcywh(boxes, xp=np):
    """Top-left ``(x, y, w, h)`` -> centre ``(cx, cy, w, h)``, on the last axis."""
    x, y, w, h = (boxes[..., i] for i in range(4))
    return xp.stack([x + w / 2, y + h / 2, w, h], axis=-1)


def cxcywh_to_xywh(boxes, xp=np):
    """Centre ``(cx, cy, w, h)`` -> top-left ``(x, y, w, h)``, on the last axis."""
    cx, cy, w, h = (boxes[..., i] for i in range(4))
    return xp.stack([cx - w / 2, cy - h / 2, w, h], axis=-1)


def iou_matrix(boxes_a, boxes_b, xp=np):
    """Intersection over union of every pair, ``[..., n, 4] x [..., m, 4] -> [..., n, m]``.

    Computed with TrackEval's arithmetic (corners ``x + w``, areas ``(x1 - x0) * (y1 - y0)``,
    clipped intersection, union = sum of areas minus intersection; a pair whose area or union
    is at most float64 eps scores 0) so that scores agree with it bit for bit in float64.
    """
    a = boxes_a[..., :, None, :]
    b = boxes_b[..., None, :, :]
    a_x1, a_y1 = a[..., 0] + a[..., 2], a[..., 1] + a[..., 3]
    b_x1, b_y1 = b[..., 0] + b[..., 2], b[..., 1] + b[..., 3]
    ix = xp.maximum(xp.minimum(a_x1, b_x1) - xp.maximum(a[..., 0], b[..., 0]), 0)
    iy = xp.maximum(xp.minimum(a_y1, b_y1) - xp.maximum(a[..., 1], b[..., 1]), 0)
    intersection = ix * iy
    area_a = (a_x1 - a[..., 0]) * (a_y1 - a[..., 1])
    area_b = (b_x1 - b[..., 0]) * (b_y1 - b[..., 1])
    union = area_a + area_b - intersection
    valid = (area_a > _EPS) & (area_b > _EPS) & (union > _EPS)
    safe_union = xp.where(valid, union, 1.0)
    return xp.where(valid, intersection / safe_union, 0.0)
