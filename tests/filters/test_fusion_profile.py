"""Fusion's target profile (jaxtrack.filters.fusion_profile) on drawn scenes and NumPy oracles.

Oracles: overlaps by hand and by a per-pair loop, occlusion groups by a breadth-first search,
drawn two-tone targets whose colours fall in known HSV bins (the target drawn on top is the
occluder), the recursive-mean formula for the models, and loops for the vmapped functions.
"""

from __future__ import annotations

import colorsys
import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.appearance.model import init_model
from jaxtrack.errors import InputError
from jaxtrack.filters.fusion_profile import (
    occlusion_status,
    overlap_ratio,
    reidentify,
    signature_distance,
    signatures,
    start_signatures,
    update_signatures,
)

HEIGHT, WIDTH = 96, 128
GREY = (128, 128, 128)
# HSV bins at step 32 (8 per channel): hues 0, 43, 85, 171 -> hue bins 0, 1, 2, 5.
RED, YELLOW, GREEN, BLUE = (200, 30, 30), (200, 200, 30), (30, 180, 30), (30, 30, 200)
PATCH, STEP, MIN_ROWS = (8, 4), 32.0, 2
NUM_BINS = 8**3
_signatures = jax.jit(
    functools.partial(signatures, patch_shape=PATCH, step=STEP, min_rows=MIN_ROWS)
)
_status = jax.jit(occlusion_status)
_reidentify = jax.jit(reidentify)


def draw(targets) -> np.ndarray:
    """Grey frame with ``(box, top, bottom)`` two-tone targets drawn in order (last on top)."""
    image = np.full((HEIGHT, WIDTH, 3), GREY, np.uint8)
    for box, top, bottom in targets:
        x, y, w, h = (round(v) for v in box)
        image[y : y + h // 2, x : x + w] = top
        image[y + h // 2 : y + h, x : x + w] = bottom
    return image


def boxes_array(*boxes) -> jnp.ndarray:
    return jnp.asarray(np.array(boxes, np.float32))


def one_hot_parts(upper: int, lower: int) -> np.ndarray:
    parts = np.zeros((2, NUM_BINS), np.float32)
    parts[0, upper] = parts[1, lower] = 1.0
    return parts


def hsv_bin(colour) -> int:
    """Joint HSV bin at step 32, from colorsys."""
    h, s, v = colorsys.rgb_to_hsv(*(c / 255 for c in colour))
    channels = [int(256 * h // STEP), int(256 * s // STEP), int(255 * v // STEP)]
    return (channels[0] * 8 + channels[1]) * 8 + channels[2]


def random_histograms(rng, shape) -> np.ndarray:
    raw = rng.gamma(0.3, size=(*shape, 2, 16)).astype(np.float32)
    return raw / raw.sum(-1, keepdims=True)


# --- eq. 2: Q = 2 |A n B| / |A u B| ---------------------------------------------------------


def test_overlap_ratio_by_hand():
    q = np.asarray(overlap_ratio(boxes_array([0, 0, 10, 10], [20, 0, 10, 10], [5, 0, 10, 10])))
    # Disjoint 0; identical 2; half-shifted: intersection 50, union 150 -> 2 * 50 / 150.
    assert q[0, 1] == 0.0
    np.testing.assert_allclose(np.diag(q), 2.0, rtol=1e-6)
    np.testing.assert_allclose(q[0, 2], 2 * 50 / 150, rtol=1e-6)
    np.testing.assert_allclose(q, q.T)


def test_overlap_ratio_against_pixel_count():
    """Integer boxes: |A n B| and |A u B| counted on a pixel grid."""
    rng = np.random.default_rng(0)
    boxes = np.concatenate([rng.integers(0, 30, (6, 2)), rng.integers(1, 20, (6, 2))], axis=1)
    masks = np.zeros((6, 60, 60), bool)
    for k, (x, y, w, h) in enumerate(boxes):
        masks[k, y : y + h, x : x + w] = True
    expected = np.array(
        [[2 * np.sum(a & b) / np.sum(a | b) for b in masks] for a in masks], np.float32
    )
    q = overlap_ratio(jnp.asarray(boxes, jnp.float32))
    np.testing.assert_allclose(q, expected, rtol=1e-6)
    assert 0 < np.sum((expected > 0) & (expected < 2))  # the draw holds partial overlaps


# --- eq. 1 signatures and their distance ----------------------------------------------------


def test_signatures_of_drawn_targets():
    """A two-tone box splits at its colour change; each part is one bin (colorsys's)."""
    box_a, box_b = [10, 20, 16, 32], [60, 40, 16, 32]
    frame = draw([(box_a, RED, BLUE), (box_b, GREEN, YELLOW)])
    sig = _signatures(jnp.asarray(frame), boxes_array(box_a, box_b))
    np.testing.assert_array_equal(sig.row, [4, 4])
    np.testing.assert_allclose(sig.histograms[0], one_hot_parts(hsv_bin(RED), hsv_bin(BLUE)))
    np.testing.assert_allclose(sig.histograms[1], one_hot_parts(hsv_bin(GREEN), hsv_bin(YELLOW)))


def test_signatures_vmap_equals_loop():
    frame = jnp.asarray(draw([([10, 20, 16, 32], RED, BLUE), ([50, 30, 20, 40], GREEN, RED)]))
    boxes = boxes_array([10, 20, 16, 32], [50, 30, 20, 40], [12, 25, 30, 50], [100, 70, 40, 40])
    batched = _signatures(frame, boxes)
    for k in range(boxes.shape[0]):
        one = _signatures(frame, boxes[k : k + 1])
        np.testing.assert_array_equal(batched.row[k], one.row[0])
        np.testing.assert_allclose(batched.histograms[k], one.histograms[0], atol=1e-7)


def test_signature_distance_analytic_and_loop():
    red_blue = one_hot_parts(1, 2)
    assert float(signature_distance(red_blue, red_blue)) == pytest.approx(0.0, abs=1e-6)
    assert float(signature_distance(red_blue, one_hot_parts(1, 3))) == pytest.approx(0.5)
    assert float(signature_distance(red_blue, one_hot_parts(4, 3))) == pytest.approx(1.0)
    assert float(signature_distance(red_blue, np.zeros_like(red_blue))) == pytest.approx(1.0)
    rng = np.random.default_rng(1)
    a, b = random_histograms(rng, (5,)), random_histograms(rng, (5,))
    expected = [
        np.mean([np.sqrt(max(1 - np.sum(np.sqrt(a[k, p] * b[k, p])), 0)) for p in (0, 1)])
        for k in range(5)
    ]
    np.testing.assert_allclose(signature_distance(a, b), expected, rtol=1e-5)


# --- occlusion status -----------------------------------------------------------------------

BOX_A, BOX_B, BOX_FAR = [30, 20, 16, 32], [38, 24, 16, 32], [96, 50, 16, 32]


def stored_signatures(targets):
    """Each target's signature drawn alone (its model before the occlusion)."""
    return jnp.concatenate(
        [_signatures(jnp.asarray(draw([t])), boxes_array(t[0])).histograms for t in targets]
    )


@pytest.mark.parametrize("front", [0, 1])
def test_occluder_is_the_target_drawn_on_top(front):
    targets = [(BOX_A, RED, BLUE), (BOX_B, GREEN, YELLOW), (BOX_FAR, YELLOW, GREEN)]
    drawn = [targets[1 - front], targets[front], targets[2]]  # the front one drawn last
    boxes = boxes_array(BOX_A, BOX_B, BOX_FAR)
    observed = _signatures(jnp.asarray(draw(drawn)), boxes).histograms
    status = _status(boxes, jnp.array([True, True, True]), stored_signatures(targets), observed)
    assert float(overlap_ratio(boxes)[0, 1]) > 0.3
    np.testing.assert_array_equal(status.related, [True, True, False])
    np.testing.assert_array_equal(status.occluder, [front, front, -1])
    np.testing.assert_array_equal(status.occluded, [front != 0, front != 1, False])


def test_dead_slot_and_threshold():
    """A dead slot on top of a live target links nothing; Q = 0.56 is no occlusion at 0.6."""
    boxes = boxes_array(BOX_A, BOX_B)
    stored = jnp.asarray(np.stack([one_hot_parts(1, 2), one_hot_parts(3, 4)]))
    dead = _status(boxes, jnp.array([True, False]), stored, stored)
    np.testing.assert_array_equal(dead.related, [False, False])
    np.testing.assert_array_equal(dead.occluder, [-1, -1])
    high = _status(boxes, jnp.array([True, True]), stored, stored, 0.6)
    np.testing.assert_array_equal(high.related, [False, False])


def occlusion_oracle(boxes, alive, stored, observed, threshold):
    """Groups by breadth-first search over a per-pair Q loop; argmin of own distances."""
    num = len(boxes)
    q = np.asarray(overlap_ratio(jnp.asarray(boxes)))
    linked = [
        [i != j and alive[i] and alive[j] and q[i, j] > threshold for j in range(num)]
        for i in range(num)
    ]
    own = np.asarray(signature_distance(stored, observed))
    occluder = np.full(num, -1)
    for start in range(num):
        if not any(linked[start]):
            continue
        group, frontier = {start}, [start]
        while frontier:
            i = frontier.pop()
            new = {j for j in range(num) if linked[i][j]} - group
            group |= new
            frontier.extend(new)
        members = sorted(group)
        occluder[start] = members[int(np.argmin(own[members]))]
    return occluder


def test_occlusion_groups_against_search():
    """Random tables (chains A-B-C where A and C do not touch included) against the search."""
    rng = np.random.default_rng(2)
    total_groups = 0
    for _ in range(3):
        num = 12
        boxes = np.concatenate(
            [rng.uniform(0, 80, (num, 2)), rng.uniform(10, 30, (num, 2))], axis=1
        ).astype(np.float32)
        alive = rng.random(num) < 0.85
        stored, observed = random_histograms(rng, (num,)), random_histograms(rng, (num,))
        status = _status(jnp.asarray(boxes), jnp.asarray(alive), stored, observed)
        expected = occlusion_oracle(boxes, alive, stored, observed, 0.3)
        np.testing.assert_array_equal(status.occluder, expected)
        np.testing.assert_array_equal(status.related, expected >= 0)
        np.testing.assert_array_equal(status.occluded, (expected >= 0) & (expected != range(num)))
        total_groups += len(set(expected) - {-1})
    assert total_groups >= 3


def test_chain_is_one_group():
    boxes = boxes_array([0, 0, 10, 10], [6, 0, 10, 10], [12, 0, 10, 10])
    q = np.asarray(overlap_ratio(boxes))
    assert q[0, 1] > 0.3 and q[1, 2] > 0.3 and q[0, 2] == 0.0
    stored = jnp.asarray(np.stack([one_hot_parts(k, k) for k in range(3)]))
    observed = jnp.asarray(np.stack([one_hot_parts(5, 5), one_hot_parts(5, 5), stored[2]]))
    status = _status(boxes, jnp.ones(3, bool), stored, observed)
    np.testing.assert_array_equal(status.occluder, [2, 2, 2])
    np.testing.assert_array_equal(status.occluded, [True, True, False])


def test_occlusion_status_jit_equals_eager():
    rng = np.random.default_rng(3)
    boxes = np.concatenate([rng.uniform(0, 40, (6, 2)), rng.uniform(10, 30, (6, 2))], 1)
    stored, observed = (jnp.asarray(random_histograms(rng, (6,))) for _ in range(2))
    args = (jnp.asarray(boxes, jnp.float32), jnp.ones(6, bool), stored, observed)
    for eager, jitted in zip(occlusion_status(*args), _status(*args), strict=True):
        np.testing.assert_array_equal(eager, jitted)


def test_mismatched_tables_raise():
    stored = jnp.zeros((3, 2, NUM_BINS))
    with pytest.raises(InputError, match="slot tables disagree"):
        occlusion_status(boxes_array(BOX_A, BOX_B), jnp.ones(2, bool), stored, stored)


# --- running signature models ---------------------------------------------------------------


def test_models_frozen_while_occluded():
    rng = np.random.default_rng(4)
    first, second = random_histograms(rng, (3,)), random_histograms(rng, (3,))
    models = init_model(jnp.asarray(first))
    occluded = jnp.array([False, True, False])
    updated = jax.jit(update_signatures)(models, jnp.asarray(second), occluded, 0.35)
    # Second histogram: rate max(1 / 2, 0.35) = 1/2 on the visible targets.
    expected = (first + second) / 2
    expected /= expected.sum(-1, keepdims=True)
    visible = np.array([0, 2])
    np.testing.assert_allclose(np.asarray(updated.histogram)[visible], expected[visible], 1e-5)
    np.testing.assert_array_equal(updated.histogram[1], models.histogram[1])
    np.testing.assert_array_equal(updated.count, [[2.0, 2.0], [1.0, 1.0], [2.0, 2.0]])  # per part
    # A third one at rate max(1 / 3, 0.35) = 0.35.
    third = random_histograms(rng, (3,))
    again = update_signatures(updated, jnp.asarray(third), jnp.zeros(3, bool), 0.35)
    expected = np.asarray(updated.histogram[0]) + 0.35 * (third[0] - updated.histogram[0])
    np.testing.assert_allclose(again.histogram[0], expected / expected.sum(-1)[:, None], 1e-5)


def test_start_signatures_replaces_born_slots_only():
    rng = np.random.default_rng(5)
    models = init_model(jnp.asarray(random_histograms(rng, (3,))))
    models = update_signatures(
        models, jnp.asarray(random_histograms(rng, (3,))), jnp.zeros(3, bool), 0.2
    )
    new = jnp.asarray(random_histograms(rng, (3,)))
    started = start_signatures(models, new, jnp.array([False, True, False]))
    np.testing.assert_allclose(started.histogram[1], new[1], rtol=1e-6)
    assert np.all(np.asarray(models.distance_mean[1]) > 0)  # the reset below changes something
    np.testing.assert_array_equal(started.count[1], [1.0, 1.0])
    np.testing.assert_array_equal(started.distance_mean[1], [0.0, 0.0])
    for field_new, field_old in zip(started, models, strict=True):
        np.testing.assert_array_equal(field_new[jnp.array([0, 2])], field_old[jnp.array([0, 2])])


# --- re-identification ----------------------------------------------------------------------

# Slot 0: an occluded red/blue target; slot 1: a visible red/blue one far away; slot 2: an
# occluded green/yellow target near slot 0.
SLOT_BOXES = [[30, 20, 16, 32], [100, 50, 16, 32], [40, 22, 16, 32]]
SLOT_COLOURS = [(RED, BLUE), (RED, BLUE), (GREEN, YELLOW)]
OCCLUDED = jnp.array([True, False, True])


def slot_table():
    targets = [(box, *colours) for box, colours in zip(SLOT_BOXES, SLOT_COLOURS, strict=True)]
    return boxes_array(*SLOT_BOXES), stored_signatures(targets)


def new_target(box, top, bottom):
    return _signatures(jnp.asarray(draw([(box, top, bottom)])), boxes_array(box)).histograms[0]


@pytest.mark.parametrize(
    ("box", "colours", "expected"),
    [
        ([34, 30, 16, 32], (RED, BLUE), 0),  # red near the occluded red: its identity
        ([34, 30, 16, 32], (GREEN, YELLOW), 2),  # green near the occluded green
        ([34, 30, 16, 32], (BLUE, GREEN), -1),  # nobody's colours
        ([96, 44, 16, 32], (RED, BLUE), -1),  # red near the visible red only
        ([2, 60, 16, 32], (RED, BLUE), -1),  # red, far from the occluded red
    ],
)
def test_reidentify(box, colours, expected):
    boxes, stored = slot_table()
    found = _reidentify(
        new_target(box, *colours), boxes_array(box)[0], OCCLUDED, boxes, stored, 1.0, 0.3
    )
    assert int(found) == expected


def test_reidentify_takes_the_nearest_signature_within_gate_and_radius():
    """Two occluded red-topped targets near the new red/blue one: D = 0.5 (red/green), 0."""
    boxes = boxes_array([30, 20, 16, 32], [40, 22, 16, 32])
    stored = jnp.asarray(
        np.stack([one_hot_parts(hsv_bin(RED), hsv_bin(GREEN)), one_hot_parts(hsv_bin(RED), 0)])
    )
    stored = stored.at[1, 1].set(jnp.asarray(one_hot_parts(0, hsv_bin(BLUE))[1]))
    box = boxes_array([34, 30, 16, 32])[0]
    red = new_target([34, 30, 16, 32], RED, BLUE)
    np.testing.assert_allclose(signature_distance(stored, red[None]), [0.5, 0.0], atol=1e-6)
    both = jnp.array([True, True])
    assert int(_reidentify(red, box, both, boxes, stored, 1.0, 0.6)) == 1
    first = jnp.array([True, False])
    assert int(_reidentify(red, box, first, boxes, stored, 1.0, 0.6)) == 0
    assert int(_reidentify(red, box, first, boxes, stored, 1.0, 0.4)) == -1
    # Slot 0's centre is (4, 10) px from the new one's: 0.34 box heights.
    assert int(_reidentify(red, box, first, boxes, stored, 0.3, 0.6)) == -1
    assert int(_reidentify(red, box, first, boxes, stored, 0.35, 0.6)) == 0


def test_reidentify_vmap_equals_loop_and_jit_equals_eager():
    boxes, stored = slot_table()
    new_boxes = [[34, 30, 16, 32], [34, 30, 16, 32], [96, 44, 16, 32], [2, 60, 16, 32]]
    colours = [(RED, BLUE), (GREEN, YELLOW), (RED, BLUE), (RED, BLUE)]
    news = jnp.stack([new_target(b, *c) for b, c in zip(new_boxes, colours, strict=True)])
    new_boxes = boxes_array(*new_boxes)
    batched = jax.jit(jax.vmap(reidentify, in_axes=(0, 0, None, None, None, None, None)))(
        news, new_boxes, OCCLUDED, boxes, stored, 1.0, 0.3
    )
    looped = [
        int(reidentify(news[k], new_boxes[k], OCCLUDED, boxes, stored, 1.0, 0.3)) for k in range(4)
    ]
    np.testing.assert_array_equal(batched, looped)
    np.testing.assert_array_equal(looped, [0, 2, -1, -1])
