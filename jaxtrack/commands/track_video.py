"""``jaxtrack track-video``: video -> background-subtraction detections -> any tracker's tracks."""

from __future__ import annotations

import argparse
import json
import operator
import sys
import time
from pathlib import Path

import cv2
import jax
import numpy as np
from tqdm import tqdm

from jaxtrack.commands.arguments import (
    DEFAULT_VARIANT,
    FRAMES_OR_NONE,
    add_config,
    add_frames,
    add_fusion_arguments,
    add_out,
    add_quiet,
    add_seed,
    add_tracker,
    add_variant_and_scene_arguments,
    apply_fusion_arguments,
    apply_tracker_variant,
    check_train_frames,
    context_variant,
    load_config,
    ranged,
    refuse_ignored,
    tracker_variant_names,
)
from jaxtrack.commands.paths import (
    check_outputs,
    file_input,
    frames_output,
    output_file,
    side_file,
    video_input,
)
from jaxtrack.configs import TrackerConfig
from jaxtrack.context.learn import BIRTH_POSITION_DIMS, CLUTTER_POSITION_DIMS
from jaxtrack.detect.pipeline import METHODS, DetectorConfig, detect_video
from jaxtrack.detect.sequence import video_info, video_sequence
from jaxtrack.errors import InputError
from jaxtrack.filters.registry import build_tracker, tracker_entry, writes_events
from jaxtrack.io import parse_frame_span, read_mot_file, write_mot_file, write_results
from jaxtrack.io.events import events_path, write_events
from jaxtrack.io.video import FrameWriter, VideoReader, annotate_frame
from jaxtrack.limits import FRAME_RATE
from jaxtrack.metrics.evaluate import evaluate_sequence
from jaxtrack.metrics.events import onset_summary
from jaxtrack.pipelines.events import event_outputs
from jaxtrack.pipelines.frame_context import streamed_params
from jaxtrack.pipelines.stream import streamed_outputs, streamed_rows
from jaxtrack.pipelines.tracking import (
    load_tracker_context,
    track_outputs,
    track_sequences,
    tracker_description,
)
from jaxtrack.plot.cmt_frames import (
    CMTFrame,
    cmt_frame_outputs,
    draw_condition_legend,
    draw_particles,
)
from jaxtrack.plot.context import position_map
from jaxtrack.plot.fusion_frames import (
    FusionFrame,
    draw_fusion,
    draw_fusion_legend,
    fusion_frame_outputs,
)
from jaxtrack.plot.hier_frames import HierarchicalFrame, draw_levels, hier_frame_outputs

DESCRIPTION = """\
Track people in a video end to end: detect them by background subtraction (as `jaxtrack
detect`, --method horprasert or mog2) on the frame span, then run a tracker (as `jaxtrack
track`, same default configurations; --config overrides them) and write MOTChallenge results
`frame,id,x,y,w,h,score,-1,-1,-1` (frames numbered from 1: video frame i counting from 0 is
frame i+1). --detections DET.txt tracks those detections instead of detecting. The frame
rate (motion model) is the video's unless --fps overrides it (vtest.avi's header says 10
fps; PETS 2009 was recorded at 7).

--tracker phd (default) runs the particle PHD tracker: --context CTX.npz uses a learned
context (`jaxtrack learn-context VIDEO --detections ...`), --variant picks its parts
(default GM). --tracker kalman runs the data-association baseline (default preset).
--tracker cmt runs contextual mixture tracking (one particle tracker per target; see
`jaxtrack track --help`) on the video's frames, streamed, with the detections as its
foreground blobs: --variant mtb|cpd|cmt picks the ablation's variant (default cmt), --zones
ZONES.json its entry/exit zones (`jaxtrack learn-zones`; default: learned on the fly from the
PHD tracker's trajectories on the span; the run says which). --context, --overlay are for
the PHD tracker, --zones for CMT: given to another tracker they are errors.

--tracker hierarchical runs the Hierarchical tracker (see `jaxtrack track --help`):
--variant kalman|managed|full (default full); its background model is the median of 25
frames of the span; the event states are written beside the results (RES.events.csv).

--tracker fusion runs the Fusion tracker (see `jaxtrack track --help`): --pool picks its
members (comma-separated, any non-empty subset of detection,classifier,predictor in any
order; default all three), --fusion proposed|naive the fusion rule (default proposed),
--train-frames A:B the span (inside --frames) it learns its zones, activity mask, motion
models and voting thresholds on (default: the first half of the span). A video has no ground
truth to learn from: its trajectories are the PHD tracker's tracks on the training span's
detections, and its voting thresholds are the paper's (th_init 3, th_term 8); --gt only
scores. RES.config.json says what it learned (training).

--annotate writes the frames with the tracks (box and id in the id's colour, a trail of the
last --trail centres of the feet) and the detections (thin white boxes) to a video (.mp4 or
.avi) or, for any other path, a folder of PNGs; --overlay birth|clutter blends in the
context's birth or clutter intensity over the image (heat map). With --tracker cmt it also
draws each living component's particles (box centres) as outlined dots coloured by the motion
condition they were proposed under: normal cyan, split yellow, merge magenta, exit
orange-red (legend in the top-right corner). With --tracker hierarchical it draws the
low-level tracks as white ellipses (thin while tentative) and the high-level trackers as
black ones (thin while lost), each labelled with its identity and event state, as the
paper's Fig. 3. With --tracker fusion it draws, for every target and hypothesis, each pool
member's response box thin (detection cyan, classifier magenta, predictor yellow), the fused
box thick in the identity's colour with the identity below it (an occluded target's dashed,
labelled "occluded"), a hypothesis not yet voted in grey, labelled "hyp" (key in the
top-right corner). --gt GT.txt prints MOTA, MOTP, MODA, MODP and
IDF1 against that ground truth.

Writes RES.txt, RES.config.json (settings used), RES.events.csv (--tracker hierarchical)
and, with --save-detections, the detections."""

EPILOG = """\
examples:
  jaxtrack track-video ../shared/data/video/vtest.avi --frames 401:795 --out v.txt \\
      --annotate v.mp4
  jaxtrack track-video ../shared/data/video/vtest.avi --frames 401:795 --fps 7 \\
      --context ctx.npz --out gm.txt --gt ../shared/data/mot15/PETS09-S2L1/gt/gt.txt
  jaxtrack track-video ../shared/data/video/vtest.avi --frames 1:100 --fps 7 \\
      --tracker cmt --variant cmt --out cmt.txt --annotate cmt.mp4
  jaxtrack track-video ../shared/data/video/vtest.avi --tracker hierarchical \\
      --out h.txt --annotate h.mp4
  jaxtrack track-video ../shared/data/video/vtest.avi --fps 7 --tracker fusion \\
      --pool detection,classifier --train-frames 1:200 --out f.txt --annotate f.mp4"""

#: Trackers whose --annotate draws more than the tracks: their per-frame drawing outputs.
FRAME_DRAWINGS = {
    "cmt": cmt_frame_outputs,
    "hierarchical": hier_frame_outputs,
    "fusion": fusion_frame_outputs,
}
#: Centres of the feet drawn behind each track by --annotate (default).
DEFAULT_TRAIL = 20
#: Detector of --method (default).
DEFAULT_METHOD = "horprasert"


def register(subparsers) -> None:
    """Adds the ``track-video`` parser to the CLI's sub-parsers."""

    parser = subparsers.add_parser(
        "track-video",
        help="detect (background subtraction) and track (PHD, CMT, ...) people in a video",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("video", metavar="VIDEO", help="video file or folder of images")
    add_out(parser, "results to write", metavar="RES.txt")
    add_frames(parser)
    parser.add_argument(
        "--fps", type=ranged(FRAME_RATE), metavar="F", help="frame rate (overrides the file's)"
    )
    parser.add_argument("--method", choices=METHODS, help=f"detector (default {DEFAULT_METHOD})")
    parser.add_argument(
        "--detections", metavar="DET.txt", help="track these detections instead of detecting"
    )
    parser.add_argument(
        "--no-split", action="store_true", help="keep blobs whole (no perspective splitting)"
    )
    parser.add_argument(
        "--save-detections", metavar="DET.txt", help="also write the detections made"
    )
    add_tracker(parser)
    add_config(parser)
    add_variant_and_scene_arguments(parser, "see jaxtrack track --help")
    add_fusion_arguments(parser)
    add_seed(parser)
    parser.add_argument("--annotate", metavar="OUT.mp4", help="write the annotated frames")
    parser.add_argument(
        "--trail",
        type=ranged(FRAMES_OR_NONE),
        metavar="N",
        help=f"trail length in frames for --annotate (default {DEFAULT_TRAIL})",
    )
    parser.add_argument(
        "--overlay",
        choices=("birth", "clutter"),
        help="with --annotate and --context: draw that intensity as a heat map",
    )
    parser.add_argument("--gt", metavar="GT.txt", help="print tracking metrics against this gt")
    add_quiet(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Detects, tracks, writes the results (and annotations), prints a summary.

    Args:
        args: the parsed arguments of ``jaxtrack track-video``.

    Returns:
        0 on success.

    Raises:
        InputError: a bad argument, an unreadable video, detections, context, zones or gt
            file.
    """

    if args.detections is not None:
        refuse_ignored(
            args,
            ("method", "no_split", "save_detections"),
            "applies when detecting, not with --detections",
        )
    if args.annotate is None:
        refuse_ignored(
            args, ("trail", "overlay"), "needs --annotate (it only changes the annotated frames)"
        )
    config, variant = tracker_config(args)
    if args.overlay and not args.context:
        raise InputError("--overlay needs --context and --annotate")
    trail = DEFAULT_TRAIL if args.trail is None else args.trail
    method = args.method or DEFAULT_METHOD
    outputs = [output_file("--out", args.out), side_file("--out", args.out, ".config.json")]
    if writes_events(config):
        outputs.append(side_file("--out", args.out, ".events.csv"))
    if args.save_detections:
        outputs.append(output_file("--save-detections", args.save_detections))
    if args.annotate:
        outputs.append(frames_output("--annotate", args.annotate))
    check_outputs(
        outputs,
        [
            *video_input(args.video, f"the video {args.video}"),
            *file_input(args.detections, f"the detections --detections {args.detections}"),
            *file_input(args.config, f"the tracker configuration --config {args.config}"),
            *file_input(args.context, f"the context --context {args.context}"),
            *file_input(args.zones, f"the zones --zones {args.zones}"),
            *file_input(args.gt, f"the ground truth --gt {args.gt}"),
        ],
    )
    context = load_tracker_context(args.context)
    start = time.perf_counter()
    with VideoReader(args.video, fps=args.fps) as reader:
        info = video_info(reader)
        span = parse_frame_span(args.frames, reader.num_frames)
        check_train_frames(args.train_frames, span, reader.num_frames)
        if args.detections:
            detections = read_mot_file(args.detections, "det", info=info)
        else:
            config_detect = DetectorConfig(method=method, split=not args.no_split)
            found = detect_video(reader, span, config_detect, progress=not args.quiet)
            detections = found.table
            if args.save_detections:
                write_mot_file(args.save_detections, detections)
        detect_seconds = time.perf_counter() - start
        sequence = video_sequence(args.video, detections, span, info)
        used = {
            **tracker_description(config),
            "seed": args.seed,
            "video": str(args.video),
            "frames": list(span),
            "fps": info.frame_rate,
            "detector": "file" if args.detections else method,
        }
        rows, drawn, events = track_span(
            sequence, reader, config, args, context, variant, used, progress=not args.quiet
        )
        elapsed = time.perf_counter() - start
        write_results(args.out, rows.frames, rows.ids, rows.boxes, rows.confs)
        if events is not None:
            written = write_events(events_path(args.out), events)
            print(f"  events: {written} ({onset_summary(events)})")
        if tracker_entry(config.tracker).takes_context:
            used["variant"] = variant or "UM"
        if args.context:
            used["context"] = str(args.context)
        Path(f"{Path(args.out).with_suffix('')}.config.json").write_text(json.dumps(used, indent=2))
        num_frames = span[1] - span[0] + 1
        print(
            f"wrote {args.out} ({len(rows.frames)} boxes, {len(set(rows.ids.tolist()))} tracks, "
            f"frames {span[0]}:{span[1]}; {num_frames / elapsed:.1f} frames/s end to end, "
            f"detection {detect_seconds:.1f} s, tracking {elapsed - detect_seconds:.1f} s "
            "including compilation)"
        )
        if args.gt:
            print_tracking_scores(args.gt, rows, span, reader.num_frames)
        if args.annotate:
            overlay = None
            if args.overlay:
                overlay = intensity_overlay(context, args.overlay, reader.width, reader.height)
            write_annotated(
                reader,
                rows,
                sequence.det_table,
                span,
                args.annotate,
                trail,
                overlay,
                drawn,
                progress=not args.quiet,
            )
            print(f"  annotated: {args.annotate}")
    return 0


def tracker_config(args: argparse.Namespace) -> tuple[TrackerConfig, str | None]:
    """The tracker's configuration (``--tracker``, ``--config``, CMT's ``--variant``) and the
    PHD context's variant (None without ``--context``).

    Raises:
        InputError: an option the tracker does not take (``--zones`` but for CMT,
            ``--context`` and ``--overlay`` but for PHD, ``--pool``, ``--fusion`` and
            ``--train-frames`` but for Fusion, a variant of another tracker), or a bad
            configuration file.
    """
    entry = tracker_entry(args.tracker)
    if not entry.takes_zones:
        refuse_ignored(args, ["zones"], f"applies to --tracker cmt, not to {args.tracker}")
    if not entry.takes_context:
        refuse_ignored(
            args, ("context", "overlay"), f"applies to the PHD tracker, not to {args.tracker}"
        )
    config = apply_fusion_arguments(args, load_config(args.config, args.tracker))
    if entry.variants or args.variant in tracker_variant_names():
        return apply_tracker_variant(args, config), None
    if not entry.takes_context:
        refuse_ignored(args, ["variant"], f"applies to the PHD tracker, not to {args.tracker}")
    return config, context_variant(args)


def track_span(sequence, reader, config, args, context, variant, used, progress: bool):
    """Tracks the span's detections: streamed with its frames for a tracker that uses them
    (CMT with its zones, the Hierarchical tracker with the background image, the Fusion
    tracker with what it learned on its training span, recorded in ``used`` and printed),
    else as ``jaxtrack track`` does.

    Args:
        sequence: the span with its detections (:func:`~jaxtrack.detect.sequence.
            video_sequence`).
        reader: the open video, the frames' source.
        config: the tracker's configuration.
        args: the parsed arguments (``seed``, ``zones``, ``train_frames``, ``annotate``).
        context: the PHD tracker's learned context, or None.
        variant: its variant (None without a context).
        used: the run's description for ``.config.json`` (the zones used are added).
        progress: show progress bars.

    Returns:
        The result rows; with ``--annotate`` and a tracker of :data:`FRAME_DRAWINGS` its
        per-frame drawing outputs stacked over the span (else None); for a tracker that
        writes events, the event state of every result row (else None).
    """
    entry = tracker_entry(config.tracker)
    if not entry.uses_frames:
        _, params = build_tracker(config, sequence.info, context, variant or DEFAULT_VARIANT)
        (rows,) = track_sequences([sequence], config, args.seed, [params], progress=progress)
        return rows, None, None
    params, scene = streamed_params(
        config,
        sequence,
        reader,
        args.seed,
        args.zones,
        args.train_frames,
        blobs=not args.detections,
    )
    for value in scene.values():
        print(value, file=sys.stderr)
    used.update(scene)
    drawn = args.annotate is not None and config.tracker in FRAME_DRAWINGS
    frame_output = FRAME_DRAWINGS[config.tracker] if drawn else track_outputs
    if writes_events(config) and not drawn:
        frame_output = event_outputs
    outputs = streamed_outputs(
        sequence, reader, config, args.seed, params, frame_output=frame_output
    )
    rows, events, outputs = streamed_rows(outputs, sequence, config)
    return rows, outputs if drawn else None, events


def print_tracking_scores(gt_path: str, rows, span: tuple[int, int], num_frames: int) -> dict:
    """Prints (and returns) MOTA, MOTP, MODA, MODP and IDF1 of ``rows`` on ``span``."""

    gt = read_mot_file(gt_path, "gt", num_frames).frame_span(*span)
    summary = evaluate_sequence(gt, rows, span).summary()
    scores = {key: summary[key] for key in ("MOTA", "MOTP", "MODA", "MODP", "IDF1")}
    print("  " + ", ".join(f"{key} {value:.4f}" for key, value in scores.items()))
    return scores


def intensity_overlay(context, part: str, width: int, height: int):
    """The context's birth or clutter intensity over the image centres, ``[height, width]``."""

    intensity = context.birth if part == "birth" else context.clutter
    dims = BIRTH_POSITION_DIMS if part == "birth" else CLUTTER_POSITION_DIMS
    grid = position_map(intensity, dims, width, height, step=8.0)
    return cv2.resize(grid, (width, height), interpolation=cv2.INTER_LINEAR)


def write_annotated(
    reader,
    rows,
    det_table,
    span,
    path: str,
    trail: int,
    overlay=None,
    drawn: CMTFrame | HierarchicalFrame | FusionFrame | None = None,
    progress: bool = True,
) -> None:
    """Writes the span's frames with detections, tracks (id colours), trails and overlay;
    with ``drawn`` a run's per-frame drawing outputs stacked over the span: a CMT run's
    :class:`~jaxtrack.plot.cmt_frames.CMTFrame` (the living components' particles coloured
    by motion condition on top, and their legend) or a Hierarchical run's
    :class:`~jaxtrack.plot.hier_frames.HierarchicalFrame` (low-level tracks in white,
    high-level trackers in black, with their event states) or a Fusion run's
    :class:`~jaxtrack.plot.fusion_frames.FusionFrame` (each member's response thin, the
    fused boxes thick, occluded targets dashed, hypotheses grey, and the key of the members
    that responded in the span)."""

    feet = np.stack([rows.boxes[:, 0] + rows.boxes[:, 2] / 2, rows.boxes[:, 1] + rows.boxes[:, 3]])
    if drawn is not None:
        drawn = jax.device_get(drawn)
    if isinstance(drawn, FusionFrame):
        responded = np.asarray(drawn.member_valid).any(axis=(0, 1))
    with FrameWriter(path, (reader.width, reader.height), reader.fps) as writer:
        frames = range(span[0], span[1] + 1)
        for k in tqdm(frames, desc="annotate", unit="frame", disable=not progress):
            image = reader.read(k)
            image = annotate_frame(image, det_table.boxes[det_table.frames == k], overlay=overlay)
            here = np.flatnonzero(rows.frames == k)
            recent = (rows.frames > k - trail) & (rows.frames <= k)
            trails = {}
            for track_id in rows.ids[here].tolist():
                points = recent & (rows.ids == track_id)
                order = np.argsort(rows.frames[points])
                trails[track_id] = feet[:, points][:, order].T
            image = annotate_frame(
                image, rows.boxes[here], rows.ids[here], trails, label=f"frame {k}"
            )
            t = k - span[0]
            if isinstance(drawn, CMTFrame):
                image = draw_particles(image, drawn.centres[t], drawn.conditions[t], drawn.alive[t])
                image = draw_condition_legend(image)
            elif isinstance(drawn, HierarchicalFrame):
                image = draw_levels(image, jax.tree.map(operator.itemgetter(t), drawn))
            elif isinstance(drawn, FusionFrame):
                image = draw_fusion(image, jax.tree.map(operator.itemgetter(t), drawn))
                image = draw_fusion_legend(image, responded)
            writer.write(image, k)
