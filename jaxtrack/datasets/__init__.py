"""Datasets: seeded synthetic surveillance scenes with known truth.

The default detection-level scene with known birth and clutter context
(:mod:`jaxtrack.datasets.synthetic`), a bank of scene families that differ from it as real
scenes do (:mod:`jaxtrack.datasets.scene_bank`), and a scripted surveillance video with known
appearance, zones and events (:mod:`jaxtrack.datasets.video_scene`, drawn by
:mod:`jaxtrack.datasets.render`, written by :mod:`jaxtrack.datasets.video_files`).
"""

from jaxtrack.datasets.context_truth import load_context_truth
from jaxtrack.datasets.render import build_canvas, render_frame, render_frames, render_labels
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
from jaxtrack.datasets.video_config import (
    VideoSceneConfig,
    VideoZone,
    load_video_config,
    video_config_from_dict,
    video_config_to_dict,
)
from jaxtrack.datasets.video_files import write_video_scene
from jaxtrack.datasets.video_scene import (
    Appearance,
    ScriptedEvent,
    VideoScene,
    generate_video_scene,
)

__all__ = [
    "FAMILIES",
    "Appearance",
    "ClutterSource",
    "EntryZone",
    "SceneConfig",
    "ScriptedEvent",
    "SyntheticScene",
    "VideoScene",
    "VideoSceneConfig",
    "VideoZone",
    "birth_intensity",
    "build_canvas",
    "clutter_intensity",
    "config_from_dict",
    "config_to_dict",
    "generate_family_scene",
    "generate_scene",
    "generate_video_scene",
    "load_context_truth",
    "load_video_config",
    "render_frame",
    "render_frames",
    "render_labels",
    "video_config_from_dict",
    "video_config_to_dict",
    "write_family_scene",
    "write_scene",
    "write_video_scene",
]
