"""The PHD stages: jit == eager, the blocked update against a NumPy oracle, births drawn once."""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.boxes import xywh_to_cxcywh
from jaxtrack.context.intensity import Intensity, log_intensity
from jaxtrack.filters.births import LOG_ZERO
from jaxtrack.filters.phd import (
    YNN_FUSED_BLOCK,
    Posterior,
    TargetClutter,
    elementwise_log_norm,
    gmm_estimates,
    partition_estimates,
    phd_births,
    phd_filter,
    phd_step,
    phd_update,
    predict,
)
from jaxtrack.filters.phd_defaults import default_phd_params, uniform_birth_intensity
from jaxtrack.filters.resampling import resample
from jaxtrack.models import log_likelihood, state_dependent_std
from jaxtrack.models.dynamics import MEASURED, MIN_SIZE, VELOCITY
from tests.filters.phd_scenes import padded_detections

WIDTH, HEIGHT = 640.0, 480.0
PARAMS = default_phd_params(WIDTH, HEIGHT, 25.0)._replace(score_weight=jnp.asarray(0.7))
BOXES = np.array(
    [
        [183.0, 106.0, 39.0, 92.0],
        [386.0, 266.0, 31.0, 69.0],
        [50.0, 60.0, 35.0, 80.0],
        [0, 0, 1, 1],
        [300.0, 200.0, 30.0, 70.0],
    ]
)
SCORES = np.array([0.97, 0.8, 0.6, 0.0, 0.9])
MASK = np.array([True, True, True, False, True])
FRAME = jax.tree.map(
    lambda x: x[0],
    padded_detections([[]], 5)._replace(
        boxes=jnp.asarray(BOXES[None], jnp.float32),
        scores=jnp.asarray(SCORES[None], jnp.float32),
        mask=jnp.asarray(MASK[None]),
    ),
)
MEASUREMENTS = xywh_to_cxcywh(FRAME.boxes, jnp)


def _particles(num, seed=0):
    """Particles near the detections and elsewhere, with uneven weights."""
    rng = np.random.default_rng(seed)
    centres = np.asarray(MEASUREMENTS)[rng.integers(0, 5, num)]
    states = np.zeros((num, 6))
    states[:, [0, 2, 4, 5]] = centres + rng.normal(0, 1, (num, 4)) * [8, 12, 4, 8]
    states[:, [1, 3]] = rng.normal(0, 2, (num, 2))
    states[:, 4:] = np.maximum(states[:, 4:], 5.0)
    log_weights = np.log(rng.uniform(0.001, 0.05, num))
    return jnp.asarray(states, jnp.float32), jnp.asarray(log_weights, jnp.float32)


def _target_spread(noise_std, measurements, particles):
    """``q(z | x_j)`` of :class:`~jaxtrack.filters.phd.TargetClutter`, ``[detections,
    particles]``: a Gaussian about each particle's box with the SDV spread, written out."""
    z = np.asarray(measurements, np.float64)[:, None, :]
    x = np.asarray(particles, np.float64)[None]
    boxes = x[..., [0, 2, 4, 5]]
    std = np.asarray(noise_std, np.float64) * x[..., [4, 5, 4, 5]]
    density = np.exp(-0.5 * ((z - boxes) / std) ** 2) / (np.sqrt(2 * np.pi) * std)
    return np.prod(density, axis=-1)


def _update_oracle(params, measurements, scores, mask, particles, log_weights):
    """PHD-context eq. 10 with the full ``[detections, particles]`` arrays, float64 NumPy."""
    log_psi = np.log(float(params.detection_prob)) + np.asarray(
        log_likelihood(measurements, particles, params.measurement_noise_std), np.float64
    )
    w = np.exp(np.asarray(log_weights, np.float64))
    x = np.asarray(particles, np.float64)
    pd = float(params.detection_prob)
    clipped = np.clip(np.asarray(scores, np.float64), 1e-6, 1 - 1e-6)
    ratio = (clipped / (1 - clipped)) ** float(params.score_weight)
    kappa = np.exp(np.asarray(log_intensity(params.clutter_intensity, measurements), np.float64))
    rate = float(params.target_clutter.rate)
    kappa = kappa + rate * _target_spread(params.target_clutter.noise_std, measurements, x) @ w
    updated = (1 - pd) * w
    log_likelihood_k = -(pd + rate) * w.sum() - float(params.clutter_intensity.magnitude)
    log_masses, states = [], []
    terms = np.full(log_psi.shape, -np.inf)
    for z in range(len(scores)):
        if not mask[z]:
            log_masses.append(LOG_ZERO)
            states.append(np.zeros(6))
            continue
        psi = np.exp(log_psi[z])
        c = np.sum(psi * w)
        denominator = kappa[z] / ratio[z] + c
        updated += psi * w / denominator
        log_likelihood_k += math.log(kappa[z] + ratio[z] * c)
        log_masses.append(math.log(c / denominator))
        states.append((psi * w) @ x / c)
        terms[z] = log_psi[z] - math.log(denominator)
    shares = np.exp(terms - terms.max(0))
    particle_scores = np.asarray(scores, np.float64) @ (shares / shares.sum(0))
    return dict(
        log_weights=np.log(updated),
        log_likelihood=log_likelihood_k,
        detection_log_masses=np.array(log_masses),
        detection_states=np.array(states),
        particle_scores=particle_scores,
    )


def _jit_update(params, particles, log_weights, block_size):
    """The jitted update of the module's frame with ``block_size`` particles per block."""
    return jax.jit(phd_update, static_argnums=(6, 7))(
        params,
        MEASUREMENTS,
        FRAME.scores,
        FRAME.mask,
        particles,
        log_weights,
        state_dependent_std,
        block_size,
    )


def _assert_matches_oracle(update, expected):
    """Every output of the update against the float64 oracle's."""
    np.testing.assert_allclose(update.log_weights, expected["log_weights"], rtol=1e-5)
    np.testing.assert_allclose(update.log_likelihood, expected["log_likelihood"], rtol=1e-5)
    np.testing.assert_allclose(
        update.detection_log_masses, expected["detection_log_masses"], rtol=1e-5, atol=1e-5
    )
    np.testing.assert_allclose(
        update.detection_states, expected["detection_states"], rtol=1e-5, atol=1e-4
    )
    np.testing.assert_allclose(update.particle_scores, expected["particle_scores"], rtol=1e-5)


@pytest.mark.parametrize("block_size", [None, 50, 64, 77, 300])
def test_blocked_update_matches_the_full_array_oracle(block_size):
    """Blocks of 50 and 64 divide 300 particles or not (77: the last block overlaps)."""
    particles, log_weights = _particles(300)
    update = _jit_update(PARAMS, particles, log_weights, block_size)
    expected = _update_oracle(PARAMS, MEASUREMENTS, SCORES, MASK, particles, log_weights)
    _assert_matches_oracle(update, expected)
    assert np.exp(expected["detection_log_masses"][MASK]).min() > 0.01  # parts with mass


TARGET_CLUTTER = TargetClutter(jnp.asarray(0.3), jnp.asarray([0.3, 0.16, 0.5, 0.3]))


@pytest.mark.parametrize("target_clutter", [False, True])
@pytest.mark.parametrize("block_size", [3000, 4500, 5000])
def test_elementwise_log_norm_matches_the_full_array_oracle(block_size, target_clutter):
    """More than ``ROWS_MAX_PARTICLES`` particles, or blocks wider than ``YNN_FUSED_BLOCK``,
    form the log-normaliser by elementwise additions (``elementwise_log_norm``): 9,000
    particles in three or two blocks (5,000: the last overlaps), with and without the
    target clutter's pass, against the float64 oracle."""
    assert not elementwise_log_norm(8192, YNN_FUSED_BLOCK)  # the tracker's sizes: kept
    assert elementwise_log_norm(8192, YNN_FUSED_BLOCK + 1)
    assert elementwise_log_norm(9000, block_size)
    params = PARAMS._replace(target_clutter=TARGET_CLUTTER) if target_clutter else PARAMS
    particles, log_weights = _particles(9000, seed=2)
    update = _jit_update(params, particles, log_weights, block_size)
    expected = _update_oracle(params, MEASUREMENTS, SCORES, MASK, particles, log_weights)
    _assert_matches_oracle(update, expected)


@pytest.mark.parametrize("block_size", [None, 77])
def test_update_with_target_clutter_matches_the_oracle(block_size):
    """``kappa(z) + rate sum_j q(z | x_j) w_j`` in the denominator, ``-rate sum_j w_j`` in the
    log-likelihood (the oracle sums ``q`` over the full array, in float64)."""
    params = PARAMS._replace(target_clutter=TARGET_CLUTTER)
    particles, log_weights = _particles(300)
    update = _jit_update(params, particles, log_weights, block_size)
    expected = _update_oracle(params, MEASUREMENTS, SCORES, MASK, particles, log_weights)
    without = _update_oracle(PARAMS, MEASUREMENTS, SCORES, MASK, particles, log_weights)
    np.testing.assert_allclose(update.log_weights, expected["log_weights"], rtol=1e-5)
    np.testing.assert_allclose(update.log_likelihood, expected["log_likelihood"], rtol=1e-5)
    np.testing.assert_allclose(
        update.detection_log_masses, expected["detection_log_masses"], rtol=1e-5, atol=1e-5
    )
    # the term is not negligible here: every detection's mass falls, one by 5 %
    drop = without["detection_log_masses"][MASK] - expected["detection_log_masses"][MASK]
    assert drop.min() > 0.002 and drop.max() > 0.05


def test_target_clutter_takes_the_mass_of_a_second_box_beside_a_target():
    """One target (mass 1) and two detections: its own box and a second box shifted by 0.6 of
    its width. The paper's update gives each detection a mass above 0.5, so each becomes an
    estimate (a duplicate); with the extra boxes the target generates (rate 0.15, spread as
    learned on PETS09-S2L1), the second box falls below 0.5 and the target's own box stays."""
    rng = np.random.default_rng(3)
    num = 400
    target = np.array([300.0, 200.0, 40.0, 100.0])  # centre x, centre y, w, h
    states = np.zeros((num, 6))
    states[:, [0, 2, 4, 5]] = target + rng.normal(0, 1, (num, 4)) * [4.0, 4.0, 2.0, 4.0]
    particles = jnp.asarray(states, jnp.float32)
    log_weights = jnp.full(num, -np.log(num), jnp.float32)
    second = target + np.array([24.0, 0.0, 0.0, 0.0])
    measurements = jnp.asarray([target, second], jnp.float32)
    scores, mask = jnp.asarray([0.9, 0.9]), jnp.asarray([True, True])
    base = PARAMS._replace(score_weight=jnp.asarray(0.0))
    spread = TargetClutter(jnp.asarray(0.15), jnp.asarray([0.40, 0.10, 0.66, 0.22]))
    masses = {}
    for name, params in (("paper", base), ("target clutter", base._replace(target_clutter=spread))):
        update = phd_update(params, measurements, scores, mask, particles, log_weights)
        masses[name] = np.exp(np.asarray(update.detection_log_masses))
    assert masses["paper"].min() > 0.5
    assert masses["target clutter"][0] > 0.5 > masses["target clutter"][1]


def test_target_clutter_rates_mixed_in_a_vmapped_batch_equal_single_runs():
    """Under ``vmap`` the ``lax.cond`` that skips the pass at rate 0 runs both branches; each
    parameter set still gets its own term."""
    particles, log_weights = _particles(300)
    batch = [PARAMS, PARAMS._replace(target_clutter=TARGET_CLUTTER)]
    stacked = jax.tree.map(lambda *leaves: jnp.stack(leaves), *batch)
    run = functools.partial(
        phd_update,
        measurements=MEASUREMENTS,
        scores=FRAME.scores,
        mask=FRAME.mask,
        particles=particles,
        log_weights=log_weights,
    )
    together = jax.vmap(lambda params: run(params).log_weights)(stacked)
    for row, params in zip(together, batch, strict=True):
        np.testing.assert_allclose(row, run(params).log_weights, rtol=1e-6)
    assert not np.allclose(together[0], together[1])


def test_blocked_update_needs_memory_for_one_block_only():
    """XLA's temporary buffers of the update grow with the block, not with the pairs."""
    particles, log_weights = _particles(4096)

    def temp_bytes(block_size):
        update = functools.partial(phd_update, block_size=block_size)
        args = (PARAMS, MEASUREMENTS, FRAME.scores, FRAME.mask, particles, log_weights)
        return jax.jit(update).lower(*args).compile().memory_analysis().temp_size_in_bytes

    pairs_bytes = 5 * 4096 * 4
    assert temp_bytes(4096) > 2 * pairs_bytes  # unblocked: several [5, 4096] arrays
    assert temp_bytes(128) < pairs_bytes  # blocked: [5, 128] arrays and per-particle outputs


def _stage_calls():
    key = jax.random.key(3)
    particles, log_weights = _particles(64)
    started = jnp.asarray(True)
    update = phd_update(
        PARAMS, MEASUREMENTS, FRAME.scores, FRAME.mask, particles, log_weights, block_size=20
    )
    posterior = Posterior(particles, log_weights, update.particle_scores)
    return {
        "predict": (predict, (key, particles, log_weights, PARAMS)),
        "births": (
            functools.partial(phd_births, births_per_detection=4),
            (key, MEASUREMENTS, FRAME.mask, PARAMS, started),
        ),
        "update": (
            functools.partial(phd_update, block_size=20),
            (PARAMS, MEASUREMENTS, FRAME.scores, FRAME.mask, particles, log_weights),
        ),
        "resample": (
            functools.partial(resample, num_samples=32),
            (key, (particles, update.particle_scores), update.log_weights),
        ),
        "partition": (partition_estimates, (key, update, posterior, FRAME, PARAMS)),
        "gmm": (
            functools.partial(gmm_estimates, max_clusters=4, num_iterations=3),
            (key, update, posterior, FRAME, PARAMS),
        ),
    }


@pytest.mark.parametrize("stage", ["predict", "births", "update", "resample", "partition", "gmm"])
def test_each_stage_jit_equals_eager(stage):
    function, args = _stage_calls()[stage]
    jitted = jax.jit(function)(*args)
    with jax.disable_jit():
        eager = function(*args)
    jax.tree.map(lambda a, b: np.testing.assert_allclose(a, b, rtol=2e-5, atol=2e-4), jitted, eager)


def _sample_one_intensity(key, measurements, mask, births_per_detection, intensity, std):
    """The births of one intensity, drawn with its own velocity range (the two-draw formula)."""
    num_slots = measurements.shape[0]
    key_gauss, key_velocity = jax.random.split(key)
    noise = state_dependent_std(measurements[:, 2:], std)
    normal = jax.random.normal(key_gauss, (num_slots, births_per_detection, 4), measurements.dtype)
    measured = (measurements[:, None, :] + noise[:, None, :] * normal).reshape(-1, 4)
    measured = measured.at[:, 2:].set(jnp.maximum(measured[:, 2:], MIN_SIZE))
    lower = intensity.lower[jnp.array(VELOCITY)]
    upper = intensity.upper[jnp.array(VELOCITY)]
    velocity = jax.random.uniform(
        key_velocity,
        (num_slots * births_per_detection, 2),
        measurements.dtype,
        minval=lower,
        maxval=upper,
    )
    states = jnp.zeros((measured.shape[0], 6), measurements.dtype)
    states = states.at[:, MEASURED].set(measured).at[:, VELOCITY].set(velocity)
    residual = (measured[:, None, :] - measurements[None]) / noise[None]
    log_gauss = -0.5 * jnp.sum(residual**2, axis=-1) - jnp.sum(jnp.log(noise), axis=-1)[None]
    log_gauss = log_gauss - 2 * math.log(2 * math.pi)
    log_mixture = jax.nn.logsumexp(jnp.where(mask[None], log_gauss, LOG_ZERO), axis=-1)
    log_weights = (
        log_intensity(intensity, states)
        - math.log(births_per_detection)
        - log_mixture
        + jnp.sum(jnp.log(upper - lower))
    )
    return states, jnp.where(jnp.repeat(mask, births_per_detection), log_weights, LOG_ZERO)


def _two_draw_births(key, measurements, mask, params, started, births_per_detection):
    draw = functools.partial(_sample_one_intensity, key, measurements, mask, births_per_detection)
    births, birth_log_weights = draw(params.birth_intensity, params.measurement_noise_std)
    initial, initial_log_weights = draw(params.initial_intensity, params.measurement_noise_std)
    return (
        jnp.where(started, births, initial),
        jnp.where(started, birth_log_weights, initial_log_weights),
    )


def _learned_birth_intensity():
    """A uniform + 3-component mixture over the state space (another PyTree shape)."""
    uniform = uniform_birth_intensity(0.4, WIDTH, HEIGHT, max_speed=6.0)
    means = jnp.array([[100.0, 1.0, 100.0, 0.0, 30.0, 70.0], [400.0, -1.0, 300.0, 0.5, 40, 90]])
    return Intensity(
        magnitude=jnp.asarray(0.6),
        uniform_weight=jnp.asarray(0.2),
        lower=uniform.lower,
        upper=uniform.upper,
        weights=jnp.array([0.5, 0.3, 0.2]),
        means=jnp.concatenate([means, means[:1] + 50.0]),
        covs=jnp.tile(jnp.diag(jnp.array([400.0, 4.0, 400.0, 4.0, 25.0, 100.0])), (3, 1, 1)),
    )


@pytest.mark.parametrize("started", [False, True])
@pytest.mark.parametrize("expected_birth_mass", [False, True])
def test_births_drawn_once_give_the_two_draw_step_exactly(started, expected_birth_mass):
    """A learned birth intensity (mixture) and a uniform initial one of another velocity range:
    one draw with the chosen range equals drawing with both and keeping one, bit for bit."""
    params = PARAMS._replace(
        birth_intensity=_learned_birth_intensity(),
        initial_intensity=uniform_birth_intensity(0.5, WIDTH, HEIGHT, max_speed=9.0),
    )
    filt = phd_filter(64, births_per_detection=8, expected_birth_mass=expected_birth_mass)
    births = functools.partial(_two_draw_births, births_per_detection=8)
    two_draw = functools.partial(filt.step.func, **{**filt.step.keywords, "births": births})
    particles, log_weights = _particles(64)
    state = filt.init(None, params)._replace(
        particles=particles, log_weights=log_weights, started=jnp.asarray(started)
    )
    key = jax.random.key(11)
    once = jax.jit(filt.step)(key, state, params, FRAME)
    twice = jax.jit(two_draw)(key, state, params, FRAME)
    jax.tree.map(np.testing.assert_array_equal, once, twice)
    assert bool(once[1].estimates.mask.any())


def test_a_benchmark_composes_the_stages_without_the_builder():
    """The stages composed by hand (as ``benchmarks/phd_step.py`` does) give the built step."""
    filt = phd_filter(64, births_per_detection=4, block_size=16)
    step = functools.partial(
        phd_step,
        births=functools.partial(phd_births, births_per_detection=4),
        update=functools.partial(phd_update, block_size=16),
        resample=functools.partial(resample, num_samples=64),
    )
    particles, log_weights = _particles(64)
    state = filt.init(None, PARAMS)._replace(particles=particles, log_weights=log_weights)
    key = jax.random.key(2)
    jax.tree.map(
        np.testing.assert_array_equal,
        jax.jit(step)(key, state, PARAMS, FRAME),
        jax.jit(filt.step)(key, state, PARAMS, FRAME),
    )
