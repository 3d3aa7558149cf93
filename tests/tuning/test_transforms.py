"""Parameter spaces: round trips, frozen parameters, domains, the configuration JSON, and one
meaning of ``birth_rate`` for the configuration, the sweep and the tuner."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.commands.arguments import load_config
from jaxtrack.errors import InputError
from jaxtrack.filters.phd_tracker import TUNABLE, UNIFORM_SHARES, PHDConfig, phd_params
from jaxtrack.models.survival import SurvivalMap
from jaxtrack.parameters import LOG, LOGIT
from jaxtrack.pipelines.sweep import batch_params
from jaxtrack.tuning import parameter_space, to_config
from jaxtrack.tuning.transforms import tunable_names
from jaxtrack.types import SequenceInfo

INFO = SequenceInfo("s", 10, 640, 480, 25.0)
PARAMS = phd_params(PHDConfig(birth_rate=0.3, clutter_rate=2.5), INFO)


def test_the_named_parameters_are_the_config_keys_and_the_uniform_shares():
    carried = [name for name in tunable_names(PARAMS) if name in PHDConfig.rules()]
    assert set(carried) == set(TUNABLE)
    assert set(tunable_names(PARAMS)) - set(carried) == set(UNIFORM_SHARES.values())


def test_round_trip_of_every_parameter():
    space = parameter_space(PARAMS, TUNABLE)
    theta = space.to_unconstrained(PARAMS)
    assert set(theta) == set(TUNABLE)
    np.testing.assert_allclose(theta["clutter_rate"], np.log(2.5), rtol=1e-6)
    np.testing.assert_allclose(theta["detection_prob"], np.log(0.8 / 0.2), rtol=1e-6)
    back = space.to_params(theta, PARAMS)
    jax.tree.map(lambda a, b: np.testing.assert_allclose(a, b, rtol=1e-5), back, PARAMS)


def test_birth_rate_means_lambda_s_everywhere():
    """Configuration, sweep and tuner: birth_rate sets the birth intensity's magnitude only;
    the first frame's initial intensity is initial_rate."""
    config = PHDConfig(birth_rate=0.05, initial_rate=0.7)
    from_config = phd_params(config, INFO)
    assert float(from_config.birth_intensity.magnitude) == pytest.approx(0.05)
    assert float(from_config.initial_intensity.magnitude) == pytest.approx(0.7)
    tuned = parameter_space(PARAMS, ["birth_rate"]).to_params({"birth_rate": jnp.log(0.05)}, PARAMS)
    swept = batch_params(PARAMS, {"birth_rate": np.array([0.05], np.float32)})
    for params in (tuned, jax.tree.map(lambda x: x[0], swept)):
        assert float(params.birth_intensity.magnitude) == pytest.approx(0.05)
        assert float(params.initial_intensity.magnitude) == pytest.approx(0.2)


def test_frozen_parameters_keep_their_values():
    space = parameter_space(
        PARAMS, ["clutter_rate", "birth_rate", "detection_prob"], ["birth_rate"]
    )
    assert set(space.trainable) == {"clutter_rate", "detection_prob"}
    theta = {"clutter_rate": jnp.log(4.0), "detection_prob": jnp.asarray(0.0)}
    params = space.to_params(theta, PARAMS)
    assert float(params.clutter_intensity.magnitude) == pytest.approx(4.0)
    assert float(params.detection_prob) == pytest.approx(0.5)
    assert float(params.birth_intensity.magnitude) == pytest.approx(0.3)


def test_transforms_are_inverse_and_probability_one_stays_finite():
    values = jnp.array([1e-3, 0.5, 0.999])
    for transform in (LOG, LOGIT):
        np.testing.assert_allclose(transform.forward(transform.inverse(values)), values, rtol=1e-5)
    assert np.isfinite(LOGIT.inverse(jnp.asarray(1.0)))
    assert float(jax.grad(LOGIT.forward)(0.0)) == pytest.approx(0.25)


def test_bad_input_raises_clear_errors():
    with pytest.raises(InputError, match=r"unknown tunable parameter.*clutter"):
        parameter_space(PARAMS, ["clutter"])
    with pytest.raises(InputError, match="no parameter left"):
        parameter_space(PARAMS, ["birth_rate"], frozen=["birth_rate"])
    space = parameter_space(PARAMS, ["clutter_rate", "survival_prob"])
    zero = PARAMS.clutter_intensity._replace(magnitude=jnp.asarray(0.0))
    with pytest.raises(InputError, match="clutter_rate must be > 0"):
        space.to_unconstrained(PARAMS._replace(clutter_intensity=zero))
    survival_map = SurvivalMap(*(jnp.zeros(()) for _ in SurvivalMap._fields))
    with pytest.raises(InputError, match=r"unknown tunable parameter.*survival_prob"):
        parameter_space(PARAMS._replace(survival_prob=survival_map), ["survival_prob"])


def test_config_json_is_accepted_by_track_and_rebuilds_the_tuned_parameters(tmp_path):
    space = parameter_space(PARAMS)
    tuned = space.to_params(
        {"clutter_rate": jnp.log(3.25), "birth_rate": jnp.log(0.04), "detection_prob": 0.0},
        PARAMS,
    )
    config = to_config(tuned, PHDConfig(num_particles=512))
    assert config.overrides() == {
        "num_particles": 512,
        "clutter_rate": 3.25,
        "birth_rate": 0.04,
        "detection_prob": 0.5,
    }
    path = tmp_path / "tuned.json"
    path.write_text(json.dumps(config.overrides()))
    loaded = load_config(str(path))
    assert loaded == config
    rebuilt = phd_params(loaded, INFO)
    assert float(rebuilt.clutter_intensity.magnitude) == pytest.approx(3.25)
    assert float(rebuilt.birth_intensity.magnitude) == pytest.approx(0.04)
    assert float(rebuilt.initial_intensity.magnitude) == pytest.approx(0.2)
    assert float(rebuilt.detection_prob) == pytest.approx(0.5)
    np.testing.assert_allclose(rebuilt.motion_noise_std, PARAMS.motion_noise_std, rtol=1e-5)
