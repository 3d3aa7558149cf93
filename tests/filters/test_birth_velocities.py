"""The births' velocity proposal from the previous frame's detections (``"detections"``).

Oracles: a float64 NumPy evaluation of ``q(v | p)``; the proposal's draws against its density
integrated over regions of the velocity plane; the births' unbiasedness against a closed-form
``int gamma(x) g(z | x) dx`` for a Gaussian birth intensity, under both proposals; and a
target whose velocity is known.
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.context.intensity import Intensity
from jaxtrack.errors import InputError
from jaxtrack.filters.births import (
    PREVIOUS_SLOTS,
    SIZE_GATE,
    UNIFORM_VELOCITY_SHARE,
    PreviousDetections,
    draw_births,
    keep_previous_detections,
    no_previous_detections,
    propose_velocities,
    sample_births,
)
from jaxtrack.filters.phd import phd_filter
from jaxtrack.filters.phd_defaults import default_phd_params
from jaxtrack.filters.phd_tracker import PHDConfig, phd_filter_of
from jaxtrack.models import constant_std, log_likelihood
from jaxtrack.types import PAD_BOX, Detections

LOWER, UPPER = np.array([-20.0, -20.0]), np.array([20.0, 20.0])
NOISE = np.array([4.0, 6.0, 5.0, 8.0])  # constant noise, pixels


def _previous(boxes, dtype=jnp.float64) -> PreviousDetections:
    boxes = np.asarray(boxes, float).reshape(-1, 4)
    padded = np.ones((PREVIOUS_SLOTS, 4))
    padded[: len(boxes)] = boxes
    mask = np.arange(PREVIOUS_SLOTS) < len(boxes)
    return PreviousDetections(jnp.asarray(padded, dtype), jnp.asarray(mask))


def _numpy_log_density(points, velocity, previous_boxes, noise=NOISE):
    """log q(v | p) written out in float64 NumPy (points and velocities ``[n, .]``)."""
    eps = UNIFORM_VELOCITY_SHARE
    inside_v = np.all((velocity >= LOWER) & (velocity <= UPPER), axis=1)
    uniform = np.where(inside_v, 1 / np.prod(UPPER - LOWER), 0.0)
    shift = points[:, None, :2] - previous_boxes[None, :, :2]  # [n, m, 2]
    reachable = np.all((shift >= LOWER) & (shift <= UPPER), axis=2)
    size_var, var = 2 * noise[2:] ** 2, 2 * noise[:2] ** 2
    size_gap = points[:, None, 2:] - previous_boxes[None, :, 2:]
    squares = np.sum(size_gap**2 / size_var, axis=2)
    shares = np.where(reachable & (squares <= SIZE_GATE), np.exp(-0.5 * squares), 0.0)
    total = shares.sum(axis=1, keepdims=True)
    shares = shares / np.where(total > 0, total, 1.0)
    gauss = np.exp(-0.5 * np.sum((velocity[:, None] - shift) ** 2 / var, axis=2)) / (
        2 * np.pi * np.sqrt(np.prod(var))
    )
    mixed = eps * uniform + (1 - eps) * np.sum(shares * gauss, axis=1)
    with np.errstate(divide="ignore"):
        return np.log(np.where(total[:, 0] > 0, mixed, uniform))


def _propose(points, previous, key, uniform_velocity=None):
    n = points.shape[0]
    k1, k2, k3 = jax.random.split(key, 3)
    dtype = points.dtype
    if uniform_velocity is None:
        uniform_velocity = jax.random.uniform(k1, (n, 2), dtype, LOWER, UPPER)
    return propose_velocities(
        points,
        uniform_velocity,
        jnp.asarray(LOWER, dtype),
        jnp.asarray(UPPER, dtype),
        previous,
        std_of=functools.partial(constant_std, noise_std=jnp.asarray(NOISE, dtype)),
        offsets=jax.random.normal(k2, (n, 2), dtype),
        choices=jax.random.uniform(k3, (n, 2), dtype),
    )


def test_log_density_matches_a_float64_numpy_reference():
    """Previous boxes: two reachable (different sizes), one beyond the speed range, one of
    another size; births near them and one with no reachable previous box (density = the
    uniform's)."""
    rng = np.random.default_rng(3)
    previous_boxes = np.array(
        [
            [100.0, 100.0, 30.0, 70.0],
            [130.0, 95.0, 40.0, 90.0],
            [300.0, 300.0, 30.0, 70.0],  # beyond the speed range
            [115.0, 105.0, 10.0, 30.0],  # within reach, of another size: gated out
        ]
    )
    points = np.concatenate(
        [
            np.array([110.0, 100.0, 31.0, 72.0]) + rng.normal(0, [3, 3, 2, 4], (40, 4)),
            [[500.0, 40.0, 30.0, 70.0]],
        ]
    )
    with jax.enable_x64(True):
        velocity, log_q = _propose(
            jnp.asarray(points), _previous(previous_boxes), jax.random.key(0)
        )
        velocity, log_q = np.asarray(velocity), np.asarray(log_q)
    np.testing.assert_allclose(
        log_q, _numpy_log_density(points, velocity, previous_boxes), rtol=1e-10
    )
    # The last birth has no reachable previous box: its velocity is the uniform draw.
    np.testing.assert_allclose(log_q[-1], -np.log(np.prod(UPPER - LOWER)), rtol=1e-12)


def test_a_box_of_another_size_is_no_candidate_and_the_weights_stay_bounded():
    """A thin box (9 px wide) after a wide one (54 px) at the same place: without the size
    gate its share underflowed to a subnormal that float32 arithmetic flushed to zero in the
    density but not in the pick, and one birth's weight reached 1e26 (uniform-0, frame 117).
    With the gate every velocity is the uniform draw, with the uniform density."""
    measurements = jnp.asarray([[79.2, 451.3, 9.16, 113.9]], jnp.float32)
    lower, upper = jnp.asarray(LOWER, jnp.float32), jnp.asarray(UPPER, jnp.float32)
    previous = _previous([[82.5, 445.7, 53.8, 134.0]], jnp.float32)
    draws = draw_births(
        jax.random.key(3),
        measurements,
        jnp.array([True]),
        256,
        lower,
        upper,
        jnp.array([0.15, 0.08, 0.25, 0.15]),
        velocities="detections",
        previous=previous,
    )
    np.testing.assert_allclose(draws.log_velocity_weight, np.log(np.prod(UPPER - LOWER)), rtol=1e-6)


def test_draws_follow_the_density_they_report():
    """Empirical probabilities of regions of the velocity plane against ``q`` integrated over
    them on a fine grid (one birth box, two previous boxes of different sizes; the Gaussian
    parts reach beyond ``V_v``, so the grid does too)."""
    point = np.array([[110.0, 100.0, 31.0, 72.0]])
    previous_boxes = np.array([[100.0, 100.0, 30.0, 70.0], [125.0, 92.0, 40.0, 80.0]])
    n = 100_000
    points = jnp.asarray(np.repeat(point, n, axis=0))
    with jax.enable_x64(True):
        velocity, _ = _propose(points, _previous(previous_boxes), jax.random.key(1))
        velocity = np.asarray(velocity)
    step = 0.1
    grid = np.arange(-60 + step / 2, 60, step)
    vx, vy = np.meshgrid(grid, grid, indexing="ij")
    cells = np.stack([vx.ravel(), vy.ravel()], -1)
    density = np.exp(
        _numpy_log_density(np.repeat(point, len(cells), 0), cells, previous_boxes)
    ).reshape(vx.shape)
    assert abs(density.sum() * step**2 - 1) < 1e-3
    regions = [  # (vx range, vy range): around each displacement, and elsewhere
        ((5.0, 15.0), (-5.0, 5.0)),
        ((-20.0, -5.0), (0.0, 20.0)),
        ((-10.0, 0.0), (3.0, 13.0)),
        ((-20.0, 20.0), (-20.0, -10.0)),
        ((-60.0, -20.0), (-60.0, 60.0)),
    ]
    for (x0, x1), (y0, y1) in regions:
        inside = (vx >= x0) & (vx < x1) & (vy >= y0) & (vy < y1)
        expected = density[inside].sum() * step**2
        observed = np.mean(
            (velocity[:, 0] >= x0)
            & (velocity[:, 0] < x1)
            & (velocity[:, 1] >= y0)
            & (velocity[:, 1] < y1)
        )
        assert abs(observed - expected) < 4 * math.sqrt(expected * (1 - expected) / n) + 2e-3


def _gaussian_birth(mean, velocity_std, magnitude=0.3):
    """A one-Gaussian birth intensity over (y1, vy1, y2, vy2, w, h), no uniform part."""
    var = np.array([20.0, velocity_std, 20.0, velocity_std, 6.0, 10.0]) ** 2
    return Intensity(
        magnitude=jnp.asarray(magnitude),
        uniform_weight=jnp.asarray(0.0),
        lower=jnp.array([0.0, LOWER[0], 0.0, LOWER[1], 1.0, 1.0]),
        upper=jnp.array([640.0, UPPER[0], 480.0, UPPER[1], 640.0, 480.0]),
        weights=jnp.array([1.0]),
        means=jnp.asarray([mean], jnp.float32),
        covs=jnp.asarray([np.diag(var)], jnp.float32),
    ), var


def test_both_proposals_estimate_the_same_birth_intensity_near_a_detection():
    """``E[sum_b w_b g(z | x_b)] = int gamma(x) g(z | x) dx``, in closed form for a Gaussian
    ``gamma`` and constant noise: ``lambda N(z; C mu, C Sigma C^T + R)`` (the velocity
    integrates out). The intensity's velocities sit at (6, -2) px/frame; the previous frame
    had a box displaced by that much, so the detections' proposal is the sharper one."""
    detection = np.array([200.0, 150.0, 40.0, 90.0])
    mean = np.array([205.0, 6.0, 150.0, -2.0, 40.0, 90.0])
    birth, var = _gaussian_birth(mean, velocity_std=1.0)
    z = detection + NOISE * np.array([1.0, -0.5, 0.3, 0.2])
    measured_var = var[[0, 2, 4, 5]] + NOISE**2
    diff = z - mean[[0, 2, 4, 5]]
    expected = (
        0.3
        * np.exp(-0.5 * np.sum(diff**2 / measured_var))
        / np.sqrt((2 * np.pi) ** 4 * np.prod(measured_var))
    )
    measurements = jnp.asarray([detection, PAD_BOX], jnp.float32)
    mask = jnp.array([True, False])
    previous = _previous([detection - np.array([6.0, -2.0, 0.0, 0.0])], jnp.float32)
    noise = jnp.asarray(NOISE, jnp.float32)

    def estimate(key, velocities):
        states, log_weights = sample_births(
            key,
            measurements,
            mask,
            32,
            birth,
            birth,
            jnp.asarray(True),
            noise,
            constant_std,
            velocities=velocities,
            previous=previous,
        )
        log_g = log_likelihood(jnp.asarray(z[None], jnp.float32), states, noise, constant_std)[0]
        return jnp.sum(jnp.exp(log_weights + log_g))

    keys = jax.random.split(jax.random.key(2), 2000)
    results = {}
    for velocities in ("uniform", "detections"):
        values = np.asarray(jax.vmap(lambda k, v=velocities: estimate(k, v))(keys), np.float64)
        results[velocities] = values
        assert abs(values.mean() - expected) < 4 * values.std() / np.sqrt(values.size)
    # The point of the proposal: a smaller Monte Carlo error at the target's velocity (here
    # 0.63 times the uniform proposal's standard deviation; the rest is the box's share).
    assert results["detections"].std() < 0.75 * results["uniform"].std()


def test_draw_births_refuses_a_bad_proposal_or_a_missing_previous_frame():
    args = (jnp.asarray([[200.0, 150.0, 40.0, 90.0]]), jnp.array([True]), 4)
    bounds = (jnp.asarray(LOWER, jnp.float32), jnp.asarray(UPPER, jnp.float32), jnp.asarray(NOISE))
    with pytest.raises(ValueError, match="velocities must be one of"):
        draw_births(jax.random.key(0), *args, *bounds, velocities="gaussian")
    with pytest.raises(ValueError, match="previous frame"):
        draw_births(jax.random.key(0), *args, *bounds, velocities="detections")


def test_kept_previous_detections_do_not_depend_on_the_frame_s_padding():
    boxes = jnp.asarray([[10.0, 20.0, 30.0, 40.0], [1.0, 2.0, 3.0, 4.0], PAD_BOX, PAD_BOX])
    mask = jnp.array([True, False, False, False])
    full, half = (
        keep_previous_detections(boxes, mask),
        keep_previous_detections(boxes[:2], mask[:2]),
    )
    for a, b in zip(full, half, strict=True):
        np.testing.assert_array_equal(a, b)
    assert full.boxes.shape == (PREVIOUS_SLOTS, 4) and int(full.mask.sum()) == 1
    np.testing.assert_array_equal(full.boxes[1:], 1.0)
    empty = no_previous_detections()
    assert not bool(empty.mask.any()) and empty.boxes.shape == (PREVIOUS_SLOTS, 4)


def _two_steps(velocities: str):
    """Two float32 steps of a 256-particle filter on a target moving (12, -3) px/frame."""
    filt = phd_filter(256, births_per_detection=16, birth_velocities=velocities)
    params = default_phd_params(640.0, 480.0, 25.0)
    key = jax.random.key(4)
    state, outputs = filt.init(key, params), []
    for frame in range(2):
        box = [100.0 + 12 * frame, 300.0 - 3 * frame, 30.0, 70.0]
        detections = Detections(
            boxes=jnp.asarray([box, PAD_BOX, PAD_BOX], jnp.float32),
            scores=jnp.array([0.99, 0.0, 0.0]),
            mask=jnp.array([True, False, False]),
        )
        state, info = jax.jit(filt.step)(jax.random.fold_in(key, frame), state, params, detections)
        outputs.append((state, info))
    return outputs


def test_the_state_keeps_the_frame_s_detections_and_the_first_frame_is_the_uniform_proposal_s():
    """Before the first frame there is no previous detection, so every velocity is the
    uniform draw (the same numbers) with the uniform density: the first step equals the
    uniform proposal's bit for bit. The second differs, and the state holds the frame's
    detection (centre form) for the next step."""
    uniform, detections = _two_steps("uniform"), _two_steps("detections")
    for a, b in zip(jax.tree.leaves(uniform[0]), jax.tree.leaves(detections[0]), strict=True):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(uniform[1][0].particles, detections[1][0].particles)
    previous = detections[1][0].previous
    np.testing.assert_allclose(previous.boxes[0], [127.0, 332.0, 30.0, 70.0])
    assert previous.mask.tolist() == [True] + [False] * (PREVIOUS_SLOTS - 1)


def test_the_tracker_default_is_the_uniform_proposal_and_bad_values_are_refused():
    assert PHDConfig().birth_velocity == "uniform"
    with pytest.raises(InputError, match="birth_velocity"):
        PHDConfig(birth_velocity="gaussian")
    proposal = phd_filter_of(PHDConfig(birth_velocity="detections"))
    assert proposal is not phd_filter_of(PHDConfig())
    state = proposal.init(jax.random.key(0), None)
    assert state.previous.mask.shape == (PREVIOUS_SLOTS,) and not bool(state.previous.mask.any())
