"""``jaxtrack label-clutter SEQ_DIR``: mark clutter detections by clicking them in a window."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from jaxtrack.commands.arguments import add_frames, add_out, add_seed, ranged
from jaxtrack.commands.paths import (
    check_outputs,
    file_input,
    output_file,
    same_path,
    sequence_inputs,
    video_input,
)
from jaxtrack.context.clutter_labels import choose_frames, load_clutter_labels
from jaxtrack.errors import InputError
from jaxtrack.io import load_sequence
from jaxtrack.io.video import VideoReader, find_frame_source
from jaxtrack.limits import FRAME_COUNT
from jaxtrack.plot.label_tool import label_interactively

DEFAULT_NUM_FRAMES = 20

DESCRIPTION = """\
Label clutter (detections that are not objects of interest) by hand, for learning the clutter
intensity (jaxtrack learn-context --clutter-from LABELS.json).

A window shows NUM randomly chosen frames of the span --frames A:B (required unless --resume;
drawn with --seed; frames without detections included) one at a time, with the frame's
detections from det/det.txt as rectangles: green = object, red = clutter.

  left click inside a box   toggle it clutter / object (overlapping boxes: the smallest
                            box containing the click)
  right arrow or n          next frame
  left arrow or p           previous frame
  s                         save
  q                         save and close (closing the window also saves)

A frame counts as labelled once it has been shown: its boxes left green are objects. The
labels file (JSON) records the sequence, image size, the labelled frames, the frames still to
show, and each clutter detection's frame and box exactly as in det.txt; continue an
unfinished labelling with --resume.

Frames come from --video, else SEQ_DIR/img1/, else SEQ_DIR/<name>.mp4 or .avi, else the boxes
are drawn on a grey canvas of the image size. Video frame i (from 0) is MOT frame i+1.

Needs a display and an interactive matplotlib backend (tkagg, qtagg, ...); in a headless
session it exits with status 2."""

EPILOG = """\
examples:
  jaxtrack label-clutter data/mot15/PETS09-S2L1 --video data/video/vtest.avi \\
      --frames 1:397 --out pets-clutter.json
  jaxtrack label-clutter data/mot15/TUD-Stadtmitte --frames 1:90 --num-frames 30 \\
      --out tud-clutter.json --backend qtagg
  jaxtrack label-clutter data/mot15/TUD-Stadtmitte --resume tud-clutter.json \\
      --out tud-clutter.json"""


def register(subparsers) -> None:
    """Adds the ``label-clutter`` parser to the CLI's sub-parsers.

    Args:
        subparsers: the object returned by ``ArgumentParser.add_subparsers``.
    """
    parser = subparsers.add_parser(
        "label-clutter",
        help="label clutter detections interactively (click boxes in a matplotlib window)",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("sequence", metavar="SEQ_DIR", help="folder with seqinfo.ini and det/")
    add_frames(parser)
    add_out(parser, "labels file to write", metavar="LABELS.json")
    parser.add_argument(
        "--video",
        type=Path,
        metavar="FILE",
        help="video (or image folder) of the sequence; frame i from 0 is MOT frame i+1",
    )
    parser.add_argument(
        "--num-frames",
        type=ranged(FRAME_COUNT),
        metavar="NUM",
        help=f"frames to label, drawn at random from A:B (default {DEFAULT_NUM_FRAMES})",
    )
    add_seed(parser)
    parser.add_argument(
        "--resume",
        type=Path,
        metavar="LABELS.json",
        help="continue this labels file: its labelled frames and clutter are kept and its "
        "pending frames are shown next (not combinable with --frames, --num-frames or a nonzero "
        "--seed)",
    )
    parser.add_argument(
        "--backend",
        metavar="NAME",
        help="matplotlib backend for the window, e.g. tkagg or qtagg (default: matplotlib's)",
    )
    parser.set_defaults(func=run)


def run(args) -> int:

    out = Path(args.out)
    # --resume continues a labels file: it may be --out itself (updated in place)
    continued = args.resume is not None and same_path(args.resume, out)
    check_outputs(
        [output_file("--out", args.out)],
        [
            *sequence_inputs(args.sequence),
            *video_input(args.video, f"the frames --video {args.video}"),
            *([] if continued else file_input(args.resume, f"the labels --resume {args.resume}")),
        ],
    )
    resume = None
    if args.resume is not None:
        given = [
            flag
            for flag, value in (
                ("--frames", args.frames),
                ("--num-frames", args.num_frames),
                ("--seed", args.seed or None),  # the default 0 draws nothing on resume
            )
            if value is not None
        ]
        if given:
            raise InputError(
                f"--resume continues the frames stored in {args.resume}; drop {given[0]}"
            )
        resume = load_clutter_labels(args.resume)
        frames = np.concatenate([resume.labelled_frames, resume.pending_frames])
        if frames.size == 0:
            raise InputError(f"{args.resume}: no frames to label (labelled and pending empty)")
        span = (int(frames.min()), int(frames.max()))
    else:
        if args.frames is None:
            raise InputError("--frames A:B is required (or --resume LABELS.json)")
        span = args.frames
    if out.exists() and not continued:
        raise InputError(f"{out} exists; continue it with --resume {out} or choose another --out")
    sequence = load_sequence(args.sequence, frames=span)
    info = sequence.info
    if resume is not None:
        if resume.sequence != info.name or resume.image_size != (info.im_width, info.im_height):
            raise InputError(
                f"{args.resume} labels {resume.sequence} at {resume.image_size[0]}x"
                f"{resume.image_size[1]}, but {args.sequence} is {info.name} at "
                f"{info.im_width}x{info.im_height}"
            )
    else:
        num_frames = DEFAULT_NUM_FRAMES if args.num_frames is None else args.num_frames
        frames = choose_frames(sequence.first_frame, sequence.last_frame, num_frames, args.seed)

    source = find_frame_source(Path(args.sequence), info.name, args.video)
    reader = None if source is None else VideoReader(source)
    try:
        if reader is not None:
            _check_reader(reader, (info.im_width, info.im_height), int(frames.max()))
        labels = label_interactively(
            sequence.det_table,
            frames,
            out,
            sequence=info.name,
            image_size=(info.im_width, info.im_height),
            frame_source=None if reader is None else reader.read,
            resume=resume,
            backend=args.backend,
        )
    finally:
        if reader is not None:
            reader.close()
    print(
        f"{out}: {len(labels)} clutter detections on {labels.labelled_frames.size} "
        f"labelled frames ({labels.pending_frames.size} still to show)"
    )
    return 0


def _check_reader(reader, image_size: tuple[int, int], last_frame: int) -> None:
    """The frames must match seqinfo.ini's size and reach the last frame to show."""
    if (reader.width, reader.height) != image_size:
        raise InputError(
            f"{reader.path} is {reader.width}x{reader.height} but seqinfo.ini says "
            f"{image_size[0]}x{image_size[1]}; the boxes would not line up"
        )
    if reader.num_frames < last_frame:
        raise InputError(
            f"{reader.path} has {reader.num_frames} frames but frame {last_frame} is to be shown"
        )
