"""Scenes shared by the dataset tests (generated once per session: about 3 s in all)."""

from __future__ import annotations

import dataclasses

import pytest

from jaxtrack.datasets import SceneConfig, generate_scene

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
