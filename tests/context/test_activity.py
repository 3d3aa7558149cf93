"""Activity mask: path sampling, the morphology on analytic paths, and the JAX lookup."""

from __future__ import annotations

import jax
import numpy as np
import pytest
from scipy import ndimage

from jaxtrack.context.activity import (
    activity_mask,
    disk,
    grid_shape,
    in_active_area,
    path_points,
)

WIDTH, HEIGHT, CELL = 768, 576, 8


def walker(identity: int, y: float, x0: float, x1: float, frames: int = 50):
    """``(frames, ids, boxes)`` of a 10x20 box whose feet go from ``(x0, y)`` to ``(x1, y)``."""
    xs = np.linspace(x0, x1, frames)
    boxes = np.c_[xs - 5, np.full(frames, y - 20.0), np.full(frames, 10.0), np.full(frames, 20.0)]
    return np.arange(1, frames + 1), np.full(frames, identity), boxes


def stacked(*walkers):
    return tuple(np.concatenate(parts) for parts in zip(*walkers, strict=True))


def test_path_points_fill_segments_within_the_step():
    frames = np.array([3, 1, 2, 1, 5])  # unsorted rows, two trajectories
    ids = np.array([1, 1, 1, 2, 2])
    boxes = np.array(
        [[90, 0, 10, 10], [0, 0, 10, 10], [30, 0, 10, 10], [0, 50, 10, 10], [0, 53, 10, 10]],
        float,
    )
    points = path_points(frames, ids, boxes, step=4.0)
    first = points[points[:, 1] == 10]  # trajectory 1: feet along y = 10, x from 5 to 95
    xs = np.unique(first[:, 0])
    assert xs.min() == 5 and xs.max() == 95 and np.max(np.diff(xs)) <= 4.0
    second = points[points[:, 1] > 10]  # trajectory 2: a 3 px step, no extra point needed
    np.testing.assert_allclose(np.unique(second[:, 1]), [60, 63])
    assert not np.any((points[:, 1] > 10) & (points[:, 1] < 60))  # no segment across ids


def test_a_straight_path_gives_its_cells_dilated_by_the_radius():
    frames, ids, boxes = walker(1, 204, 100, 600)
    mask = activity_mask(frames, ids, boxes, WIDTH, HEIGHT, CELL, radius=16.0)
    assert mask.shape == grid_shape(WIDTH, HEIGHT, CELL) == (72, 96)
    hits = np.zeros_like(mask)
    hits[204 // CELL, 100 // CELL : 600 // CELL + 1] = True
    np.testing.assert_array_equal(mask, ndimage.binary_dilation(hits, disk(2.0)))


@pytest.mark.parametrize(("gap", "joined"), [(48, True), (200, False)])
def test_closing_joins_nearby_paths_only(gap, joined):
    # 48 px = 6 cells apart: the dilations alone (2 cells each) leave the middle row empty,
    # the closing (radius 4 cells) fills it; 200 px apart stays two bands.
    paths = stacked(walker(1, 204, 100, 600), walker(2, 204 + gap, 100, 600))
    mask = activity_mask(*paths, WIDTH, HEIGHT, CELL, radius=16.0)
    between = mask[204 // CELL + 3 : (204 + gap) // CELL - 2, 20:70]
    assert between.all() if joined else not between.any()


def test_paths_at_the_image_border_are_not_eroded():
    mask = activity_mask(*walker(1, 3, 0, 767), WIDTH, HEIGHT, CELL, radius=16.0)
    assert mask[0].all() and mask[1].all() and not mask[4:].any()


def test_in_active_area_matches_a_loop_under_jit_and_vmap():
    rng = np.random.default_rng(0)
    activity = rng.random((9, 12)) < 0.5
    points = rng.uniform(-20, 120, (200, 2)).astype(np.float32)
    expected = [
        0 <= x < 96 and 0 <= y < 72 and bool(activity[int(y // 8), int(x // 8)]) for x, y in points
    ]
    np.testing.assert_array_equal(in_active_area(activity, 8.0, points), expected)
    np.testing.assert_array_equal(jax.jit(in_active_area)(activity, 8.0, points), expected)
    mapped = jax.vmap(in_active_area, in_axes=(None, None, 0))(activity, 8.0, points)
    np.testing.assert_array_equal(mapped, expected)
