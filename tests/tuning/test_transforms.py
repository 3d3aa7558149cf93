"""Parameter transforms: round trips, frozen parameters, domains, the configuration JSON."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.commands.track import load_config
from jaxtrack.errors import InputError
from jaxtrack.filters.phd_defaults import default_phd_params
from jaxtrack.filters.phd_tracker import tracker_params
from jaxtrack.io import SequenceInfo
from jaxtrack.models.survival import SurvivalMap
from jaxtrack.tuning import PARAMETERS, parameter_space, to_config
from jaxtrack.tuning.transforms import forward, inverse

PARAMS = default_phd_params(640.0, 480.0, 25.0, birth_rate=0.3, clutter_rate=2.5)


def test_round_trip_of_every_parameter():
    space = parameter_space(PARAMETERS)
    theta = space.to_unconstrained(PARAMS)
    assert set(theta) == set(PARAMETERS)
    np.testing.assert_allclose(theta["clutter_rate"], np.log(2.5), rtol=1e-6)
    np.testing.assert_allclose(theta["detection_prob"], np.log(0.8 / 0.2), rtol=1e-6)
    back = space.to_params(theta, PARAMS)
    jax.tree.map(lambda a, b: np.testing.assert_allclose(a, b, rtol=1e-5), back, PARAMS)


def test_frozen_parameters_keep_their_values_and_birth_rate_sets_both_intensities():
    space = parameter_space(["clutter_rate", "birth_rate", "detection_prob"], frozen=["birth_rate"])
    assert space.trainable == ("clutter_rate", "detection_prob")
    theta = {"clutter_rate": jnp.log(4.0), "detection_prob": jnp.asarray(0.0)}
    params = space.to_params(theta, PARAMS)
    assert float(params.clutter_intensity.magnitude) == pytest.approx(4.0)
    assert float(params.detection_prob) == pytest.approx(0.5)
    assert float(params.birth_intensity.magnitude) == pytest.approx(0.3)
    both = parameter_space(["birth_rate"]).to_params({"birth_rate": jnp.log(0.05)}, PARAMS)
    assert float(both.birth_intensity.magnitude) == pytest.approx(0.05)
    assert float(both.initial_intensity.magnitude) == pytest.approx(0.05)


def test_transforms_are_inverse_and_probability_one_stays_finite():
    values = jnp.array([1e-3, 0.5, 0.999])
    for kind in ("log", "logit"):
        np.testing.assert_allclose(forward(kind, inverse(kind, values)), values, rtol=1e-5)
    assert np.isfinite(inverse("logit", 1.0))
    grad = jax.grad(lambda t: forward("logit", t))(0.0)
    assert float(grad) == pytest.approx(0.25)


def test_bad_input_raises_clear_errors():
    with pytest.raises(InputError, match=r"unknown tunable parameter.*clutter"):
        parameter_space(["clutter"])
    with pytest.raises(InputError, match="no parameter left"):
        parameter_space(["birth_rate"], frozen=["birth_rate"])
    space = parameter_space(["clutter_rate", "survival_prob"])
    with pytest.raises(InputError, match="clutter_rate must be positive"):
        space.to_unconstrained(
            PARAMS._replace(
                clutter_intensity=PARAMS.clutter_intensity._replace(magnitude=jnp.asarray(0.0))
            )
        )
    survival_map = SurvivalMap(*(jnp.zeros(()) for _ in SurvivalMap._fields))
    with pytest.raises(InputError, match="survival_prob is not a plain array"):
        space.to_unconstrained(PARAMS._replace(survival_prob=survival_map))


def test_config_json_is_accepted_by_track_and_rebuilds_the_tuned_magnitudes(tmp_path):
    tuned = parameter_space().to_params(
        {"clutter_rate": jnp.log(3.25), "birth_rate": jnp.log(0.04), "detection_prob": 0.0},
        PARAMS,
    )
    config = to_config(tuned, {"num_particles": 512})
    assert config == {
        "num_particles": 512,
        "clutter_rate": 3.25,
        "birth_rate": 0.04,
        "detection_prob": 0.5,
        "survival_prob": pytest.approx(float(PARAMS.survival_prob)),
        "motion_noise_std": pytest.approx(np.asarray(PARAMS.motion_noise_std).tolist()),
        "measurement_noise_std": pytest.approx(np.asarray(PARAMS.measurement_noise_std).tolist()),
    }
    path = tmp_path / "tuned.json"
    path.write_text(json.dumps(config))
    loaded = load_config(str(path))
    rebuilt = tracker_params(SequenceInfo("s", 10, 640, 480, 25.0), loaded)
    assert float(rebuilt.clutter_intensity.magnitude) == pytest.approx(3.25)
    assert float(rebuilt.birth_intensity.magnitude) == pytest.approx(0.04)
    assert float(rebuilt.initial_intensity.magnitude) == pytest.approx(0.04)
    assert float(rebuilt.detection_prob) == pytest.approx(0.5)
    np.testing.assert_allclose(rebuilt.motion_noise_std, PARAMS.motion_noise_std, rtol=1e-5)
