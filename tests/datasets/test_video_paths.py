"""Walking geometry of the video scene against closed forms and a loop-based visibility."""

from __future__ import annotations

import numpy as np
import pytest

from jaxtrack.datasets import VideoSceneConfig
from jaxtrack.datasets.video_paths import (
    STRIDE,
    VISIBILITY_GRID,
    box_visibility,
    crosses_occluder,
    gait_phase,
    nominal_height,
    person_boxes,
    walk,
)

CONFIG = VideoSceneConfig()
PACE = 0.8
HORIZON = CONFIG.horizon_row * CONFIG.image_height  # r0 = -38.4 pixels


def test_walk_along_a_row_has_constant_speed():
    row = 300.0
    step = PACE * CONFIG.height_per_row * (row - HORIZON) / CONFIG.frame_rate  # v = pace h / fps
    feet, arrivals = walk(np.array([[100.0, row], [400.0, row]]), PACE, CONFIG)
    count = int(np.ceil(300.0 / step))
    assert len(feet) == count + 1 and arrivals.tolist() == [0, count]
    np.testing.assert_allclose(feet[:-1, 0], 100.0 + step * np.arange(count), rtol=0, atol=1e-9)
    np.testing.assert_array_equal(feet[-1], [400.0, row])
    np.testing.assert_array_equal(feet[:, 1], row)


def test_walk_towards_the_camera_speeds_up_geometrically():
    # Down a column: y_{k+1} - r0 = (y_k - r0)(1 + c), c = pace a / fps (closed form).
    c = PACE * CONFIG.height_per_row / CONFIG.frame_rate
    start, end = 150.0, 450.0
    feet, _ = walk(np.array([[200.0, start], [200.0, end]]), PACE, CONFIG)
    k = np.arange(len(feet) - 1)
    np.testing.assert_allclose(feet[:-1, 1], HORIZON + (start - HORIZON) * (1 + c) ** k, rtol=1e-12)
    assert len(feet) - 1 == int(np.ceil(np.log((end - HORIZON) / (start - HORIZON)) / np.log1p(c)))
    assert feet[-1, 1] == end


def test_walk_stands_on_a_stop_for_the_given_frames():
    route = np.array([[100.0, 300.0], [150.0, 300.0], [150.0, 350.0]])
    feet, arrivals = walk(route, PACE, CONFIG, {1: 7})
    first = arrivals[1]
    np.testing.assert_array_equal(feet[first : first + 7], np.repeat(route[1:2], 7, axis=0))
    assert not np.array_equal(feet[first + 7], route[1])
    assert arrivals[2] == len(feet) - 1
    phase = gait_phase(feet, CONFIG)
    assert np.all(phase[first : first + 7] == phase[first])  # no gait while standing


def test_gait_phase_is_one_cycle_per_stride():
    row = 250.0
    feet, _ = walk(np.array([[50.0, row], [550.0, row]]), PACE, CONFIG)
    height = CONFIG.height_per_row * (row - HORIZON)
    phase = gait_phase(feet, CONFIG)
    assert phase[0] == 0.0 and np.all(np.diff(phase) > 0)
    assert phase[-1] == pytest.approx(2 * np.pi * 500.0 / (STRIDE * height), rel=1e-12)


def test_person_boxes_stand_on_their_feet():
    boxes = person_boxes(np.array([[100.0, 200.0]]), np.array([80.0]), 0.4)
    np.testing.assert_allclose(boxes, [[84.0, 120.0, 32.0, 80.0]])
    assert nominal_height(HORIZON, CONFIG) == 0.0


def _visibility_loop(boxes, occluder, size):
    """Slow oracle: the same samples, every occluder tested one by one."""
    grid = VISIBILITY_GRID
    out = []
    for i, (x, y, w, h) in enumerate(boxes):
        hidden = 0
        for row in range(grid):
            for col in range(grid):
                sx, sy = x + (col + 0.5) / grid * w, y + (row + 0.5) / grid * h
                covered = not (0 <= sx < size[0] and 0 <= sy < size[1])
                ox, oy, ow, oh = occluder
                if y + h < oy + oh and ox <= sx < ox + ow and oy <= sy < oy + oh:
                    covered = True
                for j, (x2, y2, w2, h2) in enumerate(boxes):
                    if j != i and y2 + h2 > y + h and x2 <= sx < x2 + w2 and y2 <= sy < y2 + h2:
                        covered = True
                hidden += covered
        out.append(1 - hidden / grid**2)
    return np.array(out)


def test_visibility_matches_a_loop_on_random_frames():
    rng = np.random.default_rng(0)
    occluder = np.array([120.0, 60.0, 50.0, 70.0])
    for _ in range(5):
        feet = rng.uniform([-20, 40], [340, 260], (8, 2))
        boxes = person_boxes(feet, rng.uniform(20, 90, 8), 0.4)
        np.testing.assert_allclose(
            box_visibility(boxes, occluder, (320, 240)),
            _visibility_loop(boxes, occluder, (320, 240)),
            atol=1e-12,
        )


def test_visibility_analytic_cases():
    occluder = np.array([100.0, 50.0, 60.0, 100.0])  # bottom row 150
    size = (400, 300)
    alone = np.array([[10.0, 10.0, 16.0, 32.0]])
    assert box_visibility(alone, occluder, size).tolist() == [1.0]
    behind = np.array([[110.0, 60.0, 20.0, 80.0]])  # feet on row 140 < 150
    assert box_visibility(behind, occluder, size).tolist() == [0.0]
    in_front = np.array([[110.0, 80.0, 20.0, 80.0]])  # feet on row 160 > 150
    assert box_visibility(in_front, occluder, size).tolist() == [1.0]
    half_out = np.array([[-8.0, 200.0, 16.0, 40.0]])
    assert box_visibility(half_out, occluder, size).tolist() == [0.5]
    # A nearer box covering exactly the left half of a farther one; equal feet: no occlusion.
    pair = np.array([[200.0, 100.0, 32.0, 64.0], [184.0, 90.0, 32.0, 80.0]])
    assert box_visibility(pair, occluder, size).tolist() == [0.5, 1.0]
    level = np.array([[200.0, 100.0, 32.0, 64.0], [190.0, 100.0, 32.0, 64.0]])
    assert box_visibility(level, occluder, size).tolist() == [1.0, 1.0]


def test_routes_through_the_occluder_base_are_detected():
    x, y, w, h = CONFIG.pixels(CONFIG.occluder)
    base, middle = y + h, x + w / 2
    assert crosses_occluder(np.array([[middle, base - 30], [middle, base + 30]]), CONFIG)
    assert crosses_occluder(np.array([[0, base - 50], [middle, base - 10], [middle, 470]]), CONFIG)
    assert not crosses_occluder(np.array([[10.0, base - 20], [630.0, base - 20]]), CONFIG)
    assert not crosses_occluder(np.array([[20.0, base - 40], [20.0, base + 40]]), CONFIG)
