"""Fusion's motion predictor: GP posterior vs NumPy, a turning road, fallback, jit and vmap."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.context.motion_models import (
    Tracklets,
    cut_tracklets,
    fit_motion_models,
    mean_velocity,
    tracklet_cells,
    tracklet_inputs,
)
from jaxtrack.filters.fusion_motion import predict_motion, predict_one
from tests.context.motion_scenes import TURN_CENTRE, TURN_RADIUS, road_walkers


@pytest.fixture(scope="module")
def random_models():
    """One 100 x 100 cell of 30 random moving tracklets (and three empty cells)."""
    rng = np.random.default_rng(0)
    points = np.cumsum(rng.normal(1.0, 1.0, (30, 6, 2)), axis=1) + 20
    tracklets = Tracklets(points[:, :5], points[:, 5])
    models = fit_motion_models(tracklets, 200, 200, cell_size=100, min_displacement=0.0)
    return models, tracklets


def reference_posterior(models, tracklets, query):
    """Textbook GP posterior of the residual (R&W eq. 2.25-2.26) on the real points only."""
    train = tracklet_inputs(np.asarray(tracklets.points, float))
    residuals = (
        np.asarray(tracklets.next_points)
        - tracklets.points[:, -1]
        - mean_velocity(tracklets.points)
    )
    scale, amplitude, noise = (
        float(v) for v in (models.length_scale, models.amplitude, models.noise)
    )

    def kernel(a, b):
        return amplitude * np.exp(-((a[:, None] - b[None]) ** 2).sum(-1) / (2 * scale**2))

    gram = kernel(train, train) + noise * np.eye(len(train))
    row = kernel(train, tracklet_inputs(query)[None])[:, 0]
    mean = query[-1] + mean_velocity(query) + row @ np.linalg.solve(gram, residuals)
    variance = amplitude - row @ np.linalg.solve(gram, row) + noise
    return mean, variance


def test_posterior_mean_and_variance_match_numpy(random_models):
    models, tracklets = random_models
    rng = np.random.default_rng(1)
    queries = np.cumsum(rng.normal(1.0, 1.0, (8, 5, 2)), axis=1) + 20
    queries[0] = tracklets.points[3]  # on a training input: variance near the noise
    points, variance = predict_motion(models, jnp.asarray(queries, jnp.float32), jnp.ones(8, bool))
    for s, query in enumerate(queries):
        mean, var = reference_posterior(models, tracklets, query)
        np.testing.assert_allclose(points[s], mean, rtol=1e-4, atol=2e-3)
        np.testing.assert_allclose(variance[s], var, rtol=1e-3, atol=2e-4)
    # on a training input the variance drops at least as much as with that one point alone,
    # by s^4 / (s^2 + sigma^2) (analytic)
    prior = float(models.amplitude + models.noise)
    assert prior - float(variance[0]) >= float(models.amplitude) ** 2 / prior - 1e-4


def test_fallback_cells_and_invalid_slots_give_constant_velocity(random_models):
    models, _ = random_models
    queries = np.array(
        [
            [[150.0, 150], [152, 151], [154, 152], [156, 153], [158, 154]],  # unfitted cell
            [[20.0, 20], [21, 22], [23, 23], [24, 25], [26, 26]],  # fitted cell, invalid slot
        ]
    )
    points, variance = predict_motion(
        models, jnp.asarray(queries, jnp.float32), jnp.array([1, 0], bool)
    )
    np.testing.assert_allclose(points, queries[:, -1] + mean_velocity(queries), rtol=1e-6)
    np.testing.assert_allclose(variance, float(models.amplitude + models.noise), rtol=1e-6)


def test_prediction_beats_constant_velocity_in_the_turn_and_matches_it_on_straights():
    train = cut_tracklets(road_walkers(seed=0, num_walkers=60))
    test = cut_tracklets(road_walkers(seed=1, num_walkers=30))
    models = fit_motion_models(train, 640, 480, cell_size=64)
    points, _ = jax.jit(predict_motion)(
        models, jnp.asarray(test.points, jnp.float32), jnp.ones(len(test.points), bool)
    )
    constant = test.points[:, -1] + mean_velocity(test.points)
    gp_error = np.linalg.norm(np.asarray(points) - test.next_points, axis=1)
    cv_error = np.linalg.norm(constant - test.next_points, axis=1)
    last = test.points[:, -1]
    on_arc = np.abs(np.linalg.norm(last - TURN_CENTRE, axis=1) - TURN_RADIUS) < 3
    turning = on_arc & (last[:, 0] > TURN_CENTRE[0]) & (last[:, 1] < TURN_CENTRE[1])
    straight = (last[:, 0] < 250) | (last[:, 1] > 260)
    assert turning.sum() > 100 and straight.sum() > 300
    assert gp_error[turning].mean() < 0.8 * cv_error[turning].mean()  # measured 0.41 vs 0.60
    assert gp_error[straight].mean() < 1.05 * cv_error[straight].mean()


def test_jit_equals_eager_and_vmap_equals_loop(random_models):
    models, _ = random_models
    rng = np.random.default_rng(2)
    queries = jnp.asarray(
        np.cumsum(rng.normal(1.0, 2.0, (6, 5, 2)), axis=1)
        + np.repeat([20.0, 150.0], 3)[:, None, None],
        jnp.float32,
    )
    valid = jnp.array([1, 1, 0, 1, 1, 0], bool)
    eager_points, eager_variance = predict_motion(models, queries, valid)
    jit_points, jit_variance = jax.jit(predict_motion)(models, queries, valid)
    np.testing.assert_allclose(jit_points, eager_points, rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(jit_variance, eager_variance, rtol=1e-6, atol=1e-6)
    for s in range(6):
        point, variance = predict_one(models, queries[s], valid[s])
        np.testing.assert_allclose(point, eager_points[s], rtol=1e-6, atol=1e-5)
        np.testing.assert_allclose(variance, eager_variance[s], rtol=1e-6, atol=1e-6)
    cells = tracklet_cells(np.asarray(queries[:, -1]), 100.0, np.array([2, 2]))
    assert set(cells.tolist()) >= {0, 3}  # both a fitted and a fallback cell were queried
