"""Speed of the scripted video scene (``jaxtrack simulate --video``) at 640x480.

Times, on this machine (wall clock, best of ``--repeats``), for the default scene (seed 3, 500
frames, about 10 people in view, up to 17):

* ``script_seconds``: :func:`jaxtrack.datasets.generate_video_scene` (routes, ground truth,
  visibility, detections);
* ``canvas_seconds``: :func:`jaxtrack.datasets.build_canvas` (the static layers, once);
* ``render_fps``: :func:`jaxtrack.datasets.render_frame` for every frame, nothing else;
* ``render_encode_fps``: rendering and encoding every frame to an mp4 through
  :class:`~jaxtrack.io.video.FrameWriter` (the loop of ``simulate --video``);
* ``write_fps``: the whole :func:`jaxtrack.datasets.write_video_scene` (tables, truth file,
  canvas, render, encode).

Prints one JSON object on its last line. The goal is ``render_encode_fps >= 100`` on 2 CPU
cores; timings on a shared machine vary with the other load on it.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from pathlib import Path

from timing import best_time

from jaxtrack.datasets import (
    VideoSceneConfig,
    build_canvas,
    generate_video_scene,
    render_frame,
    write_video_scene,
)
from jaxtrack.io.video import FrameWriter

GOAL_FPS = 100.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=3, help="timed runs (best kept)")
    args = parser.parse_args()

    config = VideoSceneConfig()
    frames = range(1, config.num_frames + 1)
    script_seconds = best_time(lambda: generate_video_scene(args.seed, config), args.repeats)
    scene = generate_video_scene(args.seed, config)
    canvas_seconds = best_time(lambda: build_canvas(scene), args.repeats)
    canvas = build_canvas(scene)

    def render():
        for frame in frames:
            render_frame(scene, canvas, frame)

    with tempfile.TemporaryDirectory() as folder:
        video = Path(folder) / "bench.mp4"
        size = (config.image_width, config.image_height)

        def render_encode():
            with FrameWriter(video, size, config.frame_rate) as writer:
                for frame in frames:
                    writer.write(render_frame(scene, canvas, frame), frame)

        render_seconds = best_time(render, args.repeats)
        encode_seconds = best_time(render_encode, args.repeats)
        write_seconds = best_time(
            lambda: write_video_scene(scene, Path(folder) / "scene"), args.repeats
        )
    render_encode_fps = config.num_frames / encode_seconds
    print(
        json.dumps(
            {
                "benchmark": "render_speed",
                "image_size": [config.image_width, config.image_height],
                "frames": config.num_frames,
                "seed": args.seed,
                "script_seconds": round(script_seconds, 3),
                "canvas_seconds": round(canvas_seconds, 3),
                "render_fps": round(config.num_frames / render_seconds, 1),
                "render_encode_fps": round(render_encode_fps, 1),
                "write_fps": round(config.num_frames / write_seconds, 1),
                "goal_render_encode_fps": GOAL_FPS,
                "goal_met": render_encode_fps >= GOAL_FPS,
                "cpus": os.cpu_count(),
            }
        )
    )


if __name__ == "__main__":
    main()
