"""Measurement-driven births: unbiased birth intensity near detections, padded slots."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.filters.births import (
    LOG_ZERO,
    UNROLLED_ROWS,
    log_mixture_density,
    logsumexp_rows,
    sample_births,
)
from jaxtrack.filters.phd_defaults import uniform_birth_intensity
from jaxtrack.models import constant_std, log_likelihood

BIRTH = uniform_birth_intensity(0.3, 640.0, 480.0, max_speed=8.0)
MEASUREMENTS = jnp.array([[200.0, 150.0, 40.0, 90.0], [0.5, 0.5, 1.0, 1.0], [400, 300, 30, 70]])
MASK = jnp.array([True, False, True])
NOISE = jnp.array([4.0, 6.0, 5.0, 8.0])
STARTED = jnp.asarray(True)


def test_birth_weights_estimate_the_birth_intensity_seen_by_a_detection():
    """E[sum_i b_i g(z|x_i)] = int gamma(x) g(z|x) dx = lambda_s / V_(y1,y2,w,h) with constant
    noise (the Gaussian integrates to 1 over the measured components, velocity integrates out).
    Evaluated one standard deviation away from the detection, so the weights vary."""
    shifted = MEASUREMENTS[:1] + NOISE

    def estimate(key):
        states, log_weights = sample_births(
            key, MEASUREMENTS, MASK, 32, BIRTH, BIRTH, STARTED, NOISE, constant_std
        )
        log_g = log_likelihood(shifted, states, NOISE, constant_std)[0]
        return jnp.sum(jnp.exp(log_weights + log_g))

    values = np.asarray(jax.vmap(estimate)(jax.random.split(jax.random.key(0), 500)))
    measured_volume = 640.0 * 480.0 * 639.0 * 479.0
    expected = 0.3 / measured_volume
    assert values.std() > 0.01 * expected
    assert abs(values.mean() - expected) < 4 * values.std() / np.sqrt(values.size)


def test_padded_slots_give_no_mass_and_real_slots_sample_around_their_detection():
    states, log_weights = sample_births(
        jax.random.key(1), MEASUREMENTS, MASK, 64, BIRTH, BIRTH, STARTED, NOISE, constant_std
    )
    assert states.shape == (3 * 64, 6)
    log_weights = np.asarray(log_weights).reshape(3, 64)
    assert np.all(log_weights[1] == LOG_ZERO)
    assert np.all(np.isfinite(log_weights[[0, 2]])) and np.all(log_weights[[0, 2]] > LOG_ZERO)
    centres = np.asarray(states).reshape(3, 64, 6)[[0, 2]][..., [0, 2]].mean(1)
    np.testing.assert_allclose(centres, MEASUREMENTS[[0, 2], :2], atol=5.0)
    velocities = np.asarray(states)[:, [1, 3]]
    assert np.all(np.abs(velocities) <= 8.0)


def test_no_detections_no_birth_mass():
    _, log_weights = sample_births(
        jax.random.key(2), MEASUREMENTS, jnp.zeros(3, bool), 16, BIRTH, BIRTH, STARTED, NOISE
    )
    assert np.all(np.asarray(log_weights) == LOG_ZERO)


@pytest.mark.parametrize("rows", [1, 9, UNROLLED_ROWS, UNROLLED_ROWS + 8])
def test_logsumexp_rows_is_logsumexp(rows):
    """The row-after-row log-sum-exp keeps ``jax.nn.logsumexp``'s values and gradients up to
    float32 rounding, masked rows and columns included."""
    values = np.random.default_rng(rows).normal(0.0, 30.0, (rows, 300)).astype(np.float32)
    values[rows // 2, :50] = LOG_ZERO
    values[:, 50:60] = LOG_ZERO

    def reference(x):
        return jax.nn.logsumexp(x, axis=0)

    got = np.asarray(jax.jit(logsumexp_rows)(values))
    np.testing.assert_allclose(got, jax.jit(reference)(values), rtol=1e-6, atol=0)
    assert np.all(got[50:60] == LOG_ZERO + np.float32(np.log(rows)))
    weights = np.linspace(-1.0, 2.0, 300, dtype=np.float32)
    np.testing.assert_allclose(
        jax.jit(jax.grad(lambda x: logsumexp_rows(x) @ weights))(values),
        jax.jit(jax.grad(lambda x: reference(x) @ weights))(values),
        rtol=1e-5,
        atol=1e-7,
    )


@pytest.mark.parametrize("num_slots", [9, UNROLLED_ROWS + 1])
def test_log_mixture_density_matches_a_float64_reference(num_slots):
    """Both layouts (rows reduced one by one up to ``UNROLLED_ROWS`` detections, a reduction
    beyond) against NumPy in float64, padded detections ignored."""
    rng = np.random.default_rng(num_slots)
    measurements = np.column_stack(
        [rng.uniform(50, 600, (num_slots, 2)), rng.uniform(20, 90, (num_slots, 2))]
    ).astype(np.float32)
    std = rng.uniform(2.0, 9.0, (num_slots, 4)).astype(np.float32)
    mask = rng.uniform(size=num_slots) < 0.7
    points = (measurements[rng.integers(0, num_slots, 400)] + rng.normal(0, 6.0, (400, 4))).astype(
        np.float32
    )
    got = np.asarray(jax.jit(log_mixture_density)(points, measurements, std, mask))
    offsets = (points[:, None].astype(np.float64) - measurements[None]) / std[None]
    log_gauss = -0.5 * (offsets**2).sum(-1) - np.log(std).sum(-1)[None] - 2 * np.log(2 * np.pi)
    top = log_gauss[:, mask].max(-1)
    expected = top + np.log(np.exp(log_gauss[:, mask] - top[:, None]).sum(-1))
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-3)
