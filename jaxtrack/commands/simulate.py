"""``jaxtrack simulate``: write a seeded synthetic surveillance sequence with its true context."""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import numpy as np

from jaxtrack.commands.arguments import add_out, add_quiet, add_seed, ranged, refuse_ignored
from jaxtrack.commands.paths import SCENE_FILES, check_outputs, file_input, output_folder
from jaxtrack.datasets.scene_bank import FAMILIES, family_config, generate_family_scene
from jaxtrack.datasets.scene_config import SceneConfig, config_to_dict, load_scene_config
from jaxtrack.datasets.synthetic import generate_scene, write_scene
from jaxtrack.datasets.video_config import (
    VideoSceneConfig,
    check_video_name,
    load_video_config,
    video_config_to_dict,
)
from jaxtrack.datasets.video_files import TRUTH_FILE, video_file_name, write_video_scene
from jaxtrack.datasets.video_scene import generate_video_scene
from jaxtrack.errors import InputError
from jaxtrack.limits import FRAME_COUNT, FRAME_NUMBER
from jaxtrack.plot.scene import save_scene_preview

DESCRIPTION = """\
Generate a synthetic surveillance sequence with known scene context (targets entering through
a few entry/exit zones, SDV constant-velocity motion with perspective sizes, missed detections
that are likelier under occlusion, spatially persistent clutter sources plus weak uniform
clutter) and write it as a MOTChallenge folder:

  DIR/seqinfo.ini         sequence information (768x576 by default)
  DIR/det/det.txt         detections (true and clutter, shuffled within each frame)
  DIR/gt/gt.txt           ground truth (ids from 1)
  DIR/context_truth.npz   true birth and clutter intensities + zone/source metadata
                          (read with jaxtrack.datasets.load_context_truth)
  DIR/preview.png         one frame with boxes, clutter sources and entry zones

The same seed and configuration always give the same sequence. --family NAME starts from a
scene family of the test bank instead of the default scene (jaxtrack.datasets.scene_bank:
street, plaza-edges, sparse-door, layout-change, flicker, uniform, misplaced; 600 frames
each), its layout drawn from --seed.

--video renders a scripted surveillance video instead (jaxtrack.datasets.video_scene; 640x480,
25 fps, 500 frames by default): two-tone walking figures with perspective sizes entering and
leaving through four zones (west and east edges, south edge, a door), a textured background
with an illumination gradient and a sunlit patch, a billboard that hides people behind it,
foliage that sways in gusts (background-subtraction clutter) and pixel noise. Scripted by
--seed: a crossing of two similarly dressed people, a group of three walking together then
splitting, a person passing behind the billboard, a person standing still. It writes:

  DIR/seqinfo.ini         sequence information
  DIR/NAME.mp4            the frames (mp4v, lossy)
  DIR/gt/gt.txt           ground truth, MOT16/17 layout: ...,1,1,visibility (the visible
                          fraction of the box after the billboard, nearer people, image edge)
  DIR/det/det.txt         detections drawn from the ground truth (missed when occluded) and
                          false detections (uniform, and in the foliage during gusts)
  DIR/video_truth.json    zones (pixel boxes), billboard and foliage boxes, each person's
                          true colours, height, role and zones, the scripted events

With --video, --scene-config takes the video scene's fields (see --video --print-config; the
layout is in fractions of the image size, so image_width/image_height rescale the same
scene), --family and --preview-frame do not apply, and --quiet turns the progress bar of the
rendering off (without --video there is none)."""

EPILOG = """\
examples:
  jaxtrack simulate --seed 0 --out data/synthetic-0
  jaxtrack simulate --seed 1 --out /tmp/short --num-frames 200
  jaxtrack simulate --print-config > scene.json   # edit, then:
  jaxtrack simulate --seed 2 --out /tmp/custom --scene-config scene.json
  jaxtrack simulate --family street --seed 1 --out /tmp/street-1
  jaxtrack simulate --video --seed 3 --out /tmp/v3
  jaxtrack simulate --video --print-config > video.json   # edit, then:
  jaxtrack simulate --video --seed 3 --out /tmp/v3-small --scene-config video.json"""


def register(subparsers) -> None:
    """Adds the ``simulate`` parser to the CLI's sub-parsers.

    Args:
        subparsers: the object returned by ``ArgumentParser.add_subparsers``.
    """
    parser = subparsers.add_parser(
        "simulate",
        help="write a seeded synthetic sequence with known context (MOTChallenge folder)",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_seed(parser)
    add_out(parser, "sequence folder to write (required; created if needed)", False, "DIR")
    parser.add_argument(
        "--num-frames",
        type=ranged(FRAME_COUNT),
        metavar="T",
        help="number of frames (default: the configuration's, 800; with --video 500)",
    )
    parser.add_argument(
        "--family",
        choices=tuple(FAMILIES),
        metavar="NAME",
        help="start from a scene family of the test bank, its layout drawn from --seed "
        f"({', '.join(FAMILIES)}; default: the default scene)",
    )
    parser.add_argument(
        "--scene-config",
        type=Path,
        metavar="FILE.json",
        help="JSON object overriding fields of the scene configuration (not a tracker "
        "configuration; see --print-config for all fields; zones and clutter_sources replace "
        "the defaults)",
    )
    parser.add_argument(
        "--name",
        help="sequence name in seqinfo.ini, and of NAME.mp4 with --video (default: the "
        "folder's name; with --family, FAMILY-SEED)",
    )
    parser.add_argument(
        "--preview-frame",
        type=ranged(FRAME_NUMBER),
        metavar="K",
        help="frame drawn in preview.png (default: the first frame with the most targets)",
    )
    parser.add_argument(
        "--print-config",
        action="store_true",
        help="print the effective configuration as JSON and exit",
    )
    parser.add_argument(
        "--video",
        action="store_true",
        help="render the scripted surveillance video scene (NAME.mp4 with its ground truth, "
        "detections and video_truth.json) instead of a detection-level scene",
    )
    add_quiet(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Generates and writes the scene; prints a summary of its statistics.

    Args:
        args: the parsed arguments of ``jaxtrack simulate``.

    Returns:
        0 on success (or after ``--print-config``).

    Raises:
        InputError: a missing or invalid argument or configuration file.
    """
    if args.video:
        return run_video(args)
    refuse_ignored(args, ("quiet",), "needs --video (only the video is drawn with a progress bar)")
    config = SceneConfig() if args.family is None else family_config(args.family, args.seed)
    if args.scene_config is not None:
        config = load_scene_config(args.scene_config, config)
    if args.num_frames is not None:
        config = dataclasses.replace(config, num_frames=args.num_frames)
    if args.print_config:
        reason = "does nothing with --print-config (it only prints the configuration)"
        refuse_ignored(args, ("out", "name", "preview_frame"), reason)
        if args.seed and args.family is None:
            raise InputError(f"--seed {reason} unless with --family")
        print(json.dumps(config_to_dict(config), indent=2))
        return 0
    if args.out is None:
        raise InputError("--out DIR is required")
    out = Path(args.out)
    if args.preview_frame is not None and not 1 <= args.preview_frame <= config.num_frames:
        raise InputError(f"--preview-frame must lie in 1..{config.num_frames}")
    check_outputs(
        output_folder("--out", args.out, SCENE_FILES),
        file_input(args.scene_config, f"the scene configuration {args.scene_config}"),
    )
    if (out / "seqinfo.ini").is_file() and not (out / "context_truth.npz").is_file():
        raise InputError(
            f"--out {args.out} holds a sequence that jaxtrack simulate did not write (no "
            "context_truth.npz); its seqinfo.ini, det/det.txt and gt/gt.txt would be "
            "overwritten: give another folder"
        )
    name = args.name or config.name or out.resolve().name
    config = dataclasses.replace(config, name=name)

    if args.family is None:
        scene = generate_scene(args.seed, config)
    else:
        scene = generate_family_scene(args.family, args.seed, config)
    out = write_scene(scene, out)
    save_scene_preview(scene, out / "preview.png", args.preview_frame)
    stats = scene.summary()
    by_source = ", ".join(f"{k} {v:.2f}" for k, v in stats["clutter_per_frame_by_source"].items())
    seed = f"seed {args.seed}"
    if scene.seed != args.seed:
        seed += f", simulated from seed {scene.seed} (the family's condition)"
    print(f"wrote {out} ({config.num_frames} frames, {seed}, name {name})")
    print(
        f"  targets: {stats['targets']} ({stats['targets_per_frame_min']}-"
        f"{stats['targets_per_frame_max']} per frame, mean {stats['targets_per_frame_mean']:.1f}),"
        f" births {stats['births']} ({stats['births_per_frame']:.3f}/frame)"
    )
    print(
        f"  detection rate {stats['detection_rate']:.3f} "
        f"(unoccluded {stats['detection_rate_unoccluded']:.3f}, "
        f"occluded {stats['detection_rate_occluded']:.3f})"
    )
    print(f"  clutter {stats['clutter_per_frame']:.2f}/frame ({by_source})")
    return 0


#: The files ``jaxtrack simulate --video`` writes into a folder (and ``NAME.mp4``).
VIDEO_SCENE_FILES = ("seqinfo.ini", "det/det.txt", "gt/gt.txt", TRUTH_FILE)


def run_video(args: argparse.Namespace) -> int:
    """``simulate --video``: generates, renders and writes the scripted video scene.

    Args:
        args: the parsed arguments of ``jaxtrack simulate``.

    Returns:
        0 on success (or after ``--print-config``).

    Raises:
        InputError: an option that does not apply to the video scene, or a missing or
            invalid argument or configuration file.
    """
    refuse_ignored(
        args,
        ("family", "preview_frame"),
        "does not apply to --video (the video scene has no families, and its video shows "
        "every frame)",
    )
    config = VideoSceneConfig()
    if args.scene_config is not None:
        config = load_video_config(args.scene_config, config)
    if args.num_frames is not None:
        config = dataclasses.replace(config, num_frames=args.num_frames)
    if args.print_config:
        reason = "does nothing with --print-config (it only prints the configuration)"
        refuse_ignored(args, ("out", "name", "quiet"), reason)
        if args.seed:
            raise InputError(f"--seed {reason}")
        print(json.dumps(video_config_to_dict(config), indent=2))
        return 0
    if args.out is None:
        raise InputError("--out DIR is required")
    out = Path(args.out)
    name = check_video_name(args.name or config.name or out.resolve().name)
    config = dataclasses.replace(config, name=name)
    check_outputs(
        output_folder("--out", args.out, (*VIDEO_SCENE_FILES, f"{name}.mp4")),
        file_input(args.scene_config, f"the scene configuration {args.scene_config}"),
    )
    if (out / "seqinfo.ini").is_file() and not (out / TRUTH_FILE).is_file():
        raise InputError(
            f"--out {args.out} holds a sequence that jaxtrack simulate --video did not write "
            f"(no {TRUTH_FILE}); its seqinfo.ini, det/det.txt and gt/gt.txt would be "
            "overwritten: give another folder"
        )
    scene = generate_video_scene(args.seed, config)
    start = time.perf_counter()
    write_video_scene(scene, out, progress=not args.quiet)
    seconds = time.perf_counter() - start
    counts = np.bincount(scene.gt_table.frames - 1, minlength=config.num_frames)
    print(
        f"wrote {out} ({config.num_frames} frames {config.image_width}x{config.image_height} "
        f"at {config.frame_rate:g} fps, seed {args.seed}, name {name})"
    )
    print(
        f"  {video_file_name(scene)}: rendered and encoded at "
        f"{config.num_frames / seconds:.0f} frames/s"
    )
    print(
        f"  people: {scene.num_people} ({counts.min()}-{counts.max()} per frame, "
        f"mean {counts.mean():.1f}); detections {len(scene.det_table) / config.num_frames:.2f}"
        "/frame"
    )
    for event in scene.events:
        if event.kind not in ("entry", "exit"):
            ids = ", ".join(map(str, event.ids))
            print(f"  {event.kind}: id {ids}, frames {event.frames[0]}-{event.frames[1]}")
    return 0
