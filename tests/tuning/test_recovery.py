"""Tuning by the likelihood (no ground truth) recovers a synthetic scene's clutter rate and pD.

The scene follows the filter's generative model apart from the birth and motion details:
uniform clutter at 2 false detections per frame, every target detected with probability 0.9
(no occlusion penalty). The filter's noise scales are the scene's measurement noise and the
default motion noise (frozen); clutter rate, birth rate and pD start far off (0.5, 0.2, 0.6)
and are tuned with adam on the PHD log-likelihood, averaged over two keys.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.datasets.scene_config import SceneConfig
from jaxtrack.datasets.synthetic import generate_scene
from jaxtrack.filters.phd_defaults import default_phd_params
from jaxtrack.pipelines.tuner import tune
from jaxtrack.tuning import likelihood_objective, parameter_space, tuning_filter

TRUE_CLUTTER_RATE = 2.0
TRUE_DETECTION_PROB = 0.9


@pytest.mark.slow
def test_likelihood_tuning_recovers_clutter_rate_and_detection_prob():
    config = SceneConfig(
        num_frames=150,
        burn_in_frames=100,
        clutter_sources=(),
        uniform_clutter_rate=TRUE_CLUTTER_RATE,
        detection_prob=TRUE_DETECTION_PROB,
        occluded_detection_prob=TRUE_DETECTION_PROB,
    )
    scene = generate_scene(3, config)
    # Birth velocities up to the scene's velocity bound (8 px/frame): 0.4 * 576 / 28.8.
    start = default_phd_params(768.0, 576.0, 28.8, birth_rate=0.2, clutter_rate=0.5)
    start = start._replace(
        detection_prob=jnp.asarray(0.6),
        measurement_noise_std=jnp.array([0.05, 0.04, 0.05, 0.04]),
    )
    result = tune(
        likelihood_objective(tuning_filter(512, births_per_detection=16)),
        start,
        scene.detections,
        jax.random.key(0),
        space=parameter_space(start, ["clutter_rate", "birth_rate", "detection_prob"]),
        num_steps=60,
        num_keys=2,
        patience=0,
    )
    clutter_rate = float(result.params.clutter_intensity.magnitude)
    detection_prob = float(result.params.detection_prob)
    print(
        f"clutter rate {clutter_rate:.3f} (true {TRUE_CLUTTER_RATE}, measured "
        f"{scene.summary()['clutter_per_frame']:.3f}), pD {detection_prob:.3f} (true "
        f"{TRUE_DETECTION_PROB}, measured {scene.summary()['detection_rate']:.3f})"
    )
    assert abs(clutter_rate / TRUE_CLUTTER_RATE - 1) < 0.15
    assert abs(detection_prob / TRUE_DETECTION_PROB - 1) < 0.15
    # The loss went down from the wrong start.
    loss = result.history["loss"]
    print("loss at the start", loss[0], "mean of the last ten steps", np.mean(loss[-10:]))
    assert np.mean(loss[-10:]) < loss[0]
    assert result.filter_runs == 120
