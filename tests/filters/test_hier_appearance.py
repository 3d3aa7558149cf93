"""Hierarchical high-level appearance: histograms, ranking, pool, eq. 4-6 and re-association.

Oracles: a NumPy reference of the 49 histograms (exact bins), an analytic red / green
ranking, NumPy loops of the variance ratio, the recursive means and distance statistics, and
greedy matching; drawn scenes of coloured targets with known identities for re-association.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.appearance import LINEAR_COMBINATION_WEIGHTS
from jaxtrack.errors import InputError
from jaxtrack.filters.hier_appearance import (
    NUM_BINS,
    NUM_FEATURES,
    AppearanceParams,
    box_histograms,
    default_params,
    init_table,
    reset_slots,
    update_appearance,
)
from jaxtrack.filters.hier_reassociation import (
    association_distances,
    own_track_gate,
    reassociate,
)

PATCH = (6, 4)
PARAMS = default_params(PATCH)
M, N = 3, 3
_histograms = jax.jit(box_histograms, static_argnames="patch_shape")
_update = jax.jit(update_appearance, static_argnames="num_current")
_distances = jax.jit(association_distances)
_reassociate = jax.jit(reassociate)


def _assert_tree_equal(a, b):
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


# --- histograms ----------------------------------------------------------------------------


def _reference_histograms(frame, box, patch_shape):
    """Nearest-pixel samples at the cell centres, feature bins by integer arithmetic."""
    x, y, w, h = (float(v) for v in box)
    ph, pw = patch_shape
    rows = np.floor(y + (np.arange(ph) + 0.5) * h / ph).astype(int)
    cols = np.floor(x + (np.arange(pw) + 0.5) * w / pw).astype(int)
    weights = LINEAR_COMBINATION_WEIGHTS.astype(np.int64)
    low = 255 * np.minimum(weights, 0).sum(1)
    span = 255 * np.abs(weights).sum(1)
    histograms = np.zeros((NUM_FEATURES, NUM_BINS))
    for r in rows:
        for c in cols:
            if 0 <= r < frame.shape[0] and 0 <= c < frame.shape[1]:
                value = weights @ frame[r, c].astype(np.int64) - low
                bins = np.minimum(256 * value // (4 * span), NUM_BINS - 1)
                histograms[np.arange(NUM_FEATURES), bins] += 1
    total = histograms.sum(1, keepdims=True)
    return np.where(total > 0, histograms / np.maximum(total, 1), 0.0)


def test_box_histograms_equal_numpy_reference():
    frame = np.random.default_rng(0).integers(0, 256, (48, 64, 3), dtype=np.uint8)
    # Cells of 3 x 3 pixels from whole coordinates: every sample point is a pixel centre.
    boxes = np.array(
        [[5, 4, 12, 18], [40, 20, 12, 18], [-6, 33, 12, 18], [70, 0, 12, 18]], np.float32
    )
    result = np.asarray(_histograms(jnp.asarray(frame), jnp.asarray(boxes), patch_shape=PATCH))
    assert result.shape == (4, NUM_FEATURES, NUM_BINS)
    for box, histograms in zip(boxes, result, strict=True):
        np.testing.assert_allclose(histograms, _reference_histograms(frame, box, PATCH), atol=1e-6)
    assert np.all(result[3] == 0)  # wholly outside: no observation
    np.testing.assert_allclose(result[:3].sum(-1), 1.0, atol=1e-5)


# --- ranking, pool and updates -------------------------------------------------------------


def _variance_ratio_reference(p, q, delta):
    p, q = np.asarray(p, np.float64), np.asarray(q, np.float64)
    ratio = np.log(np.maximum(p, delta)) - np.log(np.maximum(q, delta))

    def variance(weights):
        mean = (weights * ratio).sum(-1)
        return (weights * ratio**2).sum(-1) - mean**2

    return variance((p + q) / 2) / (variance(p) + variance(q) + 1e-6)


def test_ranking_prefers_features_that_separate_red_target_from_green_background():
    """Red (200, 60, 60) on green (60, 200, 60): ``aR + bG + cB`` separates them iff a != b."""
    frame = np.zeros((48, 64, 3), np.uint8)
    frame[...] = (200, 60, 60)
    background = np.zeros_like(frame)
    background[...] = (60, 200, 60)
    boxes = jnp.array([[10, 10, 12, 18]], jnp.float32)
    target = _histograms(jnp.asarray(frame), boxes, patch_shape=PATCH)
    behind = _histograms(jnp.asarray(background), boxes, patch_shape=PATCH)
    table = _update(init_table(1, M, N), target, behind, jnp.array([True]), PARAMS, num_current=M)
    a, b, _ = LINEAR_COMBINATION_WEIGHTS[np.asarray(table.features[0])].T
    assert np.all(a != b)  # current and long-run: all separate the colours
    p, q = (np.asarray(h[0], np.float64) for h in (target, behind))
    ratios = _variance_ratio_reference(
        p / p.sum(-1, keepdims=True), q / q.sum(-1, keepdims=True), float(PARAMS.delta)
    )
    separating = LINEAR_COMBINATION_WEIGHTS[:, 0] != LINEAR_COMBINATION_WEIGHTS[:, 1]
    # One-hot p and q: VR = 0 on shared bins, log(1 / delta)^2 / 1e-6 on distinct ones.
    np.testing.assert_allclose(ratios[~separating], 0.0, atol=1e-9)
    np.testing.assert_allclose(ratios[separating], np.log(float(PARAMS.delta)) ** 2 / 1e-6)


def _random_histograms(rng, shape, concentration):
    counts = rng.gamma(concentration, size=(*shape, NUM_BINS))
    return (counts / counts.sum(-1, keepdims=True)).astype(np.float32)


def _reference_run(targets, backgrounds, updates, delta):
    """Per slot and feature: the mean of the observed histograms, the distances of each to the
    mean before it, their mean and population variance; the pool's win counts."""
    num_slots = targets.shape[1]
    seen = [[] for _ in range(num_slots)]
    distances = [[] for _ in range(num_slots)]
    wins = np.zeros((num_slots, NUM_FEATURES))
    current = np.full((num_slots, M), -1)
    for target, background, update in zip(targets, backgrounds, updates, strict=True):
        for s in np.flatnonzero(update):
            if seen[s]:
                mean = np.mean(seen[s], axis=0)
                distances[s].append(np.sqrt(np.maximum(1 - np.sqrt(mean * target[s]).sum(-1), 0)))
            seen[s].append(target[s].astype(np.float64))
            ratios = _variance_ratio_reference(target[s], background[s], delta)
            current[s] = np.argsort(-ratios)[:M]
            wins[s, current[s]] += 1
    return seen, distances, wins, current


def test_update_equals_numpy_loop_of_eq_2_to_6():
    rng = np.random.default_rng(1)
    frames, slots = 6, 3
    targets = _random_histograms(rng, (frames, slots, NUM_FEATURES), 0.5)
    backgrounds = _random_histograms(rng, (frames, slots, NUM_FEATURES), 0.5)
    updates = rng.random((frames, slots)) < 0.7
    updates[:, 2] = False  # never updated
    updates[:3, 0] = True
    table = init_table(slots, M, N)
    for t in range(frames):
        table = _update(
            table, targets[t], backgrounds[t], jnp.asarray(updates[t]), PARAMS, num_current=M
        )
    seen, distances, wins, current = _reference_run(
        targets, backgrounds, updates, float(PARAMS.delta)
    )
    models = table.models
    for s in range(2):
        np.testing.assert_allclose(models.histogram[s], np.mean(seen[s], axis=0), atol=1e-5)
        np.testing.assert_array_equal(models.count[s], len(seen[s]))
        d = np.stack(distances[s])
        np.testing.assert_allclose(models.distance_mean[s], d.mean(0), atol=1e-5)
        np.testing.assert_allclose(models.distance_var[s], d.var(0), atol=1e-5)
        np.testing.assert_allclose(table.last_distance[s], d[-1], atol=1e-5)
        np.testing.assert_array_equal(table.pool.wins[s], wins[s])
        np.testing.assert_array_equal(table.features[s, :M], current[s])
    assert len(distances[0]) >= 2  # the variances rest on several distances
    _assert_tree_equal(
        jax.tree.map(lambda leaf: leaf[2], table),
        jax.tree.map(lambda leaf: leaf[2], init_table(slots, M, N)),
    )


def test_pool_holds_m_plus_n_distinct_features():
    rng = np.random.default_rng(2)
    table = init_table(4, M, N)
    for _ in range(5):
        target = _random_histograms(rng, (4, NUM_FEATURES), 0.3)
        background = _random_histograms(rng, (4, NUM_FEATURES), 0.3)
        table = _update(table, target, background, jnp.ones(4, bool), PARAMS, num_current=M)
        features = np.asarray(table.features)
        assert features.shape == (4, M + N)
        assert np.all((features >= 0) & (features < NUM_FEATURES))
        assert all(len(set(row)) == M + N for row in features)
    # Long-run features: the most frequent winners outside this frame's M best.
    wins = np.asarray(table.pool.wins)
    for row, counts in zip(features, wins, strict=True):
        rest = np.setdiff1d(np.arange(NUM_FEATURES), row[:M])
        assert counts[row[M:]].min() >= np.sort(counts[rest])[-N]


def test_frozen_slots_and_empty_boxes_are_unchanged():
    rng = np.random.default_rng(3)
    table = init_table(3, M, N)
    target = _random_histograms(rng, (3, NUM_FEATURES), 0.5)
    background = _random_histograms(rng, (3, NUM_FEATURES), 0.5)
    table = _update(table, target, background, jnp.ones(3, bool), PARAMS, num_current=M)
    new_target = _random_histograms(rng, (3, NUM_FEATURES), 0.5)
    new_target[2] = 0.0  # box outside the image
    after = _update(
        table, new_target, background, jnp.array([True, False, True]), PARAMS, num_current=M
    )
    for s in (1, 2):
        _assert_tree_equal(
            jax.tree.map(lambda leaf, s=s: leaf[s], after),
            jax.tree.map(lambda leaf, s=s: leaf[s], table),
        )
    assert float(after.models.count[0, 0]) == 2.0
    assert not np.allclose(after.models.histogram[0], table.models.histogram[0])


def test_reset_slots_makes_the_next_histogram_the_model():
    rng = np.random.default_rng(4)
    target = _random_histograms(rng, (2, NUM_FEATURES), 0.5)
    background = _random_histograms(rng, (2, NUM_FEATURES), 0.5)
    table = init_table(2, M, N)
    for _ in range(3):
        table = _update(table, target, background, jnp.ones(2, bool), PARAMS, num_current=M)
    reset = jax.jit(reset_slots)(table, jnp.array([False, True]))
    _assert_tree_equal(
        jax.tree.map(lambda leaf: leaf[0], reset), jax.tree.map(lambda leaf: leaf[0], table)
    )
    assert float(reset.models.count[1].max()) == 0.0 and np.all(reset.features[1] == -1)
    assert float(reset.pool.wins[1].max()) == 0.0
    first = _random_histograms(rng, (2, NUM_FEATURES), 0.5)
    after = _update(reset, first, background, jnp.array([False, True]), PARAMS, num_current=M)
    np.testing.assert_allclose(after.models.histogram[1], first[1], atol=1e-6)
    np.testing.assert_array_equal(after.models.count[1], 1.0)
    assert float(after.pool.wins[1].sum()) == M


def test_bad_pool_sizes_are_input_errors():
    with pytest.raises(InputError, match="M = 0"):
        init_table(2, 0, 3)
    with pytest.raises(InputError, match="M \\+ N"):
        init_table(2, 30, 20)
    table = init_table(2, M, N)
    hist = jnp.zeros((2, NUM_FEATURES, NUM_BINS))
    with pytest.raises(InputError, match="N = -1"):
        update_appearance(table, hist, hist, jnp.ones(2, bool), PARAMS, num_current=M + N + 1)
    with pytest.raises(InputError, match="background histograms"):
        update_appearance(table, hist, hist[:1], jnp.ones(2, bool), PARAMS, num_current=M)
    lost = jnp.ones(2, bool)
    with pytest.raises(InputError, match="pools"):
        association_distances(table, lost, hist, table.features[:, :2], lost, PARAMS)


# --- re-association ------------------------------------------------------------------------

BACKGROUND = (110, 110, 110)
RED, GREEN, LILAC = (200, 50, 50), (50, 200, 60), (190, 190, 250)
BOXES = jnp.array([[2, 3, 12, 18], [20, 3, 12, 18], [38, 3, 12, 18]], jnp.float32)


def _scene(rng, colours):
    """A 48 x 64 frame of noisy targets (+-20 per channel) in BOXES' places, and the
    background image."""
    frame = np.zeros((48, 64, 3), np.int64)
    frame[...] = BACKGROUND
    for box, colour in zip(np.asarray(BOXES, int), colours, strict=False):
        x, y, w, h = box
        frame[y : y + h, x : x + w] = np.asarray(colour) + rng.integers(-20, 21, (h, w, 3))
    background = np.zeros((48, 64, 3), np.uint8)
    background[...] = BACKGROUND
    return jnp.asarray(np.clip(frame, 0, 255).astype(np.uint8)), jnp.asarray(background)


def _learn(table, rng, colours, slots, frames):
    """Updates ``slots`` with ``frames`` noisy views of targets ``colours`` (box k <- slot k)."""
    update = jnp.zeros(table.features.shape[0], bool).at[jnp.asarray(slots)].set(True)
    for _ in range(frames):
        frame, background = _scene(rng, colours)
        index = jnp.asarray(slots)
        target = (
            jnp.zeros_like(table.models.histogram)
            .at[index]
            .set(_histograms(frame, BOXES[: len(slots)], patch_shape=PATCH))
        )
        behind = (
            jnp.zeros_like(target)
            .at[index]
            .set(_histograms(background, BOXES[: len(slots)], patch_shape=PATCH))
        )
        table = _update(table, target, behind, update, PARAMS, num_current=M)
    return table


def _learn_candidates(colours):
    """Slots 0-1: red and green, lost after 8 frames; then one candidate slot per colour,
    learnt on 3 frames."""
    rng = np.random.default_rng(5)
    lost_table = _learn(init_table(2, M, N), rng, (RED, GREEN), [0, 1], 8)
    new_table = _learn(init_table(len(colours), M, N), rng, colours, list(range(len(colours))), 3)
    table = jax.tree.map(lambda a, b: jnp.concatenate([a, b]), lost_table, new_table)
    lost = jnp.arange(2 + len(colours)) < 2
    return table, lost


def _match(table, lost, params=PARAMS):
    distance, gated = _distances(table, lost, table.models.histogram, table.features, ~lost, params)
    return distance, gated, np.asarray(_reassociate(distance, gated))


def test_lost_targets_are_matched_to_their_own_candidates():
    table, lost = _learn_candidates((GREEN, RED))  # swapped order
    distance, gated, match = _match(table, lost)
    np.testing.assert_array_equal(match, [3, 2, -1, -1])
    assert bool(gated[0, 3]) and bool(gated[1, 2])
    assert float(distance[0, 3]) < float(distance[0, 2])
    assert float(distance[1, 2]) < float(distance[1, 3])
    assert not np.any(gated[2:]) and not np.any(gated[:, :2])


def test_candidate_of_a_third_colour_is_not_gated():
    table, lost = _learn_candidates((LILAC,))
    distance, gated, match = _match(table, lost)
    assert not np.any(gated)
    assert np.all(np.isinf(distance))
    np.testing.assert_array_equal(match, [-1, -1, -1])


def test_no_coincident_features_means_no_match():
    table, lost = _learn_candidates((RED,))
    own = np.asarray(table.features[0])
    others = np.setdiff1d(np.arange(NUM_FEATURES), np.asarray(table.features[:2]))[: M + N]
    features = table.features.at[2].set(jnp.asarray(others, jnp.int32))
    # The candidate's histograms are the lost red model itself: only the pools keep them apart.
    hist = table.models.histogram.at[2].set(table.models.histogram[0])
    distance, gated = _distances(table, lost, hist, features, ~lost, PARAMS)
    assert not np.any(gated) and np.all(np.isinf(distance))
    same_pool = table.features.at[2].set(jnp.asarray(own))
    _, gated = _distances(table, lost, hist, same_pool, ~lost, PARAMS)
    assert bool(gated[0, 2])


def test_lost_model_needs_min_updates():
    table, lost = _learn_candidates((GREEN, RED))
    _, gated, match = _match(table, lost, PARAMS._replace(min_updates=jnp.float32(9)))
    assert not np.any(gated)
    np.testing.assert_array_equal(match, [-1] * 4)


def test_own_track_gate_is_the_diagonal_of_the_association_gate():
    # Slots 0-1 (red, green models) against their own slot's box, drawn red, green, lilac.
    rng = np.random.default_rng(8)
    table = _learn(init_table(2, M, N), rng, (RED, GREEN), [0, 1], 8)
    frame, _ = _scene(rng, (RED, LILAC))
    drawn = _histograms(frame, BOXES[:2], patch_shape=PATCH)  # slot 0 red, slot 1 lilac
    every = jnp.ones(2, bool)
    gated, testable = jax.jit(own_track_gate)(table, drawn, PARAMS)
    _, pairs = _distances(table, every, drawn, table.features, every, PARAMS)
    np.testing.assert_array_equal(gated, np.diagonal(np.asarray(pairs)))
    assert gated.tolist() == [True, False] and testable.tolist() == [True, True]
    # by hand: a feature is within the gate when d <= mu + k max(sigma, sigma_min)
    models = table.models
    for s in range(2):
        pool = np.asarray(table.features[s])
        bc = np.sum(np.sqrt(np.asarray(models.histogram[s, pool] * drawn[s, pool])), axis=-1)
        d = np.sqrt(np.maximum(1.0 - bc, 0.0))
        spread = np.maximum(
            np.sqrt(np.maximum(np.asarray(models.distance_var[s, pool]), 0)), float(PARAMS.min_std)
        )
        bar = np.asarray(models.distance_mean[s, pool]) + float(PARAMS.gate_sigmas) * spread
        assert bool(np.any(d <= bar + 1e-6)) == bool(gated[s])
    # a model short of min_updates tests nothing: not testable, not gated
    strict = PARAMS._replace(min_updates=jnp.float32(9))
    gated, testable = own_track_gate(table, drawn, strict)
    assert not np.any(testable) and not np.any(gated)


def test_two_lost_trackers_gating_one_candidate_match_one_to_one():
    table, lost = _learn_candidates((RED,))
    # Slot 1 becomes a second red tracker, a little further from the candidate than slot 0.
    table = jax.tree.map(lambda leaf: leaf.at[1].set(leaf[0]), table)
    hist = table.models.histogram.at[1].set(0.9 * table.models.histogram[0] + 0.1 / NUM_BINS)
    table = table._replace(models=table.models._replace(histogram=hist))
    distance, gated, match = _match(table, lost)
    assert bool(gated[0, 2]) and bool(gated[1, 2])
    assert float(distance[0, 2]) < float(distance[1, 2])
    np.testing.assert_array_equal(match, [2, -1, -1])


def _greedy_reference(distance, gated):
    cost = np.where(gated, distance, np.inf)
    match = np.full(cost.shape[0], -1)
    while np.isfinite(cost).any():
        row, col = np.unravel_index(np.argmin(cost), cost.shape)
        match[row] = col
        cost[row, :] = np.inf
        cost[:, col] = np.inf
    return match


@pytest.mark.parametrize("shape", [(5, 3), (3, 5), (4, 4)])
def test_reassociate_equals_greedy_loop(shape):
    rng = np.random.default_rng(shape[0] * 10 + shape[1])
    for _ in range(20):
        distance = rng.random(shape).astype(np.float32)
        gated = rng.random(shape) < 0.5
        expected = _greedy_reference(distance, gated)
        np.testing.assert_array_equal(_reassociate(distance, gated), expected)
    assert np.array_equal(reassociate(jnp.asarray(distance), jnp.asarray(gated)), expected)  # eager


# --- jit, vmap ----------------------------------------------------------------------------


def test_jit_equals_eager():
    rng = np.random.default_rng(6)
    table = init_table(2, M, N)
    target = _random_histograms(rng, (2, NUM_FEATURES), 0.5)
    background = _random_histograms(rng, (2, NUM_FEATURES), 0.5)
    update = jnp.array([True, False])
    for _ in range(2):
        jitted = _update(table, target, background, update, PARAMS, num_current=M)
        eager = update_appearance(table, target, background, update, PARAMS, num_current=M)
        for a, b in zip(jax.tree.leaves(jitted), jax.tree.leaves(eager), strict=True):
            np.testing.assert_allclose(a, b, atol=1e-6)
        table = jitted
    lost = jnp.array([True, False])
    jitted = _distances(table, lost, table.models.histogram, table.features, ~lost, PARAMS)
    eager = association_distances(
        table, lost, table.models.histogram, table.features, ~lost, PARAMS
    )
    for a, b in zip(jitted, eager, strict=True):
        np.testing.assert_allclose(a, b, atol=1e-6)
    frame, _ = _scene(rng, (RED,))
    np.testing.assert_allclose(
        _histograms(frame, BOXES, patch_shape=PATCH),
        box_histograms(frame, BOXES, patch_shape=PATCH),
        atol=1e-6,
    )


def test_vmap_over_parameter_sets_equals_loop():
    rng = np.random.default_rng(7)
    targets = _random_histograms(rng, (3, 2, NUM_FEATURES), 0.5)
    backgrounds = _random_histograms(rng, (3, 2, NUM_FEATURES), 0.5)
    params = AppearanceParams(
        delta=jnp.array([1e-3, 1e-2]),
        gate_sigmas=jnp.array([3.0, 1.0]),
        min_std=jnp.array([0.05, 0.01]),
        min_updates=jnp.array([2.0, 3.0]),
        rate_floor=jnp.array([0.0, 0.5]),
    )

    def run(p):
        table = init_table(2, M, N)
        for t in range(3):
            table = update_appearance(
                table, targets[t], backgrounds[t], jnp.ones(2, bool), p, num_current=M
            )
        lost = jnp.array([True, False])
        return table, association_distances(
            table, lost, jnp.asarray(targets[0]), table.features, ~lost, p
        )

    batched = jax.jit(jax.vmap(run))(params)
    for i in range(2):
        single = run(jax.tree.map(lambda leaf, i=i: leaf[i], params))
        for a, b in zip(jax.tree.leaves(batched), jax.tree.leaves(single), strict=True):
            np.testing.assert_allclose(np.asarray(a)[i], b, atol=1e-5)
    # The two parameter sets give different models (rate floor 0.5 forgets faster).
    assert not np.allclose(batched[0].models.histogram[0], batched[0].models.histogram[1])
