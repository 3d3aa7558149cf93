"""Box conversions and overlaps (array-API agnostic: NumPy or jax.numpy).

Boxes are ``(x, y, w, h)`` with ``(x, y)`` the top-left corner (MOTChallenge) unless a name
says ``cxcywh`` (centre, width, height: the PHD filter's measurement space).
"""

from __future__ import annotations

import numpy as np


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

    Computed as TrackEval does (corners, clipped intersection, union = sum of areas minus
    intersection) so that scores agree to floating-point precision.
    """
    a = boxes_a[..., :, None, :]
    b = boxes_b[..., None, :, :]
    ix = xp.maximum(
        xp.minimum(a[..., 0] + a[..., 2], b[..., 0] + b[..., 2]) - xp.maximum(a[..., 0], b[..., 0]),
        0,
    )
    iy = xp.maximum(
        xp.minimum(a[..., 1] + a[..., 3], b[..., 1] + b[..., 3]) - xp.maximum(a[..., 1], b[..., 1]),
        0,
    )
    intersection = ix * iy
    union = a[..., 2] * a[..., 3] + b[..., 2] * b[..., 3] - intersection
    safe_union = xp.where(union > 0, union, 1.0)
    return xp.where(union > 0, intersection / safe_union, 0.0)
