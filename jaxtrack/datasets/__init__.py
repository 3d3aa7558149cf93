"""Datasets: seeded synthetic surveillance scenes with known birth and clutter context.

The default scene (:mod:`jaxtrack.datasets.synthetic`) and a bank of scene families that
differ from it as real scenes do (:mod:`jaxtrack.datasets.scene_bank`).
"""

from jaxtrack.datasets.context_truth import load_context_truth
from jaxtrack.datasets.scene_bank import FAMILIES, generate_family_scene, write_family_scene
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
    "FAMILIES",
    "ClutterSource",
    "EntryZone",
    "SceneConfig",
    "SyntheticScene",
    "birth_intensity",
    "clutter_intensity",
    "config_from_dict",
    "config_to_dict",
    "generate_family_scene",
    "generate_scene",
    "load_context_truth",
    "write_family_scene",
    "write_scene",
]
