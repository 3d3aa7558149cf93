"""Typed tracker configurations: validation naming the key, JSON round trip, hashing, registry."""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxtrack.configs import load_config_file
from jaxtrack.errors import FileFormatError, InputError
from jaxtrack.filters.kalman_tracker import KalmanConfig
from jaxtrack.filters.phd_tracker import PHDConfig
from jaxtrack.filters.registry import TRACKERS, build_tracker, tracker_entry
from jaxtrack.types import SequenceInfo

INFO = SequenceInfo("s", 10, 640, 480, 25.0)


@pytest.mark.parametrize(
    ("values", "message"),
    [
        ({"birth_rate": math.nan}, "birth_rate must be finite"),
        ({"birth_rate": 0}, r"birth_rate must lie in \(0, 10000\]"),
        ({"clutter_rate": 1e300}, r"clutter_rate must lie in"),
        ({"num_particles": 1.5}, "num_particles must be an integer"),
        ({"num_particles": True}, "num_particles must be an integer"),
        ({"num_particles": 100_000_000}, "num_particles must lie in"),
        ({"extraction": "kmeans"}, "extraction must be one of partition, gmm"),
        ({"detection_prob": 0.0}, r"detection_prob must lie in \(0, 1\]"),
        ({"motion_noise_std": [0.1, 0.1]}, "motion_noise_std must be a list of 4 numbers"),
        ({"measurement_noise_std": [0.1, 0.1, 0.1, 1e30]}, r"measurement_noise_std\[3\]"),
        ({"max_gap": -1}, "max_gap must lie in"),
        ({"particles": 10}, "unknown phd configuration key.*'particles'"),
    ],
)
def test_bad_values_name_the_key(values, message):
    with pytest.raises(InputError, match=message):
        PHDConfig.from_dict(values)


def test_json_round_trip_and_hash():
    config = PHDConfig(num_particles=512, motion_noise_std=[0.1, 0.2, 0.3, 0.4])
    again = PHDConfig.from_dict(json.loads(json.dumps(config.to_dict())))
    assert again == config and hash(again) == hash(config)
    assert again.motion_noise_std == (0.1, 0.2, 0.3, 0.4)
    assert config.overrides() == {"num_particles": 512, "motion_noise_std": [0.1, 0.2, 0.3, 0.4]}
    assert config.replace(birth_rate=1).birth_rate == 1.0
    with pytest.raises(InputError, match="birth_rate"):
        config.replace(birth_rate=-1)


def test_config_files_name_file_and_problem(tmp_path):
    path = tmp_path / "c.json"
    path.write_text('{"birth_rate": NaN}')
    with pytest.raises(FileFormatError, match=r"c\.json.*NaN is not a number"):
        load_config_file(path, PHDConfig)
    path.write_text('{\n"birth_rate": }')
    with pytest.raises(FileFormatError, match=r"c\.json, line 2: not valid JSON"):
        load_config_file(path, PHDConfig)
    path.write_bytes(b'{"birth_rate": "\xff"}')
    with pytest.raises(FileFormatError, match="not a UTF-8 text file"):
        load_config_file(path, PHDConfig)
    path.write_text("[1, 2]")
    with pytest.raises(FileFormatError, match="must be a JSON object"):
        load_config_file(path, PHDConfig)
    path.write_text('{"preset": "sort", "max_gap": 3}')
    assert load_config_file(path, KalmanConfig) == KalmanConfig(preset="sort", max_gap=3)


@settings(max_examples=60, deadline=None)
@given(
    st.dictionaries(
        st.sampled_from([*sorted(PHDConfig.rules()), "bogus"]),
        st.one_of(
            st.floats(allow_nan=True, allow_infinity=True),
            st.integers(-(10**12), 10**12),
            st.booleans(),
            st.text(max_size=5),
            st.lists(st.floats(), max_size=5),
            st.none(),
        ),
    )
)
def test_any_json_object_loads_or_raises_input_error(values):
    try:
        config = PHDConfig.from_dict(values)
    except InputError:
        return
    assert PHDConfig.from_dict(config.to_dict()) == config


def test_registry_builds_every_tracker_and_shares_filters():
    for name, entry in TRACKERS.items():
        assert tracker_entry(name) is entry
        filt, params = build_tracker(entry.config_type(), INFO)
        assert isinstance(params, entry.params_type)
        again, _ = build_tracker(entry.config_type(), INFO)
        assert again is filt  # cached on the setting: one compile per setting
    phd, _ = build_tracker(PHDConfig(birth_rate=3.0), INFO)
    assert phd is build_tracker(PHDConfig(), INFO)[0]  # magnitudes are params, not statics
    assert phd is not build_tracker(PHDConfig(num_particles=64), INFO)[0]
    with pytest.raises(InputError, match="unknown tracker 'nosuch'"):
        tracker_entry("nosuch")
    with pytest.raises(InputError, match="takes no context"):
        build_tracker(KalmanConfig(), INFO, context=object())


@pytest.mark.parametrize(
    ("values", "message"),
    [
        ({"clutter_rate": 1e-50}, "clutter_rate = 1e-50 is not representable in float32"),
        ({"detection_prob": 1e-300}, "detection_prob = 1e-300 is not representable"),
        ({"motion_noise_std": [1e-45, 0.1, 0.1, 0.1]}, r"motion_noise_std\[0\] = 1e-45"),
        ({"clutter_rate": 10**400}, r"clutter_rate must be finite, got 10000000000"),
        ({"num_particles": 10**400}, r"num_particles must lie in \[1, 1048576\], got 1000"),
        ({"max_gap": -(10**400)}, "max_gap must lie in"),
    ],
)
def test_float32_and_huge_integers_are_input_errors(values, message):
    with pytest.raises(InputError, match=message):
        PHDConfig.from_dict(values)


def test_config_file_nesting_and_huge_numbers(tmp_path):
    path = tmp_path / "c.json"
    path.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(FileFormatError, match=r"c\.json: JSON nested too deeply"):
        load_config_file(path, PHDConfig)
    path.write_text('{"num_particles": ' + "9" * 5000 + "}")
    with pytest.raises(FileFormatError, match=r"c\.json"):
        load_config_file(path, PHDConfig)
    path.write_text('{"birth_rate": 1e400}')  # JSON reads it as inf
    with pytest.raises(FileFormatError, match="birth_rate must be finite"):
        load_config_file(path, PHDConfig)
    path.write_text('{"survival_prob": -Infinity}')
    with pytest.raises(FileFormatError, match="-Infinity is not a number"):
        load_config_file(path, PHDConfig)


json_value = st.recursive(
    st.one_of(
        st.none(),
        st.booleans(),
        st.integers(-(10**30), 10**30),
        st.floats(allow_nan=True, allow_infinity=True),
        st.sampled_from([1e-46, 1e-39, 3.5e38, 1e39, 10**400, 2**31, 0.0, 1.0]),
        st.text(max_size=4),
    ),
    lambda children: (
        st.lists(children, max_size=5) | st.dictionaries(st.text(max_size=3), children, max_size=3)
    ),
    max_leaves=8,
)


@settings(max_examples=150, deadline=None)
@given(
    values=st.dictionaries(
        st.sampled_from([*sorted(PHDConfig.rules()), *sorted(KalmanConfig.rules())]), json_value
    ),
    tracker=st.sampled_from(sorted(TRACKERS)),
)
def test_any_json_config_file_loads_or_raises_file_format_error(tmp_path_factory, values, tracker):
    """Written as JSON (NaN and Infinity included), read back: a config or FileFormatError."""
    path = tmp_path_factory.mktemp("config") / "c.json"
    path.write_text(json.dumps(values))
    config_type = tracker_entry(tracker).config_type
    try:
        config = load_config_file(path, config_type)
    except FileFormatError as err:
        assert err.path == str(path)
        return
    for key, value in config.to_dict().items():
        if isinstance(value, float):
            assert math.isfinite(value) and (value == 0 or abs(value) >= 1.2e-38), key
    assert config_type.from_dict(config.to_dict()) == config
