"""Intensity PyTree: densities against SciPy, integrals, sampling, gradients."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from scipy.stats import multivariate_normal

from jaxtrack.context.intensity import (
    Intensity,
    log_density,
    log_intensity,
    sample,
    uniform_intensity,
)


def mixture(uniform_weight=0.2):
    rng = np.random.default_rng(0)
    dim = 3
    means = rng.uniform(35, 65, (4, dim))
    factors = rng.normal(size=(4, dim, dim))
    covs = 4 * factors @ factors.transpose(0, 2, 1) + 40 * np.eye(dim)
    weights = np.array([0.5, 0.0, 0.3, 0.2])  # component 1 is dead
    return Intensity(
        magnitude=jnp.asarray(3.0),
        uniform_weight=jnp.asarray(uniform_weight),
        lower=jnp.zeros(dim),
        upper=jnp.full(dim, 100.0),
        weights=jnp.asarray(weights, jnp.float32),
        means=jnp.asarray(means, jnp.float32),
        covs=jnp.asarray(covs, jnp.float32),
    )


def reference_density(intensity, x):
    x = np.asarray(x, np.float64)
    volume = np.prod(np.asarray(intensity.upper) - np.asarray(intensity.lower))
    pi_u = float(intensity.uniform_weight)
    total = np.full(x.shape[0], pi_u / volume)
    for w, m, c in zip(intensity.weights, intensity.means, intensity.covs, strict=True):
        if w > 0:
            total += (
                (1 - pi_u) * float(w) * multivariate_normal(np.asarray(m), np.asarray(c)).pdf(x)
            )
    return total


def test_uniform_value():
    u = uniform_intensity(2.5, [0, 0, 10, 10], [768, 576, 200, 400])
    x = jnp.array([[1.0, 2, 30, 40], [700, 500, 100, 100]])
    expected = np.log(2.5 / (768 * 576 * 190 * 390))
    np.testing.assert_allclose(log_intensity(u, x), [expected, expected], rtol=1e-6)


def test_mixture_density_matches_scipy():
    intensity = mixture()
    x = np.random.default_rng(1).uniform(0, 100, (50, 3))
    np.testing.assert_allclose(
        np.exp(log_density(intensity, jnp.asarray(x))), reference_density(intensity, x), rtol=2e-4
    )
    # batch shape is preserved
    assert log_density(intensity, jnp.zeros((2, 5, 3))).shape == (2, 5)


def test_intensity_integrates_to_magnitude():
    intensity = mixture()
    key = jax.random.PRNGKey(0)
    points = jax.random.uniform(key, (400_000, 3), minval=0.0, maxval=100.0)
    integral = float(jnp.mean(jnp.exp(log_intensity(intensity, points)))) * 100.0**3
    # all Gaussians lie well inside the volume: the integral is the magnitude (MC error ~1%)
    np.testing.assert_allclose(integral, 3.0, rtol=0.03)


def test_sampling_moments():
    intensity = mixture(uniform_weight=0.3)
    draws = np.asarray(sample(jax.random.PRNGKey(2), intensity, 200_000))
    w = np.asarray(intensity.weights)
    expected_mean = 0.3 * 50.0 + 0.7 * (w[:, None] * np.asarray(intensity.means)).sum(0)
    np.testing.assert_allclose(draws.mean(0), expected_mean, atol=0.3)


def test_gradients_finite_with_dead_components_and_pure_uniform():
    intensity = mixture()
    x = jnp.asarray(np.random.default_rng(3).uniform(0, 100, (10, 3)), jnp.float32)
    grads = jax.grad(lambda p: jnp.sum(log_intensity(p, x)))(intensity)
    for leaf in jax.tree_util.tree_leaves(grads):
        assert np.all(np.isfinite(leaf))
    assert float(jnp.abs(grads.means[0]).sum()) > 0
    pure = intensity._replace(uniform_weight=jnp.asarray(1.0))
    grads = jax.grad(lambda p: jnp.sum(log_intensity(p, x)))(pure)
    for leaf in jax.tree_util.tree_leaves(grads):
        assert np.all(np.isfinite(leaf))
    np.testing.assert_allclose(grads.magnitude, 10 / 3.0, rtol=1e-6)
