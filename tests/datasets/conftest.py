"""Scenes shared by the dataset tests (generated once per session: about 4 s in all)."""

from __future__ import annotations

import dataclasses

import pytest

from jaxtrack.datasets import SceneConfig, VideoSceneConfig, generate_scene, generate_video_scene

#: Frames of the long scene used for rate statistics (tolerances below scale as 1/sqrt).
LONG_FRAMES = 4000


@pytest.fixture(scope="session")
def default_scene():
    """The default 800-frame scene, seed 0."""
    return generate_scene(0)


@pytest.fixture(scope="session")
def long_scene():
    """The default scene model run for 4000 frames, seed 1, for tight rate statistics."""
    return generate_scene(1, dataclasses.replace(SceneConfig(), num_frames=LONG_FRAMES))


@pytest.fixture(scope="session")
def video_scene():
    """The default scripted video scene (640x480, 500 frames), seed 3."""
    return generate_video_scene(3)


@pytest.fixture(scope="session")
def small_video_scene():
    """The same scene drawn at 320x240 (the layout is in image fractions)."""
    return generate_video_scene(3, VideoSceneConfig(image_width=320, image_height=240))
