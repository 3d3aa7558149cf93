"""Scene configuration: validation and JSON round trips."""

from __future__ import annotations

import dataclasses
import json

import pytest

from jaxtrack.datasets import (
    ClutterSource,
    EntryZone,
    SceneConfig,
    config_from_dict,
    config_to_dict,
)
from jaxtrack.errors import InputError


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
