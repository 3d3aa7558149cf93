"""The mixture particle filter (CMT eqs. 1-4) against independent oracles.

Oracles: a NumPy Kalman filter (one component, linear-Gaussian, many particles), NumPy
computations of eqs. 3-4 on hand-built cases, a two-cluster particle set with a known answer,
and scripted scenes (a target that leaves, one that enters).
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.special import logsumexp
from scipy.stats import norm

from jaxtrack.filters.base import run
from jaxtrack.filters.births import LOG_ZERO
from jaxtrack.filters.mixture import (
    local_estimate,
    mixture_filter,
    mixture_weights,
    normalise_weights,
    resample_components,
    reweight,
)
from jaxtrack.filters.mixture_components import (
    add_component,
    add_unexplained,
    delete_components,
)
from jaxtrack.filters.mixture_models import (
    bootstrap_proposal,
    log_transition,
    nearest_detection_log_likelihood,
)
from jaxtrack.filters.mixture_state import MixtureParams, init_mixture
from jaxtrack.models.dynamics import noise_gain, transition_matrix
from jaxtrack.models.noise import constant_std, state_dependent_std
from jaxtrack.types import Detections

PARAMS = MixtureParams(
    motion_noise_std=jnp.array([0.05, 0.05, 0.01, 0.01]),
    measurement_noise_std=jnp.array([0.1, 0.1, 0.1, 0.1]),
    background_log_likelihood=jnp.array(-30.0),
    min_mixture_weight=jnp.array(1e-3),
    min_log_support=jnp.array(-25.0),
    birth_log_likelihood=jnp.array(-12.0),
)
#: Constant-noise parameters (pixels) of the linear-Gaussian case; no births, no deletions.
LINEAR = MixtureParams(
    motion_noise_std=jnp.array([1.0, 1.5, 0.5, 0.5]),
    measurement_noise_std=jnp.array([3.0, 4.0, 2.0, 2.0]),
    background_log_likelihood=jnp.array(-1e4),
    min_mixture_weight=jnp.array(0.0),
    min_log_support=jnp.array(-1e9),
    birth_log_likelihood=jnp.array(-1e9),
)


def _detections(frames: list[list[tuple[float, float, float, float]]], capacity: int):
    """Padded :class:`Detections` ``[num_frames, capacity]`` from per-frame box lists."""
    boxes = np.tile(np.array([0.0, 0.0, 1.0, 1.0], np.float32), (len(frames), capacity, 1))
    mask = np.zeros((len(frames), capacity), bool)
    for t, frame in enumerate(frames):
        for j, box in enumerate(frame):
            boxes[t, j], mask[t, j] = box, True
    return Detections(jnp.asarray(boxes), jnp.asarray(mask, jnp.float32), jnp.asarray(mask))


def _frame(detections: Detections, t: int) -> Detections:
    return jax.tree.map(lambda x: x[t], detections)


def _walk(t: int, start: tuple[float, float], velocity: tuple[float, float], size=(20.0, 50.0)):
    return (start[0] + velocity[0] * t, start[1] + velocity[1] * t, *size)


#: Two walkers; the second leaves after frame 4 (0-based) and a third enters at frame 9.
SCENE = _detections(
    [
        [_walk(t, (100, 100), (3, 0))]
        + ([_walk(t, (300, 200), (-2, 0), (30, 60))] if t < 5 else [])
        + ([_walk(t - 9, (500, 300), (0, -2), (25, 55))] if t >= 9 else [])
        for t in range(13)
    ],
    capacity=3,
)
FILTER = mixture_filter(2, 16)
RUN = jax.jit(lambda key, params, detections: run(FILTER, key, params, detections))
STEP = jax.jit(FILTER.step)
ADD = jax.jit(add_component, static_argnums=4)


def _kalman(z0, measurements, params: MixtureParams):
    """NumPy Kalman filter of the constant-velocity box model with constant noise.

    The prior is the component :func:`add_component` starts from a box: ``(y1, y2, w, h)``
    spread by the measurement noise, zero velocity exactly.
    """
    r = np.asarray(params.measurement_noise_std, np.float64)
    q = np.asarray(params.motion_noise_std, np.float64)
    f = np.asarray(transition_matrix(), np.float64)
    gain = np.asarray(noise_gain(), np.float64)
    h = np.zeros((4, 6))
    h[[0, 1, 2, 3], [0, 2, 4, 5]] = 1.0
    mean = h.T @ z0
    cov = h.T @ np.diag(r**2) @ h
    for z in measurements:
        mean, cov = f @ mean, f @ cov @ f.T + gain @ np.diag(q**2) @ gain.T
        s = h @ cov @ h.T + np.diag(r**2)
        k = cov @ h.T @ np.linalg.inv(s)
        mean, cov = mean + k @ (z - h @ mean), (np.eye(6) - k @ h) @ cov
    return mean, cov


def test_one_component_bootstrap_approaches_kalman():
    """Bootstrap proposal, one detection a frame, constant noise: every component is a plain
    bootstrap particle filter, so 16 components started from the same box are 16 independent
    filters (2000 particles each) whose pooled posterior mean lies within 0.15 posterior
    std of the Kalman filter's (measured: 0.05), variances within 10% (measured: 5%)."""
    num_components, num_particles, num_frames = 16, 2000, 5
    boxes = [_walk(t, (200, 150), (4, -2), (40, 80)) for t in range(num_frames + 1)]
    detections = _detections([[box] for box in boxes[1:]], capacity=2)
    filt = mixture_filter(num_components, num_particles, noise_model=constant_std)
    state = init_mixture(jax.random.key(0), LINEAR, num_components, num_particles)
    for key in jax.random.split(jax.random.key(1), num_components):
        state, _ = ADD(key, state, jnp.asarray(boxes[0]), LINEAR, constant_std)
    step = jax.jit(filt.step)
    for t, key in enumerate(jax.random.split(jax.random.key(2), num_frames)):
        state, info = step(key, state, LINEAR, _frame(detections, t))
    particles = np.asarray(state.particles, np.float64).reshape(-1, 6)
    mean, cov = _kalman(_centre(boxes[0]), [_centre(b) for b in boxes[1:]], LINEAR)
    std = np.sqrt(np.diag(cov))
    np.testing.assert_array_less(np.abs(particles.mean(axis=0) - mean), 0.15 * std)
    np.testing.assert_allclose(particles.var(axis=0), np.diag(cov), rtol=0.1)
    assert np.all(np.asarray(state.alive)) and list(state.ids) == list(range(num_components))
    assert not bool(info.overflow)


def _centre(box):
    """``(y1, y2, w, h)`` of an ``(x, y, w, h)`` box."""
    return np.array([box[0] + box[2] / 2, box[1] + box[3] / 2, box[2], box[3]])


def test_mixture_weights_match_eq4_with_a_dead_component():
    rng = np.random.default_rng(0)
    log_pi = np.log(np.array([0.5, 0.3, 0.2, 1.0]))
    log_w = rng.normal(-3.0, 1.0, (4, 6))
    alive = np.array([True, True, True, False])
    new, log_support, total = mixture_weights(
        jnp.asarray(log_pi, jnp.float32), jnp.asarray(log_w, jnp.float32), jnp.asarray(alive)
    )
    w_m = np.exp(log_w).sum(axis=1)
    joint = np.exp(log_pi[:3]) * w_m[:3]
    np.testing.assert_allclose(np.exp(new[:3]), joint / joint.sum(), rtol=1e-5)
    assert float(new[3]) == np.float32(LOG_ZERO)
    np.testing.assert_allclose(log_support, np.log(w_m), rtol=1e-5)
    np.testing.assert_allclose(total, np.log(joint.sum()), rtol=1e-5)
    none_alive = mixture_weights(jnp.zeros(4), jnp.zeros((4, 6)), jnp.zeros(4, bool))
    assert np.all(np.asarray(none_alive[0]) == np.float32(LOG_ZERO)) and float(none_alive[2]) == 0.0


def _shifted_proposal(key, particles, params, inputs_t, shift):
    """Constant-velocity draws with noise ``n ~ N(shift, I)`` instead of ``N(0, I)``."""
    del inputs_t
    std = constant_std(particles[..., 4:], params.motion_noise_std)
    noise = shift + jax.random.normal(key, std.shape)
    new = particles @ transition_matrix().T + (std * noise) @ noise_gain().T
    log_q = jnp.sum(norm.logpdf(np.zeros(1)) - 0.5 * (noise - shift) ** 2 - jnp.log(std), -1)
    return new, log_q


def _cloud(key, num_particles):
    """One component's particles around a box, with velocities, equally weighted."""
    state = init_mixture(key, LINEAR, 1, num_particles)
    box = jnp.array([200.0, 150.0, 40.0, 80.0])
    state, _ = ADD(key, state, box, LINEAR, constant_std)
    velocity = 2.0 * jax.random.normal(jax.random.key(9), (num_particles, 2))
    return state.particles.at[0, :, 1].set(velocity[:, 0]).at[0, :, 3].set(velocity[:, 1])


def _eq3_by_hand(new, old, z, shift):
    """NumPy ``log w_{t-1} + log p(z|x) + log p(x|x') - log q(x|x', z)`` of one component
    (``w_{t-1}`` uniform; the shifted proposal; constant noise :data:`LINEAR`)."""
    x, x_old = np.asarray(new[0], np.float64), np.asarray(old[0], np.float64)
    q, r = np.asarray(LINEAR.motion_noise_std), np.asarray(LINEAR.measurement_noise_std)
    n = np.concatenate([x[:, [1, 3]] - x_old[:, [1, 3]], x[:, 4:] - x_old[:, 4:]], 1) / q
    return (
        -math.log(x.shape[0])
        + norm.logpdf(_centre(z), x[:, [0, 2, 4, 5]], r).sum(1)
        + norm.logpdf(n).sum(1)
        - norm.logpdf(n, np.asarray(shift)).sum(1)
    )


def test_proposal_log_density_enters_the_weights_exactly():
    """Eq. 3 with a shifted proposal: weights equal ``p(z|x) p(x|x') / q`` from NumPy, in the
    stage and through the builder's injected proposal (the step's ``log w_m``)."""
    shift = jnp.array([0.8, -0.5, 0.3, 0.0])
    particles = _cloud(jax.random.key(0), 64)
    box = (205.0, 148.0, 40.0, 80.0)
    frame = _frame(_detections([[box]], capacity=2), 0)
    new, log_q = _shifted_proposal(jax.random.key(1), particles, LINEAR, frame, shift)
    log_like = nearest_detection_log_likelihood(new, LINEAR, frame, constant_std)
    log_old = jnp.full((1, 64), -math.log(64))
    weights = reweight(
        log_old, log_like, log_transition(new, particles, LINEAR, constant_std), log_q
    )
    expected = _eq3_by_hand(new, particles, box, shift)
    np.testing.assert_allclose(weights[0], expected, rtol=1e-4, atol=1e-3)
    propose = functools.partial(_shifted_proposal, shift=shift)
    filt = mixture_filter(1, 64, propose=propose, noise_model=constant_std)
    state = filt.init(jax.random.key(0), LINEAR)._replace(
        particles=particles, alive=jnp.array([True]), log_mixture_weights=jnp.zeros(1)
    )
    step_key = jax.random.key(5)
    _, info = jax.jit(filt.step)(step_key, state, LINEAR, frame)
    # The step's first key goes to the proposal.
    new, _ = propose(jax.random.split(step_key, 3)[0], particles, LINEAR, frame)
    expected = logsumexp(_eq3_by_hand(new, particles, box, shift))
    np.testing.assert_allclose(info.log_support[0], expected, rtol=1e-4)


def test_shifted_proposal_estimates_the_bootstrap_mean():
    """Importance weighting corrects the shift: with 20000 particles the weighted means of a
    shifted and the bootstrap proposal agree within 0.3 px (their spread is about 2 px)."""
    num_particles = 20000
    particles = _cloud(jax.random.key(0), num_particles)
    frame = _frame(_detections([[(205.0, 148.0, 40.0, 80.0)]], capacity=2), 0)
    means = []
    for propose in (
        functools.partial(_shifted_proposal, shift=jnp.array([0.5, -0.5, 0.2, 0.2])),
        functools.partial(bootstrap_proposal, noise_model=constant_std),
    ):
        new, log_q = propose(jax.random.key(1), particles, LINEAR, frame)
        log_w = reweight(
            jnp.zeros((1, num_particles)),
            nearest_detection_log_likelihood(new, LINEAR, frame, constant_std),
            log_transition(new, particles, LINEAR, constant_std),
            log_q,
        )
        means.append(np.exp(normalise_weights(log_w)[0]) @ np.asarray(new[0]))
    np.testing.assert_allclose(means[0], means[1], atol=0.3)


def test_local_estimate_is_the_heaviest_clusters_weighted_mean():
    rng = np.random.default_rng(1)
    near = rng.normal([100.0, 0, 50, 0, 20, 40], 1.0, (12, 6))
    far = rng.normal([300.0, 0, 80, 0, 30, 60], 1.0, (8, 6))
    weights = np.concatenate([rng.uniform(0.5, 1.0, 12) * 0.3, rng.uniform(0.5, 1.0, 8)])
    particles = np.concatenate([near, far])
    estimate = jax.jit(local_estimate)(jnp.asarray(particles), jnp.log(jnp.asarray(weights)))
    heavy = weights[12:] / weights[12:].sum()
    np.testing.assert_allclose(estimate, heavy @ far, rtol=1e-5)
    single = local_estimate(jnp.asarray(near), jnp.zeros(12))
    np.testing.assert_allclose(single, near.mean(axis=0), rtol=1e-3, atol=0.5)


def test_resampling_stays_within_each_component():
    particles = jnp.arange(3 * 5, dtype=jnp.float32).reshape(3, 5, 1) * jnp.ones(6)
    log_w = jnp.log(jnp.array([[1, 0, 0, 0, 0], [0, 0, 1, 1, 0], [1, 1, 1, 1, 1.0]]))
    new, new_log_w = jax.jit(resample_components)(jax.random.key(0), particles, log_w)
    values = np.asarray(new[..., 0])
    assert (
        np.all(values[0] == 0)
        and set(values[1]) <= {7.0, 8.0}
        and set(values[2]) <= set(range(10, 15))
    )
    np.testing.assert_allclose(new_log_w, np.full((3, 5), -math.log(5)), rtol=1e-6)


def test_deletion_and_new_components():
    """``pi`` and support thresholds delete; a new box fills the first dead slot, new id."""
    state = init_mixture(jax.random.key(0), PARAMS, 3, 4)
    for box in ([10.0, 10, 20, 40], [100.0, 10, 20, 40], [200.0, 10, 20, 40]):
        state, full = ADD(jax.random.key(1), state, jnp.asarray(box), PARAMS, state_dependent_std)
        assert not bool(full)
    np.testing.assert_allclose(np.exp(state.log_mixture_weights), [1 / 3] * 3, rtol=1e-5)
    state, full = ADD(
        jax.random.key(2), state, jnp.array([9.0, 9, 9, 9]), PARAMS, state_dependent_std
    )
    assert bool(full) and list(state.ids) == [0, 1, 2] and int(state.next_id) == 3
    state = state._replace(log_mixture_weights=jnp.log(jnp.array([0.6, 0.3999, 1e-4])))
    state, deleted = jax.jit(delete_components)(state, jnp.array([-1.0, -30.0, -1.0]), PARAMS)
    assert list(deleted) == [False, True, True] and list(state.ids) == [0, -1, -1]
    np.testing.assert_allclose(np.exp(state.log_mixture_weights), [1.0, 0, 0], atol=1e-6)
    state, _ = ADD(
        jax.random.key(3), state, jnp.array([50.0, 60, 20, 40]), PARAMS, state_dependent_std
    )
    assert list(state.ids) == [0, 3, -1] and list(state.alive) == [True, True, False]
    np.testing.assert_allclose(np.exp(state.log_mixture_weights), [0.5, 0.5, 0], atol=1e-6)
    np.testing.assert_allclose(
        np.asarray(state.particles[1, :, [0, 2, 4, 5]]).mean(axis=1), [60, 80, 20, 40], atol=5
    )


def test_scene_ids_persist_per_slot_and_leavers_are_deleted():
    _, info = RUN(jax.random.key(0), PARAMS, SCENE)
    ids, mask = np.asarray(info.tracks.ids), np.asarray(info.tracks.mask)
    assert not mask[0].any()  # components start after their first detection
    assert np.all(ids[1:, 0] == 0)  # the first walker keeps slot 0 and id 0 throughout
    assert np.all(ids[1:5, 1] == 1)  # the second, until it leaves
    deleted_at = np.flatnonzero(np.asarray(info.deleted)[:, 1])
    assert deleted_at.tolist() == [5]
    assert np.all(ids[5:10, 1] == -1) and np.all(ids[10:, 1] == 2)  # the third, a new id
    truth = np.array([_walk(t, (100, 100), (3, 0)) for t in range(1, 13)])
    np.testing.assert_allclose(info.tracks.boxes[1:, 0], truth, atol=6.0)
    assert not np.asarray(info.overflow).any()
    assert np.all(np.isfinite(info.log_likelihood))


def test_overflow_is_reported_when_slots_run_out():
    """The walkers of frame 0 are explained; a third box finds no slot until one is freed."""
    state = _two_components()
    frame = _frame(_detections([[*_frame_boxes(0), (500.0, 300.0, 25.0, 55.0)]], 3), 0)
    add = jax.jit(add_unexplained)
    full, overflow = add(jax.random.key(0), state, frame, PARAMS)
    assert bool(overflow)
    jax.tree.map(np.testing.assert_array_equal, full, state)
    freed = state._replace(alive=state.alive.at[1].set(False), ids=state.ids.at[1].set(-1))
    without_second = _frame(_detections([[_frame_boxes(0)[0], (500.0, 300.0, 25.0, 55.0)]], 3), 0)
    added, overflow = add(jax.random.key(0), freed, without_second, PARAMS)
    assert not bool(overflow) and list(added.ids) == [0, 2]
    np.testing.assert_allclose(added.particles[1, :, 0].mean(), 512.5, atol=3.0)


def _frame_boxes(t: int) -> list[tuple[float, ...]]:
    """The real boxes of :data:`SCENE`'s frame ``t``."""
    frame = _frame(SCENE, t)
    return [tuple(map(float, box)) for box in np.asarray(frame.boxes)[np.asarray(frame.mask)]]


@pytest.mark.slow
def test_jit_equals_eager():
    """One step from two living components (eager: op by op, about 5 s of tiny compiles)."""
    state = _two_components()
    frame = _frame(SCENE, 1)
    jitted = STEP(jax.random.key(4), state, PARAMS, frame)
    with jax.disable_jit():
        eager = FILTER.step(jax.random.key(4), state, PARAMS, frame)
    jax.tree.map(lambda a, b: np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-3), jitted, eager)
    assert np.asarray(jitted[1].tracks.mask).sum() == 2


def _two_components():
    """A mixture with the two walkers of :data:`SCENE`'s first frame as components."""
    state = init_mixture(jax.random.key(0), PARAMS, 2, 16)
    for key, box in zip(jax.random.split(jax.random.key(1)), SCENE.boxes[0, :2], strict=True):
        state, _ = ADD(key, state, box, PARAMS, state_dependent_std)
    return state


def test_vmap_over_params_equals_loop():
    batch = jax.tree.map(
        lambda *x: jnp.stack(x),
        PARAMS,
        PARAMS._replace(
            measurement_noise_std=jnp.array([0.2, 0.2, 0.15, 0.15]),
            min_log_support=jnp.array(-20.0),
        ),
    )
    _, batched = jax.jit(jax.vmap(lambda p: run(FILTER, jax.random.key(5), p, SCENE)))(batch)
    for i in range(2):
        _, single = RUN(jax.random.key(5), jax.tree.map(lambda x, i=i: x[i], batch), SCENE)
        jax.tree.map(
            lambda a, b, i=i: np.testing.assert_allclose(a[i], b, rtol=1e-4, atol=1e-3),
            batched,
            single,
        )
    assert not np.allclose(batched.log_likelihood[0], batched.log_likelihood[1])


def test_gradient_of_the_frame_likelihood_matches_finite_differences():
    """``d log sum_j pi_j w_j / d measurement_noise_std`` on one frame (no resampling in
    the path): autodiff equals central differences within 2%; over a whole run the gradient
    w.r.t. both noise vectors is finite and non-zero."""
    state = _two_components()
    frame = _frame(SCENE, 1)

    @jax.jit
    def frame_log_likelihood(std):
        params = PARAMS._replace(measurement_noise_std=std)
        return STEP(jax.random.key(3), state, params, frame)[1].log_likelihood

    std = jnp.array([0.12, 0.1, 0.1, 0.08])
    grad = jax.grad(frame_log_likelihood)(std)
    eps = 1e-3
    numeric = [
        (frame_log_likelihood(std.at[i].add(eps)) - frame_log_likelihood(std.at[i].add(-eps)))
        / (2 * eps)
        for i in range(4)
    ]
    np.testing.assert_allclose(grad, numeric, rtol=0.02)

    def total(params):
        return jnp.sum(run(FILTER, jax.random.key(0), params, SCENE)[1].log_likelihood)

    grads = jax.jit(jax.grad(total))(PARAMS)
    for leaf in (grads.measurement_noise_std, grads.motion_noise_std):
        assert np.all(np.isfinite(leaf)) and np.any(np.asarray(leaf) != 0)


def test_one_compile_across_detection_counts():
    traces = []

    def counted(particles, params, inputs_t):
        traces.append(1)
        return nearest_detection_log_likelihood(particles, params, inputs_t)

    filt = mixture_filter(2, 8, likelihood=counted)
    step = jax.jit(filt.step)
    state = filt.init(jax.random.key(0), PARAMS)
    for t in (0, 5, 9, 12):  # 2, 1, 2 and 2 detections; then none
        state, _ = step(jax.random.key(t), state, PARAMS, _frame(SCENE, t))
    empty = jax.tree.map(lambda x: x.at[:].set(False) if x.dtype == bool else x, _frame(SCENE, 0))
    state, info = step(jax.random.key(99), state, PARAMS, empty)
    assert len(traces) == 1
    assert np.all(np.isfinite(state.log_weights)) and np.isfinite(info.log_likelihood)


@pytest.mark.parametrize("sizes", [(0, 40), (2, 0)])
def test_builder_rejects_bad_sizes(sizes):
    with pytest.raises(ValueError, match="must be positive"):
        mixture_filter(*sizes)
