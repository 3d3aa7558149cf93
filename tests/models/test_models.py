"""SDV / constant-noise dynamics, likelihood and survival against independent formulas."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.stats import multivariate_normal

from jaxtrack.models import (
    SurvivalMap,
    constant_std,
    log_likelihood,
    sample_constant_velocity,
    state_dependent_std,
    survival_probability,
)

STATE = np.array([100.0, 3.0, 200.0, -1.0, 40.0, 90.0])


def _expected_moments(state, noise_std, sdv):
    """Mean and covariance of one constant-velocity step, written out from SPEC section 1."""
    y1, vy1, y2, vy2, w, h = state
    s1, s2, sw, sh = noise_std * (np.array([w, h, w, h]) if sdv else 1.0)
    mean = np.array([y1 + vy1, vy1, y2 + vy2, vy2, w, h])
    cov = np.zeros((6, 6))
    cov[np.ix_([0, 1], [0, 1])] = s1**2 * np.array([[0.25, 0.5], [0.5, 1.0]])
    cov[np.ix_([2, 3], [2, 3])] = s2**2 * np.array([[0.25, 0.5], [0.5, 1.0]])
    cov[4, 4], cov[5, 5] = sw**2, sh**2
    return mean, cov


@pytest.mark.parametrize(
    ("noise_model", "sdv"), [(state_dependent_std, True), (constant_std, False)]
)
def test_dynamics_moments(noise_model, sdv):
    noise_std = np.array([0.05, 0.02, 0.03, 0.01]) if sdv else np.array([2.0, 1.0, 1.5, 0.5])
    states = jnp.tile(jnp.asarray(STATE, jnp.float32), (200_000, 1))
    samples = np.asarray(
        sample_constant_velocity(jax.random.key(0), states, jnp.asarray(noise_std), noise_model),
        np.float64,
    )
    mean, cov = _expected_moments(STATE, noise_std, sdv)
    std = np.sqrt(np.diag(cov))
    # Monte Carlo: 200k draws, standard error of a mean is std / 447.
    np.testing.assert_allclose(samples.mean(0), mean, atol=float(5 * std.max() / 447))
    # Covariance entries: standard error about sqrt(c_ii c_jj) / 447 (up to sqrt 2).
    tolerance = 7 * np.outer(std, std) / 447
    assert np.all(np.abs(np.cov(samples.T) - cov) < tolerance)


def test_sdv_noise_scales_with_box_size():
    small = jnp.array([[0.0, 0.0, 0.0, 0.0, 10.0, 20.0]])
    big = small.at[:, 4:].multiply(10.0)
    key = jax.random.key(1)
    noise_std = jnp.array([0.1, 0.1, 0.1, 0.1])
    step_small = sample_constant_velocity(key, small, noise_std) - small
    step_big = sample_constant_velocity(key, big, noise_std) - big
    np.testing.assert_allclose(step_big, 10 * step_small, rtol=1e-4, atol=1e-4)
    step_small_const = sample_constant_velocity(key, small, noise_std, constant_std) - small
    step_big_const = sample_constant_velocity(key, big, noise_std, constant_std) - big
    np.testing.assert_allclose(step_big_const, step_small_const, atol=1e-4)


@pytest.mark.parametrize(
    ("noise_model", "sdv"), [(state_dependent_std, True), (constant_std, False)]
)
def test_likelihood_matches_scipy(noise_model, sdv):
    rng = np.random.default_rng(0)
    states = STATE + rng.normal(0, [5, 1, 5, 1, 3, 6], (7, 6))
    measurements = states[:3, [0, 2, 4, 5]] + rng.normal(0, 4, (3, 4))
    noise_std = np.array([0.1, 0.05, 0.2, 0.1]) if sdv else np.array([3.0, 4.0, 5.0, 6.0])
    got = log_likelihood(
        jnp.asarray(measurements), jnp.asarray(states), jnp.asarray(noise_std), noise_model
    )
    for j, z in enumerate(measurements):
        for i, x in enumerate(states):
            w, h = x[4], x[5]
            std = noise_std * (np.array([w, h, w, h]) if sdv else 1.0)
            expected = multivariate_normal(x[[0, 2, 4, 5]], np.diag(std**2)).logpdf(z)
            np.testing.assert_allclose(got[j, i], expected, rtol=1e-5)


def test_survival_constant_and_map():
    states = jnp.array(
        [[10.0, 0, 10.0, 0, 5, 5], [90.0, 0, 10.0, 0, 5, 5], [90.0, 0, 70.0, 0, 5, 5]]
    )
    states = jnp.concatenate([states, jnp.array([[-50.0, 0, 500.0, 0, 5, 5]])])
    np.testing.assert_allclose(survival_probability(jnp.asarray(0.9), states), 0.9)
    grid = SurvivalMap(
        probs=jnp.array([[0.1, 0.2], [0.3, 0.4]]),
        lower=jnp.array([0.0, 0.0]),
        upper=jnp.array([100.0, 80.0]),
    )
    # rows follow y2 (cells of 40 px), columns y1 (cells of 50 px); outside -> border cell.
    np.testing.assert_allclose(survival_probability(grid, states), [0.1, 0.2, 0.4, 0.3])
