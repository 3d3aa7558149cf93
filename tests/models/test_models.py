"""SDV / constant-noise dynamics, likelihood and survival against independent formulas."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.stats import multivariate_normal

from jaxtrack.models import (
    SurvivalMap,
    constant_std,
    dynamics,
    log_likelihood,
    sample_constant_velocity,
    state_dependent_std,
    survival_probability,
)
from jaxtrack.models.noise import std_columns

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


def _halved_std(sizes, noise_std):
    """A noise model outside this package (for the generic path of ``std_columns``)."""
    return 0.5 * noise_std * jnp.concatenate([sizes, sizes], axis=-1)


@pytest.mark.parametrize("noise_model", [state_dependent_std, constant_std, _halved_std])
def test_std_columns_equal_the_model_output_columns(noise_model):
    rng = np.random.default_rng(3)
    sizes = jnp.asarray(rng.uniform(1, 200, (5, 7, 2)), jnp.float32)
    noise_std = jnp.asarray([0.11, 0.07, 0.05, 0.13], jnp.float32)
    columns = std_columns(noise_model, sizes, noise_std)
    stacked = np.asarray(noise_model(sizes, noise_std))
    assert len(columns) == 4
    for k, column in enumerate(columns):
        assert column.shape == (5, 7, 1)
        np.testing.assert_array_equal(np.asarray(column)[..., 0], stacked[..., k])


@pytest.mark.parametrize("rows", [True, False], ids=["rows", "elementwise"])
@pytest.mark.parametrize("noise_model", [state_dependent_std, constant_std, _halved_std])
def test_dynamics_equal_the_written_out_float32_sums(noise_model, rows, monkeypatch):
    """Both forms of the step (``rows_layout``) against the transition's sums in NumPy
    float32, in their order (``(y + v) + n / 2``, ``v + n``, ``max(w + nw, 1)``): equal up
    to a few roundings (XLA may fuse a multiply and an add into one rounding), exactly where
    no rounding happens (signed zeros, the size floor)."""
    monkeypatch.setattr(dynamics, "ROWS_MAX_PARTICLES", 10**9 if rows else 0)
    rng = np.random.default_rng(4)
    states = rng.normal(0, 50, (300, 6)).astype(np.float32)
    states[:, 4:] = rng.uniform(0.5, 120, (300, 2))
    states[:3, 1] = -0.0  # a negative zero velocity must stay -0 where the noise is -0
    normal = rng.normal(0, 1, (300, 4)).astype(np.float32)
    normal[:3] = -0.0
    normal[3:6, 2:] = -1e4  # sizes pushed below the floor
    noise_std = np.array([0.11, 0.07, 0.05, 0.13], np.float32)
    step = jax.jit(functools.partial(sample_constant_velocity, None, noise_model=noise_model))
    got = np.asarray(step(jnp.asarray(states), jnp.asarray(noise_std), normal=normal))
    std = np.asarray(noise_model(jnp.asarray(states[:, 4:]), jnp.asarray(noise_std)))
    n1, n2, nw, nh = (std[:, k] * normal[:, k] for k in range(4))
    y1, vy1, y2, vy2, w, h = states.T
    half = np.float32(0.5)
    expected = np.stack(
        [
            (y1 + vy1) + half * n1,
            vy1 + n1,
            (y2 + vy2) + half * n2,
            vy2 + n2,
            np.maximum(w + nw, np.float32(1)),
            np.maximum(h + nh, np.float32(1)),
        ],
        axis=1,
    )
    # A few roundings of the terms' sizes apart (a fused multiply-add rounds once where
    # NumPy rounds twice; the noise model's own products may be grouped otherwise).
    scale = np.stack(
        [
            np.abs(y1) + np.abs(vy1) + np.abs(n1),
            np.abs(vy1) + np.abs(n1),
            np.abs(y2) + np.abs(vy2) + np.abs(n2),
            np.abs(vy2) + np.abs(n2),
            np.abs(w) + np.abs(nw),
            np.abs(h) + np.abs(nh),
        ],
        axis=1,
    )
    assert np.all(np.abs(got - expected) <= 4 * np.finfo(np.float32).eps * scale)
    np.testing.assert_array_equal(got[:3], expected[:3])
    np.testing.assert_array_equal(np.signbit(got[:3]), np.signbit(expected[:3]))
    assert np.all(got[3:6, 4:] == 1.0)


@pytest.mark.parametrize(
    ("noise_model", "sdv"), [(state_dependent_std, True), (constant_std, False)]
)
@pytest.mark.parametrize("elementwise_log_norm", [False, True])
def test_likelihood_matches_scipy(noise_model, sdv, elementwise_log_norm):
    rng = np.random.default_rng(0)
    states = STATE + rng.normal(0, [5, 1, 5, 1, 3, 6], (7, 6))
    measurements = states[:3, [0, 2, 4, 5]] + rng.normal(0, 4, (3, 4))
    noise_std = np.array([0.1, 0.05, 0.2, 0.1]) if sdv else np.array([3.0, 4.0, 5.0, 6.0])
    got = log_likelihood(
        jnp.asarray(measurements),
        jnp.asarray(states),
        jnp.asarray(noise_std),
        noise_model,
        elementwise_log_norm,
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
