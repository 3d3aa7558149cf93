"""``jaxtrack detect``: people detections from a video by background subtraction."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from jaxtrack.commands.arguments import (
    TRAIN_FRAMES,
    add_frames,
    add_json,
    add_out,
    add_quiet,
    ranged,
)
from jaxtrack.commands.paths import (
    check_outputs,
    file_input,
    frames_output,
    output_file,
    video_input,
)
from jaxtrack.detect.pipeline import METHODS, DetectorConfig, detect_video
from jaxtrack.errors import InputError
from jaxtrack.io import read_mot_file, write_mot_file
from jaxtrack.io.video import VIDEO_EXTENSIONS, FrameWriter, VideoReader, annotate_frame
from jaxtrack.limits import FRAME_RATE
from jaxtrack.metrics.detection import detection_precision_recall

DESCRIPTION = """\
Detect people in a video file (or a folder of images) by background subtraction and write
MOTChallenge detections `frame,-1,x,y,w,h,score,-1,-1,-1` (frames numbered from 1: video
frame i counting from 0 is frame i+1).

Methods:
  horprasert  Horprasert colour model (SPEC 4): per-pixel robust mean/spread of RGB from
              --train-frames frames spread evenly over the span (temporal median and MAD,
              so people walking through them do not enter the background); brightness and
              chromaticity distortion normalised by their own variation; automatic
              thresholds; foreground and dark foreground kept, shadows and highlights
              dropped (default)
  mog2        OpenCV's MOG2 Gaussian-mixture subtractor with shadow detection, warmed up
              on the same training frames; shadows dropped

Both then clean the mask at half resolution (opening with a vertical line, closing with a
tall ellipse), keep blobs of >= 240 full-resolution pixels, learn a perspective prior
(person height against the row of the feet) from the blobs, split blobs too wide or tall
for one person, drop parts under half a person's height, and widen thin silhouettes to a
pedestrian box (w/h 0.41). Score = min(1, height / expected height at that row).

With --gt, precision and recall against that ground truth (IoU 0.5, one-to-one per frame,
gt rows with conf 0 ignored) are printed."""

EPILOG = """\
examples:
  jaxtrack detect ../shared/data/video/vtest.avi --out det.txt
  jaxtrack detect ../shared/data/video/vtest.avi --method mog2 --frames 1:100 --out d.txt \\
      --gt ../shared/data/mot15/PETS09-S2L1/gt/gt.txt --preview det.mp4"""


def register(subparsers) -> None:
    """Adds the ``detect`` parser to the CLI's sub-parsers."""

    defaults = DetectorConfig()
    parser = subparsers.add_parser(
        "detect",
        help="detect people in a video by background subtraction (MOTChallenge det.txt)",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("video", metavar="VIDEO", help="video file or folder of images")
    add_out(parser, "detections to write", metavar="DET.txt")
    parser.add_argument(
        "--method", choices=METHODS, default=defaults.method, help="detector (default horprasert)"
    )
    add_frames(parser)
    parser.add_argument(
        "--fps",
        type=ranged(FRAME_RATE),
        metavar="F",
        help="frame rate of a --preview video (default: the input video's)",
    )
    parser.add_argument(
        "--train-frames",
        type=ranged(TRAIN_FRAMES),
        default=defaults.train_frames,
        metavar="N",
        help=f"frames for the background statistics (default {defaults.train_frames})",
    )
    parser.add_argument(
        "--no-split", action="store_true", help="keep blobs whole (no perspective splitting)"
    )
    parser.add_argument(
        "--preview",
        metavar="OUT.mp4",
        help="also write the frames with their detections (.mp4/.avi, or a folder for PNGs)",
    )
    parser.add_argument("--gt", metavar="GT.txt", help="print precision/recall against this gt")
    add_quiet(parser)
    add_json(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Detects, writes the detections (and the preview), prints a summary.

    Args:
        args: the parsed arguments of ``jaxtrack detect``.

    Returns:
        0 on success.

    Raises:
        InputError: a bad argument, an unreadable video or ground-truth file.
    """

    if args.fps is not None and not (
        args.preview and Path(args.preview).suffix.lower() in VIDEO_EXTENSIONS
    ):
        raise InputError(
            "--fps applies to a --preview video (.mp4/.avi); detection does not use the frame rate"
        )
    outputs = [output_file("--out", args.out)]
    if args.preview:
        outputs.append(frames_output("--preview", args.preview))
    check_outputs(
        outputs,
        [
            *video_input(args.video, f"the video {args.video}"),
            *file_input(args.gt, f"the ground truth --gt {args.gt}"),
        ],
    )
    config = DetectorConfig(
        method=args.method, train_frames=args.train_frames, split=not args.no_split
    )
    start = time.perf_counter()
    with VideoReader(args.video, fps=args.fps) as reader:
        found = detect_video(reader, args.frames, config, progress=not args.quiet)
        elapsed = time.perf_counter() - start
        write_mot_file(args.out, found.table)
        first, last = found.frames
        summary = {
            "out": str(args.out),
            "detections": len(found.table),
            "frames": [first, last],
            "frames_per_second": (last - first + 1) / elapsed,
        }
        if not args.json:
            print(
                f"wrote {args.out} ({len(found.table)} detections in frames {first}:{last}, "
                f"{summary['frames_per_second']:.1f} frames/s)"
            )
        if found.prior is not None:
            prior = found.prior
            summary["perspective_prior"] = {
                "intercept": prior.intercept,
                "slope": prior.slope,
                "aspect": prior.aspect,
            }
            if not args.json:
                print(
                    f"  perspective prior: height = {prior.intercept:.1f} + {prior.slope:.3f} * "
                    f"foot row, silhouette w/h {prior.aspect:.2f}"
                )
        if args.gt:
            precision, recall = precision_recall(
                found.table, args.gt, found.frames, reader.num_frames
            )
            summary.update(precision=precision, recall=recall)
            if not args.json:
                print(f"  precision {precision:.3f}, recall {recall:.3f} (IoU 0.5, vs {args.gt})")
        if args.preview:
            write_preview(reader, found.table, found.frames, args.preview, not args.quiet)
            summary["preview"] = str(args.preview)
            if not args.json:
                print(f"  preview: {args.preview}")
    if args.json:
        print(json.dumps(summary))
    return 0


def precision_recall(table, gt_path: str, frames: tuple[int, int], num_frames: int):
    """Precision and recall of ``table`` against the gt file on ``frames`` (IoU 0.5)."""

    gt = read_mot_file(gt_path, "gt", num_frames).frame_span(*frames)
    return detection_precision_recall(table, gt, frames)


def write_preview(reader, table, frames: tuple[int, int], path: str, progress: bool = True) -> None:
    """Writes the span's frames with their detection boxes to a video or PNG folder."""

    if not frames[0] <= frames[1]:
        raise InputError(f"empty frame span {frames}")
    with FrameWriter(path, (reader.width, reader.height), reader.fps) as writer:
        span = range(frames[0], frames[1] + 1)
        for k in tqdm(span, desc="preview", unit="frame", disable=not progress):
            boxes = table.boxes[np.flatnonzero(table.frames == k)]
            writer.write(annotate_frame(reader.read(k), boxes, label=f"frame {k}"), k)
