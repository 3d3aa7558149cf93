"""Colour spaces against the standard library and explicit formulas; Collins' feature set."""

from __future__ import annotations

import colorsys
import itertools

import jax.numpy as jnp
import numpy as np

from jaxtrack.appearance import (
    LINEAR_COMBINATION_WEIGHTS,
    hsv,
    linear_combinations,
    normalised_rg,
    rgb,
)

RNG = np.random.default_rng(1)
# Random colours plus the corner cases: black, white, greys, pure and tied primaries.
PIXELS = np.concatenate(
    [
        RNG.uniform(0, 255, (200, 3)),
        [[0, 0, 0], [255, 255, 255], [128, 128, 128], [255, 0, 0], [0, 255, 0], [0, 0, 255]],
        [[255, 255, 0], [0, 255, 255], [255, 0, 255], [200, 200, 10], [10, 200, 200]],
    ]
).astype(np.float32)


def test_hsv_matches_colorsys():
    got = np.asarray(hsv(jnp.asarray(PIXELS)))
    expected = np.array([colorsys.rgb_to_hsv(*(p / 255.0)) for p in PIXELS.astype(np.float64)])
    scale = np.array([256.0, 256.0, 255.0])
    hue_gap = np.abs(got[:, 0] - scale[0] * expected[:, 0])
    hue_gap = np.minimum(hue_gap, 256.0 - hue_gap)  # hue is circular
    assert hue_gap.max() < 1e-3
    np.testing.assert_allclose(got[:, 1:], scale[1:] * expected[:, 1:], atol=1e-3)
    assert np.all((got[:, 0] >= 0) & (got[:, 0] < 256))


def test_normalised_rg_formula():
    got = np.asarray(normalised_rg(jnp.asarray(PIXELS)))
    total = PIXELS.astype(np.float64).sum(1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        expected = np.where(total > 0, 256.0 * PIXELS[:, :2] / total, 256.0 / 3.0)
    np.testing.assert_allclose(got, expected, rtol=1e-5)
    np.testing.assert_array_equal(rgb(jnp.asarray(PIXELS)), PIXELS)


def test_collins_feature_set():
    weights = LINEAR_COMBINATION_WEIGHTS.astype(int)
    assert weights.shape == (49, 3)
    # Every non-zero triple in {-2..2}^3 is a multiple of exactly one kept triple.
    for triple in itertools.product(range(-2, 3), repeat=3):
        if any(triple):
            parallel = [w for w in weights if np.linalg.matrix_rank(np.stack([w, triple])) == 1]
            assert len(parallel) == 1, triple
    for raw in ([1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1], [2, -1, -1]):
        assert any(np.array_equal(w, raw) for w in weights)


def test_linear_combinations_loop():
    got = np.asarray(linear_combinations(jnp.asarray(PIXELS)))
    for k, (a, b, c) in enumerate(LINEAR_COMBINATION_WEIGHTS.astype(float)):
        low = 255 * (min(a, 0) + min(b, 0) + min(c, 0))
        high = 255 * (max(a, 0) + max(b, 0) + max(c, 0))
        for i, (red, green, blue) in enumerate(PIXELS.astype(float)):
            expected = 256 * (a * red + b * green + c * blue - low) / (high - low)
            assert abs(got[i, k] - expected) < 1e-3
    assert got.min() >= 0 and got.max() <= 256
