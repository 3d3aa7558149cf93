"""The video scene's configuration: JSON round trip and every rule named in its error."""

from __future__ import annotations

import dataclasses
import json

import pytest

from jaxtrack.datasets import (
    VideoSceneConfig,
    VideoZone,
    load_video_config,
    video_config_from_dict,
    video_config_to_dict,
)
from jaxtrack.errors import FileFormatError, InputError


def test_round_trip_through_json():
    config = VideoSceneConfig(
        name="plaza",
        num_frames=400,
        zones=(VideoZone("a", (0.0, 0.5, 0.05, 0.2)), VideoZone("b", (0.4, 0.9, 0.2, 0.1))),
        noise_std=2.5,
    )
    plain = json.loads(json.dumps(video_config_to_dict(config)))
    assert plain["zones"][1] == {"name": "b", "box": [0.4, 0.9, 0.2, 0.1]}
    assert video_config_from_dict(plain) == config
    assert video_config_from_dict({}) == VideoSceneConfig()


def test_partial_override_keeps_the_rest():
    config = video_config_from_dict({"image_width": 320, "image_height": 240})
    assert config == dataclasses.replace(VideoSceneConfig(), image_width=320, image_height=240)


def test_pixels_and_perspective_law():
    config = VideoSceneConfig()
    assert config.pixels((0.5, 0.25, 0.1, 0.2)) == (320.0, 120.0, 64.0, 96.0)
    # h = a (y_f - r0) H with a = 0.24, r0 = -0.08, H = 480: at the bottom row 124.4 pixels.
    assert config.person_height(1.0) == pytest.approx(0.24 * 1.08 * 480)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"speed": 3}, "unknown field"),
        ({"num_frames": 0}, "num_frames"),
        ({"noise_std": -1}, "noise_std"),
        ({"occluder": [0.9, 0.4, 0.2, 0.2]}, "inside the image"),
        ({"vegetation": [0.1, 0.1, 0.0, 0.2]}, "positive"),
        ({"zones": [{"name": "a", "box": [0, 0.5, 0.1, 0.1]}]}, "between 2 and"),
        (
            {"zones": [{"name": "a", "box": [0, 0.5, 0.1, 0.1]}] * 2},
            "zone names must be distinct",
        ),
        (
            {
                "zones": [
                    {"name": "a", "box": [0, 0, 0.1, 0.1]},
                    {"name": "b", "box": [0, 0.5, 1, 0.1]},
                ]
            },
            "zone 'a' reaches above the ground",
        ),
        ({"zones": [{"name": "a", "box": [0, 0.5, 0.1]}]}, "4 entries"),
        ({"horizon_row": 0.5}, "horizon_row"),
        ({"height_per_row": 0.9}, "lower height_per_row"),
        ({"occluder": [0.5, 0.5, 0.05, 0.05]}, "cannot hide a person"),
        ({"occluder": [0.5, 0.0, 0.2, 0.2]}, "must stand on the ground"),
        ({"name": "a/b"}, "cannot name the video file"),
        ({"name": ".."}, "cannot name the video file"),
        ({"walkers_per_zone": 101}, "walkers_per_zone"),
    ],
)
def test_bad_values_name_the_field(overrides, message):
    with pytest.raises(InputError, match=message):
        video_config_from_dict(overrides)


def test_bad_file_names_the_file(tmp_path):
    path = tmp_path / "video.json"
    path.write_text('{"stand_frames": 1}')
    with pytest.raises(FileFormatError, match=r"video\.json.*stand_frames"):
        load_video_config(path)
    path.write_text("[1, 2]")
    with pytest.raises(FileFormatError, match="expected a JSON object"):
        load_video_config(path)
    path.write_text('{"noise_std": 1.5}')
    assert load_video_config(path) == VideoSceneConfig(noise_std=1.5)
