"""Datasets: seeded synthetic surveillance scenes with known birth and clutter context."""

from jaxtrack.datasets.context_truth import load_context_truth
from jaxtrack.datasets.scene_config import (
    ClutterSource,
    EntryZone,
    SceneConfig,
    config_from_dict,
    config_to_dict,
)
from jaxtrack.datasets.synthetic import (
    SyntheticScene,
    birth_intensity,
    clutter_intensity,
    generate_scene,
    write_scene,
)

__all__ = [
    "ClutterSource",
    "EntryZone",
    "SceneConfig",
    "SyntheticScene",
    "birth_intensity",
    "clutter_intensity",
    "config_from_dict",
    "config_to_dict",
    "generate_scene",
    "load_context_truth",
    "write_scene",
]
