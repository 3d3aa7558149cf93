"""A scripted video scene written as a MOTChallenge folder with its video and truth.

Files (:func:`write_video_scene`):

* ``seqinfo.ini``: name, frame rate, length, image size;
* ``<name>.mp4``: the frames (:mod:`jaxtrack.datasets.render`), MPEG-4 part 2 (``mp4v``,
  lossy) through :class:`~jaxtrack.io.video.FrameWriter`; ``jaxtrack`` finds it as the
  sequence's frames (:func:`~jaxtrack.io.video.find_frame_source`);
* ``gt/gt.txt``: ground truth in the MOT16/17 layout ``frame, id, x, y, w, h, 1, 1,
  visibility``;
* ``det/det.txt``: detections ``frame, -1, x, y, w, h, score, -1, -1, -1``;
* ``video_truth.json`` (:data:`TRUTH_FILE`): the seed and configuration, the entry/exit zones
  (``{"name", "x", "y", "w", "h"}`` pixel boxes, top-left corner, as ``zones.json``), the
  occluder and vegetation boxes, each person's true appearance (``top``, ``bottom``, ``skin``
  RGB, ``height_scale``), role, zones and frames, the scripted events (``type``, ``ids``,
  ``frames``, ``zone``) and the gust spans of the vegetation.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from tqdm import tqdm

from jaxtrack.datasets.render import render_frames
from jaxtrack.datasets.video_config import video_config_to_dict
from jaxtrack.datasets.video_scene import VideoScene
from jaxtrack.io.motchallenge import write_mot_file, write_seqinfo
from jaxtrack.io.video import FrameWriter

#: Name of the truth file in the sequence folder.
TRUTH_FILE = "video_truth.json"


def video_file_name(scene: VideoScene) -> str:
    """``<name>.mp4``: the video's file name in the sequence folder."""
    return f"{scene.info.name}.mp4"


def write_video_scene(scene: VideoScene, out_dir: str | Path, progress: bool = False) -> Path:
    """Writes a scene's MOTChallenge folder, video and truth (see the module docstring).

    Args:
        scene: the scene.
        out_dir: the sequence folder (created if needed; these files are overwritten).
        progress: show a progress bar while the frames are rendered and encoded.

    Returns:
        The folder.

    Raises:
        FileFormatError: OpenCV cannot write the video file.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_seqinfo(out / "seqinfo.ini", scene.info)
    write_mot_file(out / "gt" / "gt.txt", scene.gt_table)
    write_mot_file(out / "det" / "det.txt", scene.det_table)
    (out / TRUTH_FILE).write_text(json.dumps(video_truth(scene), indent=1) + "\n")
    config = scene.config
    size = (config.image_width, config.image_height)
    frames = tqdm(
        render_frames(scene),
        total=config.num_frames,
        desc="render + encode",
        unit="frame",
        disable=not progress,
    )
    with FrameWriter(out / video_file_name(scene), size, config.frame_rate) as writer:
        for number, image in enumerate(frames, start=1):
            writer.write(image, number)
    return out


def video_truth(scene: VideoScene) -> dict:
    """The content of ``video_truth.json`` (plain JSON values; see the module docstring)."""
    config = scene.config
    gt = scene.gt_table
    names = [zone.name for zone in config.zones]
    look = scene.appearance
    people = []
    for index, role in enumerate(scene.roles):
        frames = gt.frames[gt.ids == index + 1]
        exit_zone = int(scene.exit_zones[index])
        people.append(
            {
                "id": index + 1,
                "role": role,
                "top": look.top[index].tolist(),
                "bottom": look.bottom[index].tolist(),
                "skin": look.skin[index].tolist(),
                "height_scale": float(look.height_scale[index]),
                "entry_zone": names[scene.entry_zones[index]],
                "exit_zone": names[exit_zone] if exit_zone >= 0 else None,
                "first_frame": int(frames[0]),
                "last_frame": int(frames[-1]),
            }
        )
    return {
        "source": "jaxtrack simulate --video (scripted scene truth)",
        "seed": int(scene.seed),
        "video": video_file_name(scene),
        "image_size": [config.image_width, config.image_height],
        "zones": [_box(box, name) for box, name in zip(scene.zones, names, strict=True)],
        "occluder": _box(scene.occluder),
        "vegetation": _box(scene.vegetation),
        "gusts": _spans(scene.gust),
        "people": people,
        "events": [
            {
                "type": event.kind,
                "ids": list(event.ids),
                "frames": list(event.frames),
                "zone": event.zone,
            }
            for event in scene.events
        ],
        "config": video_config_to_dict(config),
    }


def _box(box: np.ndarray, name: str | None = None) -> dict:
    named = {} if name is None else {"name": name}
    return named | {key: float(value) for key, value in zip("xywh", box, strict=True)}


def _spans(flags: np.ndarray) -> list[list[int]]:
    """``[first, last]`` 1-based frame spans in which ``flags`` holds."""
    edges = np.diff(np.concatenate([[0], flags.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1) + 1, np.flatnonzero(edges == -1)
    return [[int(a), int(b)] for a, b in zip(starts, ends, strict=True)]
