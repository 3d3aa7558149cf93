"""Particle PHD step: NumPy reference, mass bookkeeping, Kalman oracle, gradients."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.boxes import cxcywh_to_xywh
from jaxtrack.filters.base import run
from jaxtrack.filters.phd import PHDParams, join_particles, phd_filter
from jaxtrack.filters.phd_defaults import default_phd_params
from jaxtrack.models import SurvivalMap, constant_std, dynamics
from tests.filters.phd_reference import reference_of_state
from tests.filters.phd_scenes import padded_detections, walking_scene

WIDTH, HEIGHT = 640.0, 480.0


def _params(**changes) -> PHDParams:
    params = default_phd_params(WIDTH, HEIGHT, 25.0)
    params = params._replace(
        motion_noise_std=jnp.array([0.05, 0.02, 0.05, 0.05]),
        measurement_noise_std=jnp.array([0.15, 0.08, 0.25, 0.15]),
    )
    return params._replace(**changes)


def _to_float64(tree):
    return jax.tree.map(
        lambda x: jnp.asarray(x, jnp.float64) if jnp.issubdtype(x.dtype, jnp.floating) else x,
        tree,
    )


def _state_with_targets(filt, key, targets, num_particles, mass_per_target=1.0):
    """Init state whose particles sit around the given (y1, vy1, y2, vy2, w, h) states."""
    state = filt.init(key, None)
    targets = np.asarray(targets)
    rng = np.random.default_rng(0)
    owner = np.arange(num_particles) % len(targets)
    particles = targets[owner] + rng.normal(0, [3, 0.5, 3, 0.5, 1, 2], (num_particles, 6))
    weight = mass_per_target * len(targets) / num_particles
    return state._replace(
        particles=jnp.asarray(particles, state.particles.dtype),
        log_weights=jnp.full(num_particles, np.log(weight), state.log_weights.dtype),
        mass=jnp.asarray(mass_per_target * len(targets), state.mass.dtype),
    )


TARGETS = [(200.0, 2.0, 150.0, 0.0, 40.0, 90.0), (400.0, -1.0, 300.0, 1.0, 30.0, 70.0)]
BOXES = np.array(
    [[183.0, 106.0, 39.0, 92.0], [386.0, 266.0, 31.0, 69.0], [50.0, 60.0, 35.0, 80.0], [0, 0, 1, 1]]
)
SCORES = np.array([0.97, 0.8, 0.6, 0.0])
MASK = np.array([True, True, True, False])


@pytest.mark.parametrize(
    ("score_weight", "block"),
    [(0.0, None), (1.0, None), (1.0, 20)],
    ids=["plain", "scores", "blocks"],
)
def test_step_matches_numpy_reference(score_weight, block):
    # blocks: 48 predicted particles in blocks of 20, 3 blocks, the last overlapping
    with jax.enable_x64(True):
        filt = phd_filter(32, births_per_detection=4, extraction="partition", block_size=block)
        params = _to_float64(
            _params(score_weight=jnp.asarray(score_weight), survival_prob=jnp.asarray(0.97))
        )
        state = _to_float64(_state_with_targets(filt, jax.random.key(0), TARGETS, 32))
        detections = _to_float64(
            padded_detections([[]], 4)._replace(
                boxes=jnp.asarray(BOXES[None]),
                scores=jnp.asarray(SCORES[None]),
                mask=jnp.asarray(MASK[None]),
            )
        )
        frame = jax.tree.map(lambda x: x[0], detections)
        key = jax.random.key(7)
        new_state, info = jax.jit(filt.step)(key, state, params, frame)
        reference = reference_of_state(key, state, params, BOXES, SCORES, MASK, 4)
    np.testing.assert_allclose(info.log_likelihood, reference["log_likelihood"], rtol=1e-5)
    np.testing.assert_allclose(new_state.mass, reference["mass"], rtol=1e-5)
    np.testing.assert_allclose(np.exp(new_state.log_weights), reference["mass"] / 32, rtol=1e-5)
    np.testing.assert_allclose(new_state.particles, reference["resampled"], rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(
        info.estimates.masses[np.array(reference["valid"])], reference["shares"], rtol=1e-5
    )
    # The two detected targets have most of their detection's share, the clutter little.
    assert reference["shares"][0] > 0.9 and reference["shares"][2] < 0.5


def test_mass_without_detections_decays_by_survival_times_missed_detection():
    filt = phd_filter(64, births_per_detection=8)
    params = _params(detection_prob=jnp.asarray(0.8), survival_prob=jnp.asarray(0.95))
    state = _state_with_targets(filt, jax.random.key(0), TARGETS, 64, mass_per_target=0.9)
    empty = jax.tree.map(lambda x: x[0], padded_detections([[]], 5))
    step = jax.jit(filt.step)
    for k in range(3):
        mass = state.mass
        state, info = step(jax.random.key(k), state, params, empty)
        np.testing.assert_allclose(state.mass, mass * 0.95 * 0.2, rtol=1e-5)
        np.testing.assert_allclose(info.mass, state.mass, rtol=1e-6)
        # log p(empty set) = -pD * predicted mass - clutter magnitude
        np.testing.assert_allclose(
            info.log_likelihood, -0.8 * mass * 0.95 - params.clutter_intensity.magnitude, rtol=1e-5
        )


def test_mass_decays_by_the_survival_map_of_each_target():
    """A state-dependent survival probability (2 x 2 map): each target's mass is multiplied
    by its own cell's probability (and by the missed-detection probability)."""
    filt = phd_filter(64, births_per_detection=8)
    survival = SurvivalMap(
        probs=jnp.array([[0.5, 0.7], [0.6, 0.9]]),  # rows follow y2, columns y1
        lower=jnp.array([0.0, 0.0]),
        upper=jnp.array([WIDTH, HEIGHT]),
    )
    params = _params(detection_prob=jnp.asarray(0.8), survival_prob=survival)
    state = _state_with_targets(filt, jax.random.key(0), TARGETS, 64, mass_per_target=0.9)
    empty = jax.tree.map(lambda x: x[0], padded_detections([[]], 5))
    new_state, _ = jax.jit(filt.step)(jax.random.key(1), state, params, empty)
    # target (200, 150) in cell (0, 0): 0.5; target (400, 300) in cell (1, 1): 0.9
    np.testing.assert_allclose(new_state.mass, 0.9 * (0.5 + 0.9) * 0.2, rtol=1e-5)


@pytest.mark.parametrize(
    ("detection_prob", "expected", "extraction"),
    [(1.0, 1.0, "partition"), (0.9, 1 / (1 - 0.1 * 0.99), "gmm")],
)
def test_mass_of_a_repeatedly_detected_target(detection_prob, expected, extraction):
    """Fixed point of eq. 10 with one detection per frame and negligible clutter:
    M = (1 - pD) e M + 1."""
    detections, _ = walking_scene(30, [(100.0, 100.0)], [(3.0, 1.0)], noise=1.0, capacity=3)
    params = _params(
        detection_prob=jnp.asarray(detection_prob),
        survival_prob=jnp.asarray(0.99),
        clutter_intensity=_params().clutter_intensity._replace(magnitude=jnp.asarray(1e-3)),
    )
    filt = phd_filter(256, extraction=extraction)
    _, info = jax.jit(lambda k: run(filt, k, params, detections))(jax.random.key(0))
    np.testing.assert_allclose(info.mass[-10:], expected, rtol=2e-3)
    assert np.all(info.tracks.mask.sum(1)[3:] == 1)


def _kalman(prior_mean, prior_cov, measurements, transition, process_cov, observation, noise_cov):
    means, covs = [], []
    mean, cov = prior_mean, prior_cov
    for z in measurements:
        mean, cov = transition @ mean, transition @ cov @ transition.T + process_cov
        innovation_cov = observation @ cov @ observation.T + noise_cov
        gain = cov @ observation.T @ np.linalg.inv(innovation_cov)
        mean = mean + gain @ (z - observation @ mean)
        cov = (np.eye(6) - gain @ observation) @ cov
        means.append(mean)
        covs.append(cov)
    return np.array(means), np.array(covs)


def test_single_linear_gaussian_target_tracks_the_kalman_filter():
    """pD = 1, no clutter, no births, constant noise: the PHD recursion is the Bayes filter."""
    motion_std = np.array([1.0, 0.8, 0.5, 0.5])
    meas_std = np.array([3.0, 4.0, 2.0, 3.0])
    transition = np.eye(6)
    transition[0, 1] = transition[2, 3] = 1.0
    gain = np.zeros((6, 4))
    gain[[0, 1, 2, 3, 4, 5], [0, 0, 1, 1, 2, 3]] = [0.5, 1.0, 0.5, 1.0, 1.0, 1.0]
    process_cov = gain @ np.diag(motion_std**2) @ gain.T
    observation = np.zeros((4, 6))
    observation[[0, 1, 2, 3], [0, 2, 4, 5]] = 1.0

    rng = np.random.default_rng(1)
    truth = np.array([300.0, 2.0, 200.0, -1.0, 40.0, 90.0])
    prior_cov = np.diag([5.0, 2.0, 6.0, 2.0, 3.0, 4.0]) ** 2
    prior_mean = truth + rng.multivariate_normal(np.zeros(6), prior_cov)
    measurements = []
    for _ in range(15):
        truth = transition @ truth + gain @ (motion_std * rng.normal(size=4))
        measurements.append(observation @ truth + meas_std * rng.normal(size=4))
    measurements = np.array(measurements)
    kf_means, kf_covs = _kalman(
        prior_mean,
        prior_cov,
        measurements,
        transition,
        process_cov,
        observation,
        np.diag(meas_std**2),
    )

    num_particles = 4000
    filt = phd_filter(
        num_particles,
        births_per_detection=0,
        extraction="partition",
        motion_noise_model=constant_std,
        measurement_noise_model=constant_std,
    )
    params = _params(
        motion_noise_std=jnp.asarray(motion_std),
        measurement_noise_std=jnp.asarray(meas_std),
        detection_prob=jnp.asarray(1.0),
        survival_prob=jnp.asarray(1.0),
        clutter_intensity=_params().clutter_intensity._replace(magnitude=jnp.asarray(0.0)),
    )
    initial = filt.init(jax.random.key(0), params)._replace(
        particles=jnp.asarray(rng.multivariate_normal(prior_mean, prior_cov, num_particles)),
        log_weights=jnp.full(num_particles, -np.log(num_particles)),
        mass=jnp.asarray(1.0),
    )
    boxes = cxcywh_to_xywh(measurements)
    detections = padded_detections([[tuple(b)] for b in boxes], 2)
    step = jax.jit(filt.step)
    kf_std = np.sqrt(np.diagonal(kf_covs, axis1=1, axis2=2))
    # Four independent runs (keys 1.., 101.., 201.., 301..): one run's error is correlated
    # from frame to frame (resampling carries it), so a single run's worst frame depends on
    # its draws; the runs' mean error has half the Monte Carlo spread of one run and is held
    # to the same bounds.
    errors, particle_errors = [], []
    for repeat in range(4):
        state = initial
        run_errors, run_particle_errors = [], []
        for k in range(len(measurements)):
            frame = jax.tree.map(lambda x, k=k: x[k], detections)
            state, info = step(jax.random.key(100 * repeat + k + 1), state, params, frame)
            posterior_mean = np.asarray(info.estimates.states[0], np.float64)
            particles = np.asarray(state.particles, np.float64)
            run_errors.append((posterior_mean - kf_means[k]) / kf_std[k])
            run_particle_errors.append((particles.mean(0) - kf_means[k]) / kf_std[k])
            np.testing.assert_allclose(particles.std(0), kf_std[k], rtol=0.3)
            np.testing.assert_allclose(state.mass, 1.0, rtol=1e-5)
            assert bool(info.estimates.mask[0])
        errors.append(run_errors)
        particle_errors.append(run_particle_errors)
    # Monte Carlo tolerances (4000 particles; an effective sample size of a few hundred
    # after weighting gives a standard error near 0.05-0.1 KF standard deviations per run).
    assert np.all(np.abs(np.mean(errors, axis=0)) < 0.35)
    assert np.all(np.abs(np.mean(particle_errors, axis=0)) < 0.4)
    assert np.mean(np.abs(errors)) < 0.1
    assert np.max(np.abs(errors)) < 0.6  # no run strays far


@pytest.mark.parametrize("num_survivors", [100, 9000])
def test_join_particles_equals_concatenate_in_either_layout(num_survivors):
    """Survivors up to ``ROWS_MAX_PARTICLES`` are joined as rows, more as ``[n, 6]`` rows
    of the states' own layout (``dynamics.rows_layout``): the same array either way, under
    ``jit`` too."""
    assert dynamics.rows_layout(100) and not dynamics.rows_layout(9000)
    rng = np.random.default_rng(7)
    survivors = jnp.asarray(rng.normal(size=(num_survivors, 6)), jnp.float32)
    born = jnp.asarray(rng.normal(size=(37, 6)), jnp.float32)
    expected = np.concatenate([np.asarray(survivors), np.asarray(born)])
    np.testing.assert_array_equal(join_particles(survivors, born), expected)
    np.testing.assert_array_equal(jax.jit(join_particles)(survivors, born), expected)
