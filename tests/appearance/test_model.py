"""Appearance model: recursive means and distance statistics against explicit weighted sums."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.appearance import (
    bhattacharyya_distance,
    init_model,
    update_model,
    within_gate,
)

RNG = np.random.default_rng(9)
_update = jax.jit(update_model)


def _histograms(frames, shape=(2, 16)):
    counts = RNG.uniform(0, 1, (frames, *shape)) + 0.2 * np.arange(shape[-1])
    return (counts / counts.sum(-1, keepdims=True)).astype(np.float32)


def _run(histograms, occluded, beta):
    model = init_model(jnp.asarray(histograms[0]))
    for t in range(1, len(histograms)):
        model = _update(model, jnp.asarray(histograms[t]), jnp.asarray(occluded[t]), beta)
    return model


def _reference(histograms, used, beta):
    """Recursive mean and distance statistics written as explicit weighted sums.

    With rates r_1 = 1, r_n = max(1 / n, beta), item i ends with weight
    r_i prod_{j > i} (1 - r_j): the mean of the histograms, and the mean and variance of
    the distances (each distance taken to the model before its update).
    """
    kept = [h.astype(np.float64) for h, u in zip(histograms, used, strict=True) if u]
    means, distances = [kept[0]], []
    for h in kept[1:]:
        distances.append(np.sqrt(np.maximum(1 - np.sqrt(means[-1] * h).sum(-1), 0)))
        rate = max(1 / (len(means) + 1), beta)
        means.append((1 - rate) * means[-1] + rate * h)

    def weights(count):
        rates = [max(1 / n, beta) if n > 1 else 1.0 for n in range(1, count + 1)]
        return np.array([rates[i] * np.prod([1 - r for r in rates[i + 1 :]]) for i in range(count)])

    w = weights(len(kept))
    mean_histogram = np.tensordot(w, np.stack(kept), axes=1)
    d = np.stack(distances)
    wd = weights(len(distances))
    distance_mean = np.tensordot(wd, d, axes=1)
    distance_var = np.tensordot(wd, (d - distance_mean) ** 2, axes=1)
    return mean_histogram, distance_mean, distance_var, len(kept)


@pytest.mark.parametrize("beta", [0.0, 0.25])
def test_recursive_means_match_weighted_sums(beta):
    histograms = _histograms(12)
    occluded = np.zeros(12, bool)
    occluded[[4, 5, 9]] = True
    model = _run(histograms, occluded, beta)
    mean_histogram, distance_mean, distance_var, count = _reference(histograms, ~occluded, beta)
    np.testing.assert_allclose(model.histogram, mean_histogram, atol=1e-6)
    np.testing.assert_allclose(model.distance_mean, distance_mean, atol=1e-6)
    np.testing.assert_allclose(model.distance_var, distance_var, atol=1e-6)
    np.testing.assert_array_equal(model.count, count)


def test_cumulative_mean_is_numpy_mean():
    histograms = _histograms(8)
    model = _run(histograms, np.zeros(8, bool), 0.0)
    np.testing.assert_allclose(model.histogram, histograms.mean(0), atol=1e-6)
    # The distances to the running means, recomputed directly: Welford = np.mean / np.var.
    distances = [
        np.sqrt(np.maximum(1 - np.sqrt(histograms[:t].mean(0) * histograms[t]).sum(-1), 0))
        for t in range(1, 8)
    ]
    np.testing.assert_allclose(model.distance_mean, np.mean(distances, 0), atol=1e-6)
    np.testing.assert_allclose(model.distance_var, np.var(distances, 0), atol=1e-6)


def test_occluded_or_empty_updates_change_nothing():
    histograms = _histograms(3)
    model = _update(init_model(jnp.asarray(histograms[0])), histograms[1], False, 0.1)
    for frozen in (
        _update(model, jnp.asarray(histograms[2]), jnp.asarray(True), 0.1),
        _update(model, jnp.zeros((2, 16)), jnp.asarray(False), 0.1),
    ):
        for before, after in zip(model, frozen, strict=True):
            np.testing.assert_array_equal(before, after)
    empty = init_model(jnp.zeros(16))
    assert float(empty.count) == 0.0
    first = _update(empty, jnp.asarray(histograms[0, 0]), jnp.asarray(False), 0.1)
    np.testing.assert_allclose(first.histogram, histograms[0, 0], atol=1e-7)
    assert float(first.count) == 1.0 and float(first.distance_mean) == 0.0


def test_gate():
    histograms = _histograms(10, (16,))
    model = _run(histograms, np.zeros(10, bool), 0.0)
    spread = float(np.sqrt(model.distance_var))
    assert spread > 0.0
    near = histograms.mean(0)
    far = np.eye(16)[0]
    distance_far = float(bhattacharyya_distance(model.histogram, far))
    assert bool(within_gate(model, near, 3.0, 0.0))
    assert not bool(within_gate(model, far, 3.0, 0.0))
    # The floor on the spread opens the gate: d <= mean + k sigma_min.
    floor = (distance_far - float(model.distance_mean)) / 3.0 + 1e-3
    assert bool(within_gate(model, far, 3.0, floor))
