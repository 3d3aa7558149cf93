"""Scene configuration: validation and JSON round trips."""

from __future__ import annotations

import dataclasses
import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxtrack.datasets import (
    ClutterSource,
    EntryZone,
    SceneConfig,
    config_from_dict,
    config_to_dict,
)
from jaxtrack.datasets.scene_config import load_scene_config
from jaxtrack.errors import FileFormatError, InputError


def test_default_config_round_trips_through_json():
    config = SceneConfig()
    plain = json.loads(json.dumps(config_to_dict(config)))
    assert config_from_dict(plain) == config
    assert config.total_clutter_rate == pytest.approx(1.9)


def test_partial_overrides_keep_other_fields():
    config = config_from_dict(
        {
            "num_frames": 50,
            "detection_prob": 0.8,
            "clutter_sources": [
                {
                    "name": "flag",
                    "centre": [10, 20],
                    "position_std": [1, 1],
                    "size": [5, 9],
                    "size_std": [1, 1],
                    "rate": 0.3,
                }
            ],
        }
    )
    assert config.num_frames == 50 and config.detection_prob == 0.8
    assert config.clutter_sources == (
        ClutterSource("flag", (10.0, 20.0), (1.0, 1.0), (5.0, 9.0), (1.0, 1.0), 0.3),
    )
    assert config.zones == SceneConfig().zones
    assert config.image_width == 768


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"frames": 10}, "unknown field"),
        ({"num_frames": 0}, "num_frames"),
        ({"num_frames": 2.5}, "integer"),
        ({"num_frames": True}, "integer"),
        ({"detection_prob": 1.5}, "detection_prob"),
        ({"birth_rate": -1}, "birth_rate"),
        ({"motion_noise": [0.1]}, "2 entries"),
        ({"measurement_noise": "big"}, "list"),
        ({"min_box_size": [100, 100]}, "max_box_size"),
        ({"zones": []}, "entry zone"),
        ({"zones": [{"name": "z", "centre": [1, 2]}]}, "zones"),
        ({"zones": [{"name": "z", "centre": [900, 2], "position_std": [1, 1],
                     "velocity": [0, 0], "velocity_std": [1, 1]}]}, "outside the image"),
        ({"clutter_sources": [{"name": "c", "centre": [1, 2], "position_std": [1, -1],
                               "size": [1, 1], "size_std": [1, 1], "rate": 1}]}, "position_std"),
        ({"size_correlation": 1.0}, "size_correlation"),
        ({"name": 3}, "string"),
    ],
)  # fmt: skip
def test_invalid_values_raise_input_error(overrides, message):
    with pytest.raises(InputError, match=message):
        config_from_dict(overrides)


def test_zone_names_must_be_distinct():
    zone = EntryZone("a", (100.0, 300.0), (1.0, 1.0), (0.0, 0.0), (1.0, 1.0))
    with pytest.raises(InputError, match="distinct"):
        dataclasses.replace(SceneConfig(), zones=(zone, zone))


def test_zone_above_the_horizon_is_rejected():
    zone = EntryZone("sky", (100.0, 10.0), (1.0, 1.0), (0.0, 0.0), (1.0, 1.0))
    with pytest.raises(InputError, match="horizon"):
        dataclasses.replace(SceneConfig(), zones=(zone,), horizon_row=50.0)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"birth_rate": 1000}, r"birth_rate must lie in \[0, 10\], got 1000"),
        ({"uniform_clutter_rate": 1e6}, r"uniform_clutter_rate must lie in \[0, 100\]"),
        ({"num_frames": 100_000_000}, r"num_frames must lie in \[1, 1000000\]"),
        ({"num_frames": 10**400}, "num_frames must lie in"),
        ({"image_width": 10**8}, r"image_width must lie in \[16, 65536\]"),
        ({"frame_rate": 1e300}, r"frame_rate must lie in \[1, 1000\]"),
        ({"frame_rate": 10**400}, "frame_rate must be finite"),
        ({"horizon_row": -1e300}, "horizon_row must lie in"),
        ({"height_per_row": 1e-300}, "not representable in float32"),
        ({"max_box_size": [64, 1e30]}, r"max_box_size\[1\] must lie in"),
        ({"max_box_size": [64, 6000]}, "max_box_size .* exceeds 10 times the 768x576 image"),
        ({"min_box_size": [0.5, 16]}, r"min_box_size\[0\] must lie in \[1, 1048576\]"),
        ({"height_per_row": 50.0}, "perspective law gives .* boxes at the image bottom"),
        ({"size_correlation": 0.999999}, r"size_correlation must lie in \[-0\.99, 0\.99\]"),
        ({"size_spread": 1e9}, "size_spread must lie in"),
        ({"motion_noise": [0.1, 1e9]}, r"motion_noise\[1\] must lie in \[0, 1\]"),
        ({"target_score": [1e-300, 1]}, r"target_score\[0\] must lie in \[0\.01, 1000\]"),
        ({"velocity_bound": 1e300}, "velocity_bound must lie in"),
        ({"burn_in_frames": 10**7}, "burn_in_frames must lie in"),
        ({"zones": [{"name": "z", "centre": [100, 300], "position_std": [1e-9, 1],
                     "velocity": [0, 0], "velocity_std": [1, 1]}]},
         r"zone 'z' position_std\[0\] must lie in \[0\.001, 1048576\]"),
        ({"zones": [{"name": "z", "centre": [100, 300], "position_std": [1, 1],
                     "velocity": [1e300, 0], "velocity_std": [1, 1]}]}, r"zone 'z' velocity\[0\]"),
        ({"zones": [{"name": "z", "centre": [100, 300], "position_std": [1, 1],
                     "velocity": [0, 0], "velocity_std": [1, 1], "weight": 1e300}]},
         "zone 'z' weight must lie in"),
        ({"clutter_sources": [{"name": "c", "centre": [1, 2], "position_std": [1, 1],
                               "size": [1, 1], "size_std": [1, 1], "rate": 1000}]},
         r"clutter source 'c' rate must lie in \[0, 100\]"),
        ({"clutter_sources": [{"name": f"c{i}", "centre": [1, 2], "position_std": [1, 1],
                               "size": [1, 1], "size_std": [1, 1], "rate": 1} for i in range(2)],
          "uniform_clutter_rate": 99}, "is 101 false detections per frame; at most 100"),
    ],
)  # fmt: skip
def test_scene_values_are_bounded(overrides, message):
    with pytest.raises(InputError, match=message):
        config_from_dict(overrides)


def test_scene_config_file_errors_name_the_file(tmp_path):
    path = tmp_path / "scene.json"
    for text, message in (
        ('{"birth_rate": NaN}', "NaN is not a number a scene configuration accepts"),
        ('{"frame_rate": Infinity}', "Infinity is not a number"),
        ("[" * 100_000, "nested too deeply"),
        ('{\n"birth_rate": }', r"scene\.json, line 2: not valid JSON"),
        ("[1]", "expected a JSON object"),
        ('{"birth_rate": 1000}', r"scene\.json: birth_rate must lie in \[0, 10\]"),
    ):
        path.write_text(text)
        with pytest.raises(FileFormatError, match=message) as info:
            load_scene_config(path)
        assert info.value.path == str(path)
    path.write_text('{"num_frames": 7, "birth_rate": 2}')
    assert load_scene_config(path) == SceneConfig(num_frames=7, birth_rate=2.0)


scene_value = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**20), 10**20),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([1e-46, 1e-300, 1e39, 10**400, 0, 0.5, 1, 2, 100, 1000]),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=3),
    st.text(max_size=3),
)


@settings(max_examples=200, deadline=None)
@given(
    st.dictionaries(
        st.sampled_from([field.name for field in dataclasses.fields(SceneConfig)]), scene_value
    )
)
def test_any_scene_values_load_or_raise_input_error(values):
    try:
        config = config_from_dict(values)
    except InputError:
        return
    # loaded: every rule holds (round trip validates again)
    assert config_from_dict(json.loads(json.dumps(config_to_dict(config)))) == config
    assert config.total_clutter_rate <= 100 and config.birth_rate <= 10
