"""Activity mask: where the training trajectories went (Fusion Sec. 2.3, the active area map).

Fusion maps "the coordinates of all the trajectories from the training set ... on the scene"
and applies morphological filtering to get a binary mask of the active areas. The coordinate
of a box is its foot point, the middle of its bottom edge ``(x + w / 2, y + h)``
(:func:`foot_points`): where a person stands on the ground, the same point the entry/exit
zones are made of (:mod:`jaxtrack.context.zones`). On a grid of square cells of side ``c``
pixels (cell ``(i, j)`` covers ``[j c, (j + 1) c) x [i c, (i + 1) c)``):

1. each trajectory's foot points, joined frame to frame by straight segments (so that a fast
   walker leaves no holes), are sampled every ``c / 2`` pixels at most and mark their cells;
2. closing by a disk of radius ``2 r`` pixels (fills the gaps between paths less than about
   ``4 r`` apart: a walkway crossed by several people is active as a whole), then dilation
   by a disk of radius ``r`` (a person covers more than the line of their feet); the
   outside of the image is empty (``scipy.ndimage``).

Building the mask is host-side NumPy/SciPy; :func:`in_active_area` is the per-frame query
(JAX, jit- and vmap-able).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float
from scipy import ndimage

#: Side of an activity cell, pixels.
ACTIVITY_CELL = 8
#: Radius of the dilation disk, pixels (the closing disk's is twice as large).
ACTIVITY_RADIUS = 16.0


def grid_shape(width: float, height: float, cell_size: float) -> tuple[int, int]:
    """``(rows, columns)`` of the cells covering a ``width x height`` image."""
    return int(np.ceil(height / cell_size)), int(np.ceil(width / cell_size))


def foot_points(boxes: np.ndarray) -> np.ndarray:
    """Middle of the bottom edge ``(x + w / 2, y + h)`` of ``[n, 4]`` boxes ``(x, y, w, h)``."""
    boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
    return np.stack([boxes[:, 0] + boxes[:, 2] / 2, boxes[:, 1] + boxes[:, 3]], axis=1)


def path_points(frames: np.ndarray, ids: np.ndarray, boxes: np.ndarray, step: float) -> np.ndarray:
    """Foot points of each trajectory joined by segments sampled at most ``step`` apart.

    Args:
        frames: ``[num_rows]`` frame of each box.
        ids: ``[num_rows]`` trajectory of each box.
        boxes: ``[num_rows, 4]`` ``(x, y, w, h)``.
        step: largest distance between consecutive samples of a segment, pixels.

    Returns:
        ``[num_samples, 2]`` points: every foot point, and points evenly spaced on each
        segment between the foot points of consecutive boxes of a trajectory.
    """
    frames = np.asarray(frames, np.int64).reshape(-1)
    ids = np.asarray(ids, np.int64).reshape(-1)
    order = np.lexsort((frames, ids))
    feet = foot_points(np.asarray(boxes, np.float64).reshape(-1, 4)[order])
    same = ids[order][1:] == ids[order][:-1]
    start, end = feet[:-1][same], feet[1:][same]
    pieces = np.ceil(np.linalg.norm(end - start, axis=1) / step).astype(np.int64)
    pieces = np.maximum(pieces, 1)
    segment = np.repeat(np.arange(pieces.size), pieces)
    offsets = np.arange(segment.size) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    fraction = (offsets / pieces[segment])[:, None]
    inner = start[segment] + fraction * (end[segment] - start[segment])
    return np.concatenate([feet, inner]).reshape(-1, 2)


def disk(radius_cells: float) -> np.ndarray:
    """Boolean disk ``i^2 + j^2 <= radius^2`` on the cell grid (odd side)."""
    half = int(np.floor(radius_cells))
    offsets = np.arange(-half, half + 1)
    return offsets[:, None] ** 2 + offsets[None, :] ** 2 <= radius_cells**2


def activity_mask(
    frames: np.ndarray,
    ids: np.ndarray,
    boxes: np.ndarray,
    width: float,
    height: float,
    cell_size: int = ACTIVITY_CELL,
    radius: float = ACTIVITY_RADIUS,
) -> np.ndarray:
    """The cells the trajectories' feet pass through, closed then dilated (module doc).

    Args:
        frames: ``[num_rows]`` frame of each box.
        ids: ``[num_rows]`` trajectory of each box.
        boxes: ``[num_rows, 4]`` ``(x, y, w, h)``.
        width: image width, pixels.
        height: image height, pixels.
        cell_size: cell side ``c``, pixels.
        radius: dilation radius ``r``, pixels (closing radius ``2 r``).

    Returns:
        ``[rows, columns]`` boolean mask (:func:`grid_shape`).
    """
    rows, columns = grid_shape(width, height, cell_size)
    points = path_points(frames, ids, boxes, cell_size / 2)
    cells = np.floor(points / cell_size).astype(np.int64)
    inside = (cells[:, 0] >= 0) & (cells[:, 0] < columns) & (cells[:, 1] >= 0)
    inside &= cells[:, 1] < rows
    closing, dilation = disk(2 * radius / cell_size), disk(radius / cell_size)
    pad = closing.shape[0] + dilation.shape[0]  # nothing reaches the padded border
    hits = np.zeros((rows + 2 * pad, columns + 2 * pad), bool)
    hits[cells[inside, 1] + pad, cells[inside, 0] + pad] = True
    closed = ndimage.binary_closing(hits, closing)
    return ndimage.binary_dilation(closed, dilation)[pad:-pad, pad:-pad]


def in_active_area(
    activity: Bool[Array, "rows columns"], cell_size: float, points: Float[Array, "*batch 2"]
) -> Bool[Array, "*batch"]:
    """Whether each point ``(x, y)`` lies in an active cell (False outside the grid).

    Pure JAX (jit- and vmap-able).

    Args:
        activity: ``[rows, columns]`` mask from :func:`activity_mask`.
        cell_size: its cell side, pixels.
        points: ``[..., 2]`` foot points ``(x, y)``.

    Returns:
        ``[...]`` booleans.
    """
    activity = jnp.asarray(activity)
    rows, columns = activity.shape
    cells = jnp.floor(jnp.asarray(points) / cell_size).astype(jnp.int32)
    column, row = cells[..., 0], cells[..., 1]
    inside = (column >= 0) & (column < columns) & (row >= 0) & (row < rows)
    return inside & activity[jnp.clip(row, 0, rows - 1), jnp.clip(column, 0, columns - 1)]
