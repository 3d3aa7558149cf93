"""Bhattacharyya measures against NumPy; Fusion's split against a brute-force loop; halves."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.appearance import (
    aspect_ratio,
    best_split,
    bhattacharyya_coefficient,
    bhattacharyya_distance,
    halves,
    histogram_likelihood,
)
from jaxtrack.errors import InputError

RNG = np.random.default_rng(6)


def _random_histograms(shape):
    counts = RNG.uniform(0, 1, shape) * (RNG.uniform(0, 1, shape) < 0.6)
    return counts / counts.sum(-1, keepdims=True)


def test_bhattacharyya_matches_numpy():
    p, q = _random_histograms((5, 3, 40)), _random_histograms((5, 3, 40))
    coefficient = np.sqrt(p * q).sum(-1)
    np.testing.assert_allclose(bhattacharyya_coefficient(p, q), coefficient, rtol=1e-5)
    np.testing.assert_allclose(bhattacharyya_distance(p, q), np.sqrt(1 - coefficient), rtol=1e-5)
    sigma = 0.3
    np.testing.assert_allclose(
        histogram_likelihood(p, q, sigma), np.exp(-(1 - coefficient) / (2 * sigma**2)), rtol=1e-5
    )


def test_bhattacharyya_limits():
    p = _random_histograms((1, 64))[0]
    disjoint_a, disjoint_b = np.eye(8)[2], np.eye(8)[5]
    assert float(bhattacharyya_distance(p, p)) == pytest.approx(0.0, abs=1e-3)  # sqrt of ulps
    assert float(histogram_likelihood(p, p, 0.2)) == pytest.approx(1.0, abs=1e-5)
    assert float(bhattacharyya_distance(disjoint_a, disjoint_b)) == 1.0
    assert float(bhattacharyya_distance(np.zeros(8), disjoint_a)) == 1.0  # nothing seen


def _split_loop(row_counts, min_rows):
    best_row, best_distance = None, -1.0
    for y in range(min_rows, len(row_counts) - min_rows + 1):
        upper, lower = row_counts[:y].sum(0), row_counts[y:].sum(0)
        distance = np.sqrt(max(1 - np.sqrt(upper / upper.sum() * lower / lower.sum()).sum(), 0))
        if distance > best_distance + 1e-9:
            best_row, best_distance = y, distance
    return best_row, best_distance


@pytest.mark.parametrize("min_rows", [1, 3])
def test_best_split_matches_loop(min_rows):
    for trial in range(5):
        row_counts = RNG.integers(0, 5, (12, 16)).astype(np.float64)
        row_counts[: 3 + trial, :8] *= 4  # some structure, so the maximum is clear
        row, distance = _split_loop(row_counts, min_rows)
        split = jax.jit(best_split, static_argnums=1)(jnp.asarray(row_counts), min_rows)
        assert int(split.row) == row
        assert float(split.distance) == pytest.approx(distance, abs=1e-5)
        upper = row_counts[:row].sum(0)
        np.testing.assert_allclose(split.histograms[0], upper / upper.sum(), rtol=1e-5)


def test_halves_and_shape():
    assert halves(6) == (3,)
    with pytest.raises(InputError, match="even"):
        halves(5)
    with pytest.raises(InputError, match="min_rows"):
        best_split(jnp.ones((6, 4)), 4)
    np.testing.assert_allclose(aspect_ratio(jnp.array([[1.0, 2.0, 30.0, 60.0]])), [0.5])
