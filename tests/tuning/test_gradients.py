"""Gradients of both objectives against central finite differences (common random numbers).

With a fixed key the objective is a piecewise-smooth function of the parameters: the random
draws are fixed and reparameterised, and the resampled ancestors change only where the
resampling grid crosses a step of the weights' CDF. With the naive estimator ("none", the
ancestors constant) autodiff gives exactly the derivative of that function, so it must agree
with central differences of step ``1e-6`` (in the unconstrained space, float64) wherever no
ancestor changes within the step. Tolerance: relative ``1e-4`` per component, absolute
``1e-6`` times the gradient's largest component.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.datasets.scene_config import SceneConfig
from jaxtrack.datasets.synthetic import generate_scene
from jaxtrack.filters.phd_defaults import default_phd_params
from jaxtrack.filters.phd_tracker import TUNABLE
from jaxtrack.tuning import (
    likelihood_objective,
    parameter_space,
    supervised_objective,
    tuning_filter,
)

SCENE = generate_scene(
    5, SceneConfig(num_frames=10, burn_in_frames=60, birth_rate=0.2, uniform_clutter_rate=1.0)
)
# Every tunable parameter (the properties tree depends only on the params' structure).
SPACE = parameter_space(default_phd_params(640.0, 480.0), TUNABLE)
STEP = 1e-6


def _flat(theta):
    return jnp.concatenate([jnp.ravel(theta[name]) for name in SPACE.trainable])


def _unflat(vector, like):
    out, start = {}, 0
    for name in SPACE.trainable:
        size = like[name].size
        out[name] = vector[start : start + size].reshape(like[name].shape)
        start += size
    return out


def _gradient_and_differences(objective_factory):
    """Autodiff gradient and central differences of an objective in theta (float64)."""
    with jax.enable_x64(True):
        base = default_phd_params(768.0, 576.0, 10.0, birth_rate=0.3, clutter_rate=2.0)
        base = jax.tree.map(lambda x: jnp.asarray(x, jnp.float64), base)
        base = base._replace(detection_prob=jnp.asarray(0.85), survival_prob=jnp.asarray(0.95))
        detections = jax.tree.map(
            lambda x: jnp.asarray(x, jnp.float64) if x.dtype.kind == "f" else jnp.asarray(x),
            SCENE.detections,
        )
        truth = jax.tree.map(
            lambda x: jnp.asarray(x, jnp.float64) if x.dtype.kind == "f" else jnp.asarray(x),
            SCENE.ground_truth,
        )
        objective = objective_factory(tuning_filter(64, births_per_detection=8, estimator="none"))
        theta = SPACE.to_unconstrained(base)
        theta = {name: jnp.asarray(value, jnp.float64) for name, value in theta.items()}
        center = _flat(theta)

        def value(vector):
            params = SPACE.to_params(_unflat(vector, theta), base)
            return objective.loss(params, jax.random.key(7), detections, truth)[0]

        # One compile: value_and_grad at the centre and at the 2 * n shifted points.
        steps = STEP * jnp.eye(center.size)
        points = jnp.concatenate([center[None], center + steps, center - steps])
        values, grads = jax.jit(jax.vmap(jax.value_and_grad(value)))(points)
        n = center.size
        differences = (values[1 : n + 1] - values[n + 1 :]) / (2 * STEP)
        return np.asarray(grads[0]), np.asarray(differences), float(values[0])


@pytest.mark.parametrize(
    "factory", [likelihood_objective, supervised_objective], ids=["likelihood", "supervised"]
)
def test_gradient_matches_central_differences(factory):
    grad, differences, value = _gradient_and_differences(factory)
    assert np.isfinite(value)
    # Every tunable parameter has an effect (the size-noise entries included).
    assert np.all(grad != 0), grad
    np.testing.assert_allclose(grad, differences, rtol=1e-4, atol=1e-6 * np.abs(grad).max())
