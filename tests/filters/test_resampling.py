"""Resampling schemes: offspring counts, mass preservation, CDF accuracy, gradients."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.filters.resampling import (
    _inverse_cdf,
    cumulative_probs,
    multinomial,
    prefix_sum,
    resample,
    residual,
    stratified,
    systematic,
)

PROBS = np.random.default_rng(0).dirichlet(np.full(50, 0.5)).astype(np.float32)


def _counts(scheme, key, num_samples=1000):
    indices = np.asarray(scheme(key, jnp.asarray(PROBS), num_samples))
    assert indices.shape == (num_samples,)
    assert indices.min() >= 0 and indices.max() < PROBS.size
    return np.bincount(indices, minlength=PROBS.size)


def test_systematic_counts_within_one_of_expectation():
    for seed in range(5):
        counts = _counts(systematic, jax.random.key(seed))
        assert np.all(np.abs(counts - 1000 * PROBS) < 1 + 1e-3)


def test_residual_keeps_the_deterministic_copies():
    for seed in range(5):
        counts = _counts(residual, jax.random.key(seed))
        assert np.all(counts >= np.floor(1000 * PROBS) - 1e-6)
        assert counts.sum() == 1000


@pytest.mark.parametrize("scheme", [systematic, stratified, multinomial, residual])
def test_schemes_are_unbiased(scheme):
    keys = jax.random.split(jax.random.key(1), 400)
    counts = jax.vmap(lambda k: jnp.bincount(scheme(k, jnp.asarray(PROBS), 200), length=50))(keys)
    mean = np.asarray(counts).mean(0)
    # 400 replicates; multinomial count variance n p (1 - p) bounds the other schemes'.
    standard_error = np.sqrt(200 * PROBS * (1 - PROBS) / 400)
    assert np.all(np.abs(mean - 200 * PROBS) < 5 * standard_error + 1e-3)


def test_blockwise_cdf_is_accurate_for_a_million_particles():
    probs = np.random.default_rng(2).exponential(size=1_000_000).astype(np.float32)
    exact = np.cumsum(probs.astype(np.float64))
    exact /= exact[-1]
    blockwise = np.asarray(cumulative_probs(jnp.asarray(probs)))
    naive = np.cumsum(probs) / np.sum(probs)
    assert blockwise[-1] == 1.0
    assert np.max(np.abs(blockwise - exact)) < 1e-6
    assert np.max(np.abs(blockwise - exact)) < np.max(np.abs(naive - exact))


def test_float64_cdf_under_x64():
    with jax.enable_x64(True):
        probs = jnp.asarray(np.random.default_rng(3).random(1000))
        cdf = cumulative_probs(probs)
        assert cdf.dtype == jnp.float64
        np.testing.assert_allclose(cdf, np.cumsum(probs) / np.sum(probs), rtol=1e-14)


@pytest.mark.parametrize("stop_gradient", [False, True])
def test_resample_preserves_mass(stop_gradient):
    particles = jnp.arange(50.0)[:, None]
    log_weights = jnp.log(jnp.asarray(PROBS) * 3.7)
    new_particles, new_log_weights = resample(
        jax.random.key(0), particles, log_weights, 64, stop_gradient=stop_gradient
    )
    assert new_particles.shape == (64, 1)
    np.testing.assert_allclose(jnp.exp(new_log_weights), 3.7 / 64, rtol=1e-5)
    # Ancestors are particles that had weight, in non-decreasing order (systematic).
    assert np.all(np.diff(np.asarray(new_particles[:, 0])) >= 0)


def test_stop_gradient_resampling_gives_unbiased_gradients():
    """d/dtheta E[sum_i w~_i f(x~_i)] with w_i = exp(theta * f_i): the sg estimator is unbiased,
    the plain one (ancestors as constants) misses the score term."""
    values = jnp.linspace(-1.0, 1.0, 8)
    theta = 0.7

    def estimate(theta, key, stop_gradient):
        log_weights = theta * values
        new_values, new_log_weights = resample(
            key, values[:, None], log_weights, 8, multinomial, stop_gradient
        )
        return jnp.sum(jnp.exp(new_log_weights) * new_values[:, 0])

    exact = jax.grad(lambda t: jnp.sum(jnp.exp(t * values) * values))(theta)
    keys = jax.random.split(jax.random.key(5), 4000)
    grads = {
        sg: np.asarray(jax.vmap(jax.grad(estimate), (None, 0, None))(theta, keys, sg))
        for sg in (False, True)
    }
    standard_error = grads[True].std() / np.sqrt(keys.shape[0])
    assert abs(grads[True].mean() - exact) < 4 * standard_error
    assert abs(grads[False].mean() - exact) > 10 * grads[False].std() / np.sqrt(keys.shape[0])


@pytest.mark.parametrize(("n", "num_samples"), [(7, 3), (5, 20), (1000, 1000), (2624, 2048)])
def test_systematic_counting_equals_binary_search_of_the_points(n, num_samples):
    # The O(n) histogram of systematic() against searchsorted of the same float32 points,
    # on weights with zeros (repeated CDF values) and a wide dynamic range.
    for seed in range(10):
        probs = jax.random.uniform(jax.random.key(seed), (n,)) ** 4
        if seed % 3 == 0:
            probs = probs.at[::2].set(0.0)
        key = jax.random.key(seed + 100)
        offset = jax.random.uniform(key, (), probs.dtype)
        points = (offset + jnp.arange(num_samples)) / num_samples
        np.testing.assert_array_equal(
            np.asarray(systematic(key, probs, num_samples)),
            np.asarray(_inverse_cdf(probs, points)),
        )


@pytest.mark.parametrize("n", [1, 31, 32, 33, 1000, 1025, 100_003])
def test_prefix_sum_of_integers_is_exact(n):
    counts = np.random.default_rng(n).integers(0, 5, n).astype(np.int32)
    got = jax.jit(prefix_sum)(jnp.asarray(counts))
    assert got.dtype == jnp.int32
    np.testing.assert_array_equal(got, np.cumsum(counts))
    # Every count in one place (a systematic histogram's extreme): still exact.
    spike = np.zeros(n, np.int32)
    spike[n // 2] = n
    np.testing.assert_array_equal(prefix_sum(jnp.asarray(spike)), np.cumsum(spike))


@pytest.mark.parametrize("n", [7, 32, 2560, 100_000])
def test_prefix_sum_of_floats_is_within_a_few_ulps_of_the_total(n):
    values = np.random.default_rng(n).exponential(size=n).astype(np.float32)
    exact = np.cumsum(values.astype(np.float64))
    got = np.asarray(jax.jit(prefix_sum)(jnp.asarray(values)), np.float64)
    ulp = np.spacing(np.float32(exact[-1]))
    assert np.max(np.abs(got - exact)) < 4 * ulp
    # Under vmap (a sweep's configurations), each row as alone.
    batch = np.stack([values, values[::-1]])
    batched = jax.vmap(prefix_sum)(jnp.asarray(batch))
    for row, alone in zip(np.asarray(batched), batch, strict=True):
        np.testing.assert_allclose(row, np.cumsum(alone.astype(np.float64)), rtol=0, atol=4 * ulp)
