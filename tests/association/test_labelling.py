"""Labelling: gated assignment against SciPy, identities through misses and crossings."""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
from scipy.optimize import linear_sum_assignment

from jaxtrack.association.assignment import gated_assignment
from jaxtrack.association.estimates import Estimates
from jaxtrack.association.labelling import (
    LabelParams,
    confirm_by_evidence,
    confirm_by_score,
    init_labels,
    label_step,
)
from jaxtrack.context.scores import identity_calibration

PARAMS = LabelParams(
    min_iou=jnp.asarray(0.3),
    max_missed_frames=jnp.asarray(3.0),
    confirm_score=jnp.asarray(0.0),
    new_track_max_iou=jnp.asarray(1.0),
    velocity_smoothing=jnp.asarray(0.0),
    score_calibration=identity_calibration(),
)


def test_gated_assignment_matches_scipy_on_allowed_pairs():
    rng = np.random.default_rng(0)
    solve = jax.jit(gated_assignment)
    for _ in range(30):
        rows, cols = rng.integers(1, 7, 2)
        cost = rng.random((rows, cols)).astype(np.float32) - 1
        allowed = rng.random((rows, cols)) < 0.6
        match = np.asarray(solve(jnp.asarray(cost), jnp.asarray(allowed)))
        # Oracle: maximum-cardinality matching over allowed pairs, minimum cost among those.
        big = np.where(allowed, cost, 1e3)
        r, c = linear_sum_assignment(big)
        keep = allowed[r, c]
        expected = np.full(rows, -1)
        expected[r[keep]] = c[keep]
        assert (match >= 0).sum() == keep.sum()
        taken = match[match >= 0]
        assert len(set(taken.tolist())) == taken.size
        assert np.all(allowed[np.nonzero(match >= 0)[0], taken])
        np.testing.assert_allclose(
            cost[np.nonzero(match >= 0)[0], taken].sum(), cost[r[keep], c[keep]].sum(), rtol=1e-5
        )


def _estimates(boxes, velocities=None, scores=None, capacity=4):
    """Estimates from centre boxes (y1, y2, w, h) and velocities (vy1, vy2)."""
    states = np.zeros((capacity, 6), np.float32)
    states[:, 4:] = 1.0
    mask = np.zeros(capacity, bool)
    velocities = np.zeros((len(boxes), 2)) if velocities is None else np.asarray(velocities)
    for j, (box, velocity) in enumerate(zip(boxes, velocities, strict=True)):
        states[j] = (box[0], velocity[0], box[1], velocity[1], box[2], box[3])
        mask[j] = True
    all_scores = np.ones(capacity, np.float32) if scores is None else np.asarray(scores, np.float32)
    return Estimates(
        states=jnp.asarray(states),
        masses=jnp.ones(capacity),
        scores=jnp.asarray(all_scores),
        mask=jnp.asarray(mask),
    )


def _run(frames, params=PARAMS, max_tracks=6):
    step = jax.jit(label_step)
    state = init_labels(max_tracks)
    ids = []
    for estimates in frames:
        state, labels = step(state, params, estimates)
        assert not labels.overflow
        ids.append(np.where(labels.confirmed, np.asarray(labels.ids), -1))
    return ids


def test_identity_survives_a_short_miss_and_ends_after_a_long_one():
    frames = []
    for t in range(20):
        boxes = [(100 + 5 * t, 200, 40, 100)] if t not in (5, 6, 12, 13, 14, 15) else []
        frames.append(_estimates(boxes, [(5.0, 0.0)] * len(boxes)))
    ids = _run(frames)
    assert ids[0][0] == 1
    assert all(ids[t][0] == 1 for t in range(12) if t not in (5, 6))  # two missed frames
    assert all(ids[t][0] == 2 for t in range(16, 20))  # four missed frames > 3: new track
    assert all(np.all(ids[t] == -1) for t in (5, 6, 12, 13, 14, 15))


def test_identities_are_kept_when_targets_cross():
    """Two targets cross; their boxes overlap heavily for a few frames and the order of the
    estimates changes, but the velocities carry each identity through."""
    frames = []
    for t in range(24):
        a = (100 + 8 * t, 200 + 1 * t, 40, 100)
        b = (292 - 8 * t, 210 - 1 * t, 40, 100)
        order = [a, b] if t % 2 else [b, a]
        velocity = [(8.0, 1.0), (-8.0, -1.0)] if t % 2 else [(-8.0, -1.0), (8.0, 1.0)]
        frames.append(_estimates(order, velocity))
    ids = _run(frames)
    for t in range(24):
        a_slot = 0 if t % 2 else 1
        assert ids[t][a_slot] == ids[0][1], t
        assert ids[t][1 - a_slot] == ids[0][0], t
    assert ids[0][0] != ids[0][1]


def test_tracks_are_confirmed_by_a_high_score_and_stay_confirmed():
    params = PARAMS._replace(confirm_score=jnp.asarray(0.9))
    scores = [0.6, 0.7, 0.95, 0.6, 0.5]
    frames = [
        _estimates(
            [(100 + 2 * t, 200, 40, 100), (400, 200, 40, 100)],
            [(2.0, 0.0), (0.0, 0.0)],
            [scores[t], 0.6, 0, 0],
        )
        for t in range(5)
    ]
    step = jax.jit(label_step)
    state = init_labels(4)
    for t, estimates in enumerate(frames):
        state, labels = step(state, params, estimates)
        np.testing.assert_array_equal(labels.ids[:2], [1, 2])  # identities from the start
        np.testing.assert_array_equal(labels.confirmed[:2], [t >= 2, False])


def test_overflow_is_flagged():
    boxes = [(100 + 60 * j, 200, 40, 100) for j in range(4)]
    _, labels = label_step(init_labels(3), PARAMS, _estimates(boxes))
    assert bool(labels.overflow)
    np.testing.assert_array_equal(labels.ids, [1, 2, 3, -1])


def test_an_estimate_overlapping_a_live_track_starts_no_duplicate_track():
    first = _estimates([(100, 200, 40, 100)])
    second = _estimates([(100, 200, 40, 100), (104, 204, 40, 100)])  # IoU ~0.77 with the track
    for threshold, expected in ((0.5, -1), (1.0, 2)):
        params = PARAMS._replace(new_track_max_iou=jnp.asarray(threshold))
        state, _ = label_step(init_labels(4), params, first)
        state, labels = label_step(state, params, second)
        np.testing.assert_array_equal(labels.ids[:2], [1, expected])
        assert int(jnp.sum(state.table.active)) == (1 if expected < 0 else 2)


def test_confirmed_tracks_take_precedence_over_tentative_ones():
    params = PARAMS._replace(confirm_score=jnp.asarray(0.9))
    # Track 1 (confirmed, score 1) at x=100, track 2 (tentative, score 0.5) at x=130.
    first = _estimates([(100, 200, 40, 100), (130, 200, 40, 100)], scores=[1.0, 0.5, 0, 0])
    # One estimate at x=120: IoU 0.33 with track 1, 0.60 with track 2.
    second = _estimates([(120, 200, 40, 100)], scores=[0.5, 0, 0, 0])
    state, labels = label_step(init_labels(4), params, first)
    np.testing.assert_array_equal(labels.confirmed[:2], [True, False])
    _, labels = label_step(state, params, second)
    assert int(labels.ids[0]) == 1 and bool(labels.confirmed[0])


def test_linked_tracks_smooth_their_box_displacement():
    params = PARAMS._replace(velocity_smoothing=jnp.asarray(0.75))
    state, _ = label_step(init_labels(2), params, _estimates([(100, 200, 40, 100)], [(4.0, 0.0)]))
    np.testing.assert_allclose(state.velocities[0], [4.0, 0.0])  # new track: PHD velocity
    state, _ = label_step(state, params, _estimates([(112, 202, 40, 100)], [(9.0, 9.0)]))
    # displacement (12, 2) since the last frame: 0.75 * (4, 0) + 0.25 * (12, 2)
    np.testing.assert_allclose(state.velocities[0], [6.0, 0.5], rtol=1e-6)
    empty = _estimates([])
    state, _ = label_step(state, params, empty)  # missed: velocity kept
    state, _ = label_step(state, params, _estimates([(130, 203, 40, 100)], [(0.0, 0.0)]))
    # two frames since the last link: predicted x = 112 + 2 * 6 = 124, IoU 0.74: linked;
    # displacement per frame (18, 1) / 2.
    np.testing.assert_allclose(state.velocities[0], [0.75 * 6 + 0.25 * 9, 0.75 * 0.5 + 0.25 * 0.5])


def _logit(score: float) -> float:
    return math.log(score) - math.log1p(-score)


def _evidence_oracle(scores, confirm_score):
    """Frame of confirmation of one target held on every frame where its score is not None:
    the running sum of logit(score) over held frames reaches logit(confirm_score)."""
    total = 0.0
    for t, score in enumerate(scores):
        if score is None:
            continue
        total += _logit(score)
        if total >= _logit(confirm_score):
            return t
    return None


def test_evidence_rule_confirms_when_the_score_log_odds_add_up():
    """Four targets far apart, each with its own score sequence (None: not detected), against
    a plain-Python sum of log-odds; the score rule confirms only the target that once
    reaches the threshold."""
    confirm = 0.97
    sequences = [
        [0.8] * 6,  # 3 logit(0.8) = 4.16 >= logit(0.97) = 3.48: third frame
        [0.6] * 12,  # logit(0.6) = 0.405: ninth frame
        [0.9, 0.2, 0.9, 0.9, 0.99, 0.9],  # a low score lowers the sum: fourth frame, not second
        [0.8, None, None, 0.8, 0.8, 0.8],  # the sum is kept through missed frames: fifth frame
    ]
    frames = 12
    params = PARAMS._replace(confirm_score=jnp.asarray(confirm), max_missed_frames=jnp.asarray(4.0))
    step = jax.jit(functools.partial(label_step, confirmation=confirm_by_evidence))
    score_step = jax.jit(label_step)
    state, score_state = init_labels(6), init_labels(6)
    first_confirmed = [None] * 4
    first_by_score = [None] * 4
    for t in range(frames):
        boxes, scores, slots = [], [], []
        for k, seq in enumerate(sequences):
            if t < len(seq) and seq[t] is not None:
                boxes.append((100 + 150 * k, 200, 40, 100))
                scores.append(seq[t])
                slots.append(k)
        estimates = _estimates(boxes, scores=scores + [0.0] * (6 - len(scores)), capacity=6)
        state, labels = step(state, params, estimates)
        score_state, score_labels = score_step(score_state, params, estimates)
        for j, k in enumerate(slots):
            if labels.confirmed[j] and first_confirmed[k] is None:
                first_confirmed[k] = t
            if score_labels.confirmed[j] and first_by_score[k] is None:
                first_by_score[k] = t
    expected = [_evidence_oracle(seq, confirm) for seq in sequences]
    assert expected == [2, 8, 3, 4]
    assert first_confirmed == expected
    assert first_by_score == [None, None, 4, None]


def test_evidence_rule_with_one_detection_at_the_threshold_confirms_at_once():
    params = PARAMS._replace(confirm_score=jnp.asarray(0.97))
    estimates = _estimates([(100, 200, 40, 100), (400, 200, 40, 100)], scores=[0.98, 0.96, 0, 0])
    for rule in (confirm_by_score, confirm_by_evidence):
        _, labels = label_step(init_labels(4), params, estimates, confirmation=rule)
        np.testing.assert_array_equal(labels.confirmed[:2], [True, False])
