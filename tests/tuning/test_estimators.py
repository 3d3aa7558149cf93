"""The resampling gradient estimators and the expected-birth-mass likelihood term."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.datasets.scene_config import SceneConfig
from jaxtrack.datasets.synthetic import generate_scene
from jaxtrack.filters.phd import phd_filter
from jaxtrack.filters.phd_defaults import default_phd_params
from jaxtrack.filters.resampling import resample
from jaxtrack.tuning import relaxed_gospa, tuning_filter

LOG_WEIGHTS = jnp.log(jnp.array([0.5, 0.1, 0.3, 0.05, 0.05]) * 2.0)  # mass 2
PARTICLES = jnp.arange(5.0)[:, None]


def test_soft_resampling_preserves_mass_and_passes_gradients():
    def mean_and_mass(log_weights):
        particles, new = resample(jax.random.key(0), PARTICLES, log_weights, 200, soft_weight=0.5)
        weights = jnp.exp(new)
        return jnp.sum(weights * particles[:, 0]) / jnp.sum(weights), jnp.sum(weights)

    (mean, mass), (grad_mean, grad_mass) = (
        mean_and_mass(LOG_WEIGHTS),
        jax.jacobian(mean_and_mass)(LOG_WEIGHTS),
    )
    assert float(mass) == pytest.approx(2.0, rel=1e-5)
    # The weighted mean is close to the exact one, sum p_i x_i = 1.05.
    assert float(mean) == pytest.approx(1.05, abs=0.1)
    assert np.all(np.isfinite(grad_mean)) and np.any(np.asarray(grad_mean) != 0)
    np.testing.assert_allclose(np.sum(grad_mass), 2.0, rtol=1e-4)  # d mass / d log w sums to M
    _, plain = resample(jax.random.key(0), PARTICLES, LOG_WEIGHTS, 200)
    assert np.allclose(np.exp(plain), 0.01)  # the default stays plain resampling


def test_bad_estimator_settings_raise():
    with pytest.raises(ValueError, match="soft_weight must lie in"):
        resample(jax.random.key(0), PARTICLES, LOG_WEIGHTS, 4, soft_weight=1.0)
    with pytest.raises(ValueError, match="exclusive"):
        resample(jax.random.key(0), PARTICLES, LOG_WEIGHTS, 4, stop_gradient=True, soft_weight=0.5)
    with pytest.raises(ValueError, match="exclusive"):
        phd_filter(8, stop_gradient_resampling=True, soft_resampling=0.5)
    with pytest.raises(ValueError, match="estimator must be one of"):
        tuning_filter(8, estimator="reinforce")
    with pytest.raises(ValueError, match="soft_weight must lie in"):
        tuning_filter(8, estimator="soft", soft_weight=0.0)


def test_expected_birth_mass_replaces_the_birth_particles_mass():
    scene = generate_scene(2, SceneConfig(num_frames=3, burn_in_frames=40))
    params = default_phd_params(768.0, 576.0, 10.0, birth_rate=0.5)
    frame = jax.tree.map(lambda x: jnp.asarray(x[0]), scene.detections)
    results = {}
    for expected in (False, True):
        filt = phd_filter(64, births_per_detection=8, expected_birth_mass=expected)
        state = filt.init(jax.random.key(0), params)
        info = jax.jit(filt.step)(jax.random.key(1), state, params, frame)[1]
        results[expected] = float(info.log_likelihood)
    # First frame: no survivors; the birth particles' mass is far below int gamma = 0.5.
    pd = float(params.detection_prob)
    difference = results[False] - results[True]
    assert 0 < difference <= pd * 0.5 + 1e-5


def test_relaxed_gospa_of_point_masses_is_gospa():
    boxes = jnp.array([[100.0, 100.0, 20.0, 40.0], [300.0, 200.0, 20.0, 40.0], [0, 0, 1, 1]])
    mask = jnp.array([True, True, False])
    # One unit of mass on the first box (exact), one far from everything: one miss, one false.
    states = jnp.array([[100.0, 100.0, 20.0, 40.0], [600.0, 500.0, 20.0, 40.0]])
    value, mass = relaxed_gospa(states, jnp.zeros(2), boxes, mask, epsilon=0.01, iterations=200)
    assert float(mass) == pytest.approx(2.0)
    assert float(value) == pytest.approx(0.5 + 0.5, abs=0.02)  # c^2 / 2 per miss and false
    # A small offset costs its squared scale-free distance (smoothed cut-off).
    shifted = states.at[0, 0].add(2.0)  # 0.1 box widths
    value2, _ = relaxed_gospa(shifted, jnp.zeros(2), boxes, mask, epsilon=0.01, iterations=200)
    assert float(value2 - value) == pytest.approx(1 - np.exp(-0.01), abs=0.005)
    empty, _ = relaxed_gospa(states, jnp.full(2, -1e30), boxes, mask)
    assert float(empty) == pytest.approx(1.0, abs=1e-3)  # two misses, no mass
