"""CMT's contextual observation model (eqs. 11-17) against NumPy loops and drawn scenes."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.errors import InputError
from jaxtrack.filters.cmt_observation import (
    NUM_LEVELS,
    NUM_VALUES,
    STEP,
    AppearanceState,
    COMParams,
    appearance_log_likelihood,
    box_features,
    default_com_params,
    drop_weak_features,
    init_appearance,
    likelihood_gap,
    num_features,
    observation_weights,
    update_appearance,
)

PATCH = (16, 8)
F = num_features(STEP)  # 8 buckets per channel: 2 x 3 x 8 + 1 = 49
BINS = 8
SHAPE = F - 1
# Compiled once per static configuration (eager dispatch of these is slow).
_features = jax.jit(jax.vmap(box_features, in_axes=(None, 0, None, None)), static_argnums=(2, 3))
_weights = jax.jit(observation_weights, static_argnums=(5, 6))
_update = jax.jit(update_appearance)
_log_likelihood = jax.jit(appearance_log_likelihood)
_gap = jax.jit(likelihood_gap)


def _bucket(half: int, channel: int, value: int) -> int:
    """Feature index of the bucket holding channel ``value`` in half 0 (top) or 1 (bottom)."""
    return (half * 3 + channel) * BINS + value // int(STEP)


def _person(frame, box, top, bottom, rng=None, noise=0.0):
    """Draws a box with uniform top and bottom colours (plus Gaussian noise) into ``frame``."""
    x, y, w, h = (int(v) for v in box)
    for rows, colour in ((slice(y, y + h // 2), top), (slice(y + h // 2, y + h), bottom)):
        patch = np.broadcast_to(np.asarray(colour, float), (rows.stop - rows.start, w, 3))
        if noise:
            patch = patch + rng.normal(0.0, noise, patch.shape)
        frame[rows, x : x + w] = np.clip(np.rint(patch), 0, 255)


def _features_loop(frame, box, step, patch_shape):
    """The feature pool by a loop over the sample grid: nearest pixel at each cell centre."""
    rows, cols = patch_shape
    height, width = frame.shape[:2]
    bins = math.ceil(256 / step)
    counts = np.zeros((2, 3, bins))
    for i in range(rows):
        for j in range(cols):
            sy = box[1] + (i + 0.5) * box[3] / rows
            sx = box[0] + (j + 0.5) * box[2] / cols
            if not (0 <= sy < height and 0 <= sx < width):
                continue
            for c in range(3):
                counts[
                    int(i >= rows // 2), c, min(int(frame[int(sy), int(sx), c] // step), bins - 1)
                ] += 1
    totals = counts.sum(axis=2, keepdims=True)
    histograms = np.divide(counts, totals, out=np.zeros_like(counts), where=totals > 0)
    return np.concatenate([histograms.ravel(), [box[2] / (box[2] + box[3])]])


def _log_likelihood_loop(features, model, initialised, rho, sigma):
    """Eq. 11 term by term: ``log sum_k rho_k N(f_k; mu_k, sigma^2)``."""
    out = np.zeros(features.shape[:2])
    for m in range(features.shape[0]):
        if not initialised[m]:
            continue
        for n in range(features.shape[1]):
            total = 0.0
            for k in range(features.shape[2]):
                z = (features[m, n, k] - model[m, k]) / sigma
                total += rho[m, k] * math.exp(-0.5 * z * z) / (sigma * math.sqrt(2 * math.pi))
            out[m, n] = math.log(total)
    return out


def test_box_features_exact_buckets_of_uniform_halves():
    frame = np.zeros((60, 50, 3), np.uint8)
    box = np.array([10.0, 8.0, 16.0, 40.0], np.float32)
    top, bottom = (200, 30, 100), (20, 140, 250)
    _person(frame, box, top, bottom)
    got = np.asarray(_features(jnp.asarray(frame), jnp.asarray(box[None]), STEP, PATCH))[0]
    want = np.zeros(F)
    for half, colour in enumerate((top, bottom)):
        for channel, value in enumerate(colour):
            want[_bucket(half, channel, value)] = 1.0
    want[SHAPE] = 16.0 / 56.0
    np.testing.assert_allclose(got, want, atol=1e-6)


def test_box_features_match_pixel_loop_inside_and_across_the_border():
    rng = np.random.default_rng(3)
    frame = rng.integers(0, 256, (48, 64, 3), dtype=np.uint8)
    boxes = np.array(
        [
            [5.3, 2.7, 20.5, 41.0],  # inside
            [-6.0, 10.0, 14.0, 30.0],  # left part outside
            [50.0, 30.0, 20.0, 40.0],  # bottom-right part outside: its bottom half is empty
            [100.0, 100.0, 10.0, 20.0],  # wholly outside: only the shape feature
        ],
        np.float32,
    )
    got = np.asarray(_features(jnp.asarray(frame), jnp.asarray(boxes), 24.0, (6, 4)))
    want = np.stack([_features_loop(frame, box, 24.0, (6, 4)) for box in boxes])
    assert got.shape == (4, 2 * 3 * 11 + 1)
    np.testing.assert_allclose(got, want, atol=1e-6)
    assert np.all(got[3, :-1] == 0.0)


def test_box_features_reject_bad_input():
    frame = jnp.zeros((20, 20, 3), jnp.uint8)
    box = jnp.array([1.0, 1.0, 5.0, 10.0])
    with pytest.raises(InputError, match="even"):
        box_features(frame, box, STEP, (5, 4))
    with pytest.raises(InputError, match="uint8"):
        box_features(frame.astype(jnp.float32), box, STEP, PATCH)
    with pytest.raises(InputError, match="quantisation step"):
        box_features(frame, box, 300.0, PATCH)


def test_appearance_log_likelihood_matches_loop_jit_eager_and_vmap_over_params():
    rng = np.random.default_rng(5)
    components, particles, features = 3, 4, 7
    feats = rng.uniform(0, 1, (components, particles, features)).astype(np.float32)
    model = rng.uniform(0, 1, (components, features)).astype(np.float32)
    rho = rng.uniform(0, 1, (components, features))
    rho[:, :2] = 0.0  # dropped features
    rho = (rho / rho.sum(axis=1, keepdims=True)).astype(np.float32)
    initialised = np.array([True, False, True])
    state = AppearanceState(
        jnp.asarray(model), jnp.zeros((components, features, 4)), jnp.asarray(initialised)
    )
    sigmas = [0.05, 0.1, 0.3]
    stacked = COMParams(*(jnp.full(3, v, jnp.float32) for v in default_com_params()))
    stacked = stacked._replace(feature_std=jnp.asarray(sigmas, jnp.float32))
    batched = jax.vmap(_log_likelihood, in_axes=(None, None, None, 0))(
        jnp.asarray(feats), state, jnp.asarray(rho), stacked
    )
    for index, sigma in enumerate(sigmas):
        want = _log_likelihood_loop(feats, model, initialised, rho, sigma)
        params = default_com_params()._replace(feature_std=jnp.asarray(sigma, jnp.float32))
        jitted = np.asarray(_log_likelihood(jnp.asarray(feats), state, jnp.asarray(rho), params))
        eager = np.asarray(
            appearance_log_likelihood(jnp.asarray(feats), state, jnp.asarray(rho), params)
        )
        np.testing.assert_allclose(jitted, want, rtol=1e-5, atol=1e-4)
        np.testing.assert_allclose(eager, jitted, rtol=1e-6, atol=1e-5)
        np.testing.assert_allclose(np.asarray(batched[index]), jitted, rtol=1e-6, atol=1e-5)
    assert np.all(np.asarray(batched[:, 1]) == 0.0)  # the uninitialised slot


def test_drop_weak_features_matches_loop_and_keeps_the_best():
    rng = np.random.default_rng(9)
    weights = rng.dirichlet(np.full(10, 0.3), size=5).astype(np.float32)
    for score in (0.0, 0.5, 1.0):
        got = np.asarray(drop_weak_features(jnp.asarray(weights), jnp.asarray(score)))
        for row, out in zip(weights, got, strict=True):
            kept = np.where(row >= score / 10, row, 0.0)
            np.testing.assert_allclose(out, kept / kept.sum(), rtol=1e-5, atol=1e-7)
    # A score above 1 would drop every feature of a uniform row: the largest is kept.
    uniform = jnp.full((1, 4), 0.25)
    np.testing.assert_allclose(np.asarray(drop_weak_features(uniform, jnp.asarray(2.0))), uniform)


def _pair_scene(rng, frames, bottoms, noise, size=(70, 90)):
    """Feature vectors of two drawn people (same top, given bottoms) over noisy frames."""
    boxes = np.array([[10.0, 10.0, 16.0, 48.0], [50.0, 12.0, 16.0, 48.0]], np.float32)
    out = []
    for _ in range(frames):
        frame = np.full((*size, 3), 128, np.uint8)
        for box, bottom in zip(boxes, bottoms, strict=True):
            _person(frame, box, (180, 40, 40), bottom, rng, noise)
        out.append(np.asarray(_features(jnp.asarray(frame), jnp.asarray(boxes), STEP, PATCH)))
    return out, boxes


def _learn(feature_frames, params, num_components=2):
    state = init_appearance(num_components, F, NUM_VALUES)
    observed = jnp.ones(num_components, bool)
    frozen = jnp.zeros(num_components, bool)
    for index, features in enumerate(feature_frames):
        born = jnp.full(num_components, index == 0)
        state = _update(state, jnp.asarray(features), observed, frozen, born, params)
    return state


def test_weights_go_to_the_bottom_colour_that_tells_two_targets_apart():
    # Same top, bottom blue 80 vs 176: the bottom B buckets 2 and 5 tell the targets apart.
    params = default_com_params()
    feature_frames, boxes = _pair_scene(
        np.random.default_rng(0), 6, [(60, 60, 80), (60, 60, 176)], 0.0
    )
    state = _learn(feature_frames, params)
    centres = jnp.asarray(boxes[:, :2] + boxes[:, 2:] / 2)
    alive = jnp.ones(2, bool)
    rho = np.asarray(_weights(state.counts, centres, alive, 100.0, params, NUM_LEVELS, True))
    telling = [_bucket(1, 2, 80), _bucket(1, 2, 176)]
    np.testing.assert_allclose(rho[:, telling].sum(axis=1), 1.0, atol=1e-5)
    np.testing.assert_allclose(rho[:, telling], 0.5, atol=1e-5)
    assert np.all(rho[:, SHAPE] < 1e-6)  # same box shape: no information
    # Out of each other's field of context (radius below their 40 px distance): uniform.
    alone = np.asarray(_weights(state.counts, centres, alive, 30.0, params, NUM_LEVELS, True))
    np.testing.assert_allclose(alone, 1.0 / F, rtol=1e-6)
    # One radius per target: target 0 reaches target 1, target 1 does not reach target 0.
    mixed = np.asarray(
        _weights(state.counts, centres, alive, jnp.array([50.0, 30.0]), params, NUM_LEVELS, True)
    )
    np.testing.assert_allclose(mixed[0], rho[0], atol=1e-6)
    np.testing.assert_allclose(mixed[1], 1.0 / F, rtol=1e-6)
    # A dead neighbour is not context.
    dead = np.asarray(
        _weights(state.counts, centres, jnp.array([True, False]), 100.0, params, NUM_LEVELS, True)
    )
    np.testing.assert_allclose(dead[0], 1.0 / F, rtol=1e-6)
    # EWOM: uniform whatever the context.
    ewom = np.asarray(_weights(state.counts, centres, alive, 100.0, params, NUM_LEVELS, False))
    np.testing.assert_allclose(ewom, 1.0 / F, rtol=1e-6)


def test_threshold_drops_the_weakly_informative_features():
    # Noisy bottoms: many features carry a little information; the threshold removes them.
    params = default_com_params()
    feature_frames, boxes = _pair_scene(
        np.random.default_rng(1), 12, [(60, 60, 90), (60, 60, 120)], 12.0
    )
    state = _learn(feature_frames, params)
    centres = jnp.asarray(boxes[:, :2] + boxes[:, 2:] / 2)
    alive = jnp.ones(2, bool)
    keep_all = params._replace(min_feature_score=jnp.asarray(0.0))
    raw = np.asarray(_weights(state.counts, centres, alive, 100.0, keep_all, NUM_LEVELS, True))
    kept = np.asarray(_weights(state.counts, centres, alive, 100.0, params, NUM_LEVELS, True))
    weak = raw < 0.5 / F
    assert np.any(weak & (raw > 0))  # some features were weakly informative
    assert np.all(kept[weak] == 0.0)
    np.testing.assert_allclose(
        kept[~weak], (raw / np.sum(np.where(weak, 0, raw), axis=1, keepdims=True))[~weak], rtol=1e-5
    )


def test_update_appearance_matches_loop():
    rng = np.random.default_rng(11)
    components, features, values, frames = 4, 5, 8, 6
    params = default_com_params()._replace(decay=jnp.asarray(0.3), model_rate=jnp.asarray(0.25))
    state = init_appearance(components, features, values)
    model = np.zeros((components, features))
    counts = np.zeros((components, features, values))
    initialised = np.zeros(components, bool)
    for t in range(frames):
        f = rng.uniform(0, 1, (components, features)).astype(np.float32)
        observed = rng.uniform(size=components) < 0.8
        frozen = rng.uniform(size=components) < 0.3
        born = np.array([t == 0, t == 3, False, t == 4])
        frozen[3] |= t == 4  # born while frozen: born wins
        state = _update(
            state,
            jnp.asarray(f),
            jnp.asarray(observed),
            jnp.asarray(frozen),
            jnp.asarray(born),
            params,
        )
        for m in range(components):
            if born[m]:
                model[m], counts[m], initialised[m] = f[m], 0.0, True
            if frozen[m] and not born[m]:
                continue
            counts[m] *= math.exp(-0.3)
            if not observed[m]:
                continue
            if initialised[m] and not born[m]:
                model[m] = model[m] + 0.25 * (f[m] - model[m])
            else:
                model[m], initialised[m] = f[m], True
            for k in range(features):
                counts[m, k, min(int(f[m, k] * values), values - 1)] += 1.0
        np.testing.assert_allclose(np.asarray(state.model), model, rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(np.asarray(state.counts), counts, rtol=1e-5, atol=1e-6)
        np.testing.assert_array_equal(np.asarray(state.initialised), initialised)


def test_com_tells_similar_targets_apart_better_than_ewom():
    # CMT Fig. 9: same top, bottoms 20 apart in blue, pixel noise 10: under COM each target's
    # own box scores far above the other's; under EWOM the 2-of-49 differing buckets barely
    # count.
    params = default_com_params()
    rng = np.random.default_rng(2)
    learned, boxes = _pair_scene(rng, 20, [(60, 60, 84), (60, 60, 104)], 10.0)
    state = _learn(learned, params)
    test_frames, _ = _pair_scene(rng, 5, [(60, 60, 84), (60, 60, 104)], 10.0)
    centres = jnp.asarray(boxes[:, :2] + boxes[:, 2:] / 2)
    alive = jnp.ones(2, bool)
    gaps = {}
    for contextual in (True, False):
        rho = _weights(state.counts, centres, alive, 100.0, params, NUM_LEVELS, contextual)
        gaps[contextual] = np.array(
            [
                np.asarray(_gap(jnp.asarray(f), jnp.asarray(f[::-1]), state, rho, params))
                for f in test_frames
            ]
        )
    assert np.all(gaps[True] > 1.0)  # COM: own box at least e times as likely, every frame
    assert np.all(gaps[True] > 5.0 * np.abs(gaps[False]))
    eager = likelihood_gap(
        jnp.asarray(test_frames[0]),
        jnp.asarray(test_frames[0][::-1]),
        state,
        observation_weights(state.counts, centres, alive, 100.0, params, NUM_LEVELS, True),
        params,
    )
    np.testing.assert_allclose(np.asarray(eager), gaps[True][0], rtol=1e-5)


def test_observation_weights_jit_equals_eager():
    params = default_com_params()
    feature_frames, boxes = _pair_scene(
        np.random.default_rng(4), 4, [(60, 60, 90), (60, 60, 120)], 8.0
    )
    state = _learn(feature_frames, params)
    centres = jnp.asarray(boxes[:, :2] + boxes[:, 2:] / 2)
    args = (state.counts, centres, jnp.ones(2, bool), 100.0, params, NUM_LEVELS, True)
    np.testing.assert_allclose(
        np.asarray(observation_weights(*args)), np.asarray(_weights(*args)), rtol=1e-5, atol=1e-7
    )
