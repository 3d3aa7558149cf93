"""CMT feature weights (eq. 13-17) against NumPy loops over histograms and analytic cases."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.appearance import (
    decay_update,
    feature_values,
    feature_weights,
    field_of_context,
    multiresolution_mutual_information,
    mutual_information,
    quantise_values,
)
from jaxtrack.errors import InputError

RNG = np.random.default_rng(7)
_mutual_information = jax.jit(mutual_information)
_multiresolution = jax.jit(multiresolution_mutual_information, static_argnums=2)


def _mi_loop(counts, classes):
    """Eq. 13 by frequency counting, one term at a time."""
    kept = [u for u in range(counts.shape[0]) if classes[u]]
    total = sum(counts[u, v] for u in kept for v in range(counts.shape[1]))
    if total == 0:
        return 0.0
    information = 0.0
    for u in kept:
        p_u = sum(counts[u, v] for v in range(counts.shape[1])) / total
        for v in range(counts.shape[1]):
            p_v = sum(counts[w, v] for w in kept) / total
            p_uv = counts[u, v] / total
            if p_uv > 0:
                information += p_uv * math.log(p_uv / (p_u * p_v))
    return information


def _multilevel_loop(counts, classes, levels):
    """Eq. 17: level r puts value v in bin v // 2^r."""
    information = 0.0
    for r in range(levels):
        merged = np.zeros((counts.shape[0], counts.shape[1] // 2**r))
        for u in range(counts.shape[0]):
            for v in range(counts.shape[1]):
                merged[u, v // 2**r] += counts[u, v]
        information += _mi_loop(merged, classes) / 2**r
    return information


def test_decay_update_is_eq_15():
    frames, targets, features, values = 9, 4, 3, 8
    bins = RNG.integers(0, values, (frames, targets, features))
    observed = RNG.uniform(0, 1, (frames, targets)) < 0.7
    alpha = 0.3
    counts = jnp.zeros((targets, features, values))
    update = jax.jit(decay_update)
    for t in range(frames):
        counts = update(counts, jnp.asarray(bins[t]), jnp.asarray(observed[t]), alpha)
    expected = np.zeros((targets, features, values))
    for t in range(frames):  # each sample weighs e^(-alpha (T - 1 - t)) at the end
        for u in range(targets):
            if observed[t, u]:
                for k in range(features):
                    expected[u, k, bins[t, u, k]] += math.exp(-alpha * (frames - 1 - t))
    np.testing.assert_allclose(counts, expected, rtol=1e-5)


def test_mutual_information_matches_loop():
    for _ in range(5):
        counts = RNG.uniform(0, 3, (5, 8)) * (RNG.uniform(0, 1, (5, 8)) < 0.5)
        classes = RNG.uniform(0, 1, 5) < 0.7
        got = float(_mutual_information(jnp.asarray(counts), jnp.asarray(classes)))
        assert got == pytest.approx(_mi_loop(counts, classes), abs=1e-5)
        got = float(_multiresolution(jnp.asarray(counts), classes, 3))
        assert got == pytest.approx(_multilevel_loop(counts, classes, 3), abs=1e-5)


def test_mutual_information_analytic_cases():
    both = np.array([True, True])
    separated = np.array([[3.0, 0, 0, 0], [0, 0, 0, 3.0]])  # one feature value per target
    assert float(mutual_information(separated, both)) == pytest.approx(math.log(2), abs=1e-6)
    # Level 1 merges bins {0, 1} and {2, 3}: still separated, so I = log 2 (1 + 1/2).
    got = float(multiresolution_mutual_information(jnp.asarray(separated), both, 2))
    assert got == pytest.approx(1.5 * math.log(2), abs=1e-6)
    same = np.array([[1.0, 2, 0, 1], [2.0, 4, 0, 2]])  # the same distribution, any mass
    assert float(mutual_information(same, both)) == pytest.approx(0.0, abs=1e-6)
    alone = np.array([True, False])
    assert float(mutual_information(separated, alone)) == pytest.approx(0.0, abs=1e-6)
    with pytest.raises(InputError, match="value bins"):
        multiresolution_mutual_information(jnp.ones((2, 6)), both, 3)


def test_field_of_context_loop():
    positions = RNG.uniform(0, 100, (6, 2))
    active = np.array([True, True, True, False, True, True])
    got = np.asarray(field_of_context(jnp.asarray(positions), jnp.asarray(active), 40.0))
    for m in range(6):
        for u in range(6):
            close = m == u or np.linalg.norm(positions[m] - positions[u]) < 40.0
            assert got[m, u] == (close and active[m] and active[u])


def test_feature_weights_match_loop():
    targets, features, values, levels = 5, 4, 8, 3
    counts = RNG.uniform(0, 2, (targets, features, values)) * (
        RNG.uniform(0, 1, (targets, features, values)) < 0.5
    )
    counts[:, 2] = counts[0, 2]  # feature 2 has the same distribution for every target
    context = np.array(
        [
            [1, 1, 0, 1, 0],
            [1, 1, 0, 0, 0],
            [0, 0, 1, 0, 0],  # target 2 is alone: uniform weights
            [1, 0, 0, 1, 1],
            [0, 0, 0, 1, 1],
        ],
        bool,
    )
    got = np.asarray(jax.jit(feature_weights, static_argnums=2)(counts, context, levels))
    for m in range(targets):
        information = np.array(
            [_multilevel_loop(counts[:, k], context[m], levels) for k in range(features)]
        )
        expected = information / information.sum() if information.sum() > 0 else 1 / features
        np.testing.assert_allclose(got[m], expected, atol=1e-5)
    np.testing.assert_allclose(got.sum(1), 1.0, rtol=1e-6)
    assert np.all(got[[0, 1, 3, 4], 2] < 1e-5)  # the shared feature tells nothing


def test_feature_values_layout():
    channel_histograms = RNG.uniform(0, 1, (2, 3, 8))
    box = jnp.array([5.0, 6.0, 30.0, 90.0])
    values = np.asarray(feature_values(jnp.asarray(channel_histograms), box))
    assert values.shape == (49,)
    np.testing.assert_allclose(values[:48], channel_histograms.ravel(), rtol=1e-6)
    assert values[48] == pytest.approx(30 / 120)
    np.testing.assert_array_equal(
        quantise_values(jnp.array([0.0, 0.49, 0.5, 1.0]), 4), [0, 1, 2, 3]
    )
