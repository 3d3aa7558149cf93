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


def test_quadratic_form_matches_scipy_at_pixel_scale():
    """The matrix-product evaluation (log_normal_quadratic, used by log_density) against
    SciPy in float64 on a tracker-like 6-D mixture: positions in the hundreds of pixels,
    a covariance with condition number ~1e3, points near the components and far away."""
    from jaxtrack.context.intensity import log_normal_components, log_normal_quadratic

    rng = np.random.default_rng(3)
    dim, num = 6, 5
    low = [100, -4, 100, -4, 30, 60]  # (y1, vy1, y2, vy2, w, h)
    high = [700, 4, 500, 4, 80, 200]
    means = rng.uniform(low, high, (num, dim))
    factors = rng.normal(size=(num, dim, dim))
    covs = factors @ factors.transpose(0, 2, 1) + np.diag([400, 1, 400, 1, 25, 100])
    covs[0] = np.diag([900.0, 0.5, 900.0, 0.5, 4.0, 16.0])
    covs[0, 0, 4] = covs[0, 4, 0] = 0.999 * np.sqrt(900.0 * 4.0)  # nearly singular pair
    near = np.concatenate(
        [rng.multivariate_normal(m, c, 200) for m, c in zip(means, covs, strict=True)]
    )
    far = rng.uniform([0, -20, 0, -20, 5, 5], [768, 20, 576, 20, 300, 400], (500, dim))
    x = np.concatenate([near, far])
    expected = np.column_stack(
        [multivariate_normal(m, c).logpdf(x) for m, c in zip(means, covs, strict=True)]
    )
    args = (jnp.asarray(x, jnp.float32), jnp.asarray(means, jnp.float32))
    covs32 = jnp.asarray(covs, jnp.float32)
    quadratic = np.asarray(log_normal_quadratic(*args, covs32))
    substituted = np.asarray(log_normal_components(*args, covs32))
    assert np.linalg.cond(covs[0]) > 1e3
    close = expected > -60
    assert close.sum() > 500 and (~close).sum() > 500
    error = np.abs(quadratic - expected)
    # The quadratic form's cancellation grows with the condition number: within 1e-3 nats
    # on the well-conditioned components, 2e-2 on the nearly singular one (cond ~1e5).
    assert np.max(error[:, 1:][close[:, 1:]]) < 1e-3
    assert np.max(error[:, 0][close[:, 0]]) < 2e-2
    np.testing.assert_allclose(quadratic[~close], expected[~close], rtol=1e-4)
    assert np.max(np.abs(substituted - expected)[close]) < 1e-3
    np.testing.assert_allclose(substituted[~close], expected[~close], rtol=1e-4)
