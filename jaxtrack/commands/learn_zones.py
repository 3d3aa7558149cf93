"""``jaxtrack learn-zones``: learn a sequence's entry/exit zones and activity mask (zones.json)."""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import numpy as np
from tqdm import tqdm

from jaxtrack.commands.arguments import (
    FRAMES_OR_NONE,
    add_frames,
    add_json,
    add_out,
    add_quiet,
    add_seed,
    ranged,
    refuse_ignored,
    step_progress,
)
from jaxtrack.commands.paths import (
    check_outputs,
    figure_output,
    file_input,
    output_file,
    sequence_inputs,
    video_input,
)
from jaxtrack.context.activity import ACTIVITY_CELL, ACTIVITY_RADIUS
from jaxtrack.context.io import load_context
from jaxtrack.context.zones import (
    CLUSTER_DISTANCE,
    INTERIOR_MARGIN,
    MARGIN_FRAMES,
    MIN_POINTS,
    MIN_SHARE,
    NUM_STD,
    PADDING,
    LearnedZones,
    SceneZones,
    zones_from_intensity,
)
from jaxtrack.errors import FileFormatError, InputError, InputWarning
from jaxtrack.io import parse_frame_span, read_seqinfo
from jaxtrack.io.video import VideoReader, find_frame_source
from jaxtrack.io.zones import activity_file, save_zones
from jaxtrack.pipelines.zones import SOURCES, learn_sequence_zones
from jaxtrack.plot.zones import save_zones_figure

DESCRIPTION = f"""\
Learn the structure of a scene from the trajectories of a training span (Fusion Sec. 2.3):
its entry/exit zones and activity mask, written to ZONES.json (read by trackers' --zones;
format: jaxtrack.io.zones).

Zones. The start and end points of the trajectories (foot points: the middle of a box's
bottom edge, where a person stands) are clustered together, leaving out the starts in the
span's first --margin frames (people already there) and the ends in its last --margin
frames (still there): average linkage cut at {CLUSTER_DISTANCE:g} x the image diagonal.
A cluster of fewer than {MIN_POINTS} points is noise; one whose centre lies more than
{INTERIOR_MARGIN:g} x the diagonal inside the convex hull of the other clusters' centres is
interior (nobody enters mid-scene). Each other cluster is a zone: the box median +-
{NUM_STD:g} robust standard deviations (1.4826 MAD) of its points, padded by {PADDING:g} x
the diagonal and clipped to the image, with its counts of entries (starts) and exits
(ends). A zone where people come and go is one zone.

Activity mask. The paths of the trajectories' foot points on {ACTIVITY_CELL}-pixel cells,
closed by a {2 * ACTIVITY_RADIUS:g}-pixel disk (joins nearby paths), then dilated by a
{ACTIVITY_RADIUS:g}-pixel disk; written beside ZONES.json as <stem>.activity.png, one
pixel per cell (255: active).

Trajectory sources (--from):
  tracks    the default tracker (PHD, uniform intensities) run on the span (default)
  gt        the ground truth (rows with conf 0 left out)
  CTX.npz   a context from `jaxtrack learn-context`: each Gaussian of its birth
            intensity with at least {MIN_SHARE:g} of the density is a zone, the mean
            +- {NUM_STD:g} std of its foot point (no trajectories: no activity mask;
            --frames, --margin and --seed do not apply)

--figure PNG draws the zones over the span's first frame, taken from --video, else from
the sequence's img1/ or <name>.mp4/.avi (a blank background when it has none)."""

EPILOG = """\
examples:
  jaxtrack learn-zones data/PETS09-S2L1 --from gt --out zones.json --figure zones.png \\
      --video vtest.avi
  jaxtrack simulate --video --seed 3 --out /tmp/v3
  jaxtrack learn-zones /tmp/v3 --frames 1:300 --from gt --out /tmp/z.json --figure /tmp/z.png
  jaxtrack learn-zones data/PETS09-S2L1 --from ctx.npz --out zones.json"""


def register(subparsers) -> None:
    """Adds the ``learn-zones`` parser to the CLI's sub-parsers.

    Args:
        subparsers: the object returned by ``ArgumentParser.add_subparsers``.
    """
    parser = subparsers.add_parser(
        "learn-zones",
        help="learn entry/exit zones and the activity mask of a sequence (zones.json)",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("sequence", metavar="SEQ_DIR", help="MOTChallenge sequence folder")
    add_frames(parser)
    parser.add_argument(
        "--from",
        dest="source",
        default="tracks",
        metavar="tracks|gt|CTX.npz",
        help="where the zones come from (default: tracks)",
    )
    add_out(parser, "zones file to write (and <stem>.activity.png beside it)", metavar="ZONES.json")
    parser.add_argument("--figure", metavar="PNG", help="draw the zones over a frame into PNG")
    parser.add_argument(
        "--video",
        metavar="FILE",
        help="video file or image folder of the sequence: the frame under the --figure",
    )
    parser.add_argument(
        "--margin",
        type=ranged(FRAMES_OR_NONE),
        metavar="N",
        help=f"frames at each end of the span whose trajectory starts / ends are not entries "
        f"/ exits (default {MARGIN_FRAMES})",
    )
    add_seed(parser)
    add_quiet(parser)
    add_json(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Learns the zones, writes them (and the figure), prints a summary.

    Args:
        args: the parsed arguments of ``jaxtrack learn-zones``.

    Returns:
        0 on success.

    Raises:
        InputError: a bad argument, file or span, or no trajectory starting or ending in it.
    """
    from_context = args.source not in SOURCES
    _check_arguments(args, from_context)
    info = read_seqinfo(Path(args.sequence) / "seqinfo.ini")
    image_size = (info.im_width, info.im_height)
    start = time.perf_counter()
    # steps: reading the context, or loading, (tracking,) learning; (drawing)
    steps = (1 if from_context else 2 + (args.source == "tracks")) + bool(args.figure)
    with tqdm(total=steps, desc="learn-zones", unit="step", disable=args.quiet) as bar:
        progress = step_progress(bar)

        if from_context:
            progress("reading the context")
            learned = None
            zones, details, summary = _context_zones(args.source, image_size)
        else:
            learned = learn_sequence_zones(
                args.sequence,
                args.frames,
                source=args.source,
                seed=args.seed,
                margin_frames=MARGIN_FRAMES if args.margin is None else args.margin,
                progress=progress,
            )
            zones, details = learned.scene, _counts(learned)
            span = list(parse_frame_span(args.frames, info.seq_length))
            summary = {"frames": span, **_clusters(learned)}
        bar.update(1)
        source = {"sequence": str(args.sequence), "from": args.source, **summary}
        written = save_zones(args.out, zones, image_size, details, source)
        if args.figure:
            bar.set_description_str("drawing")
            _figure(args, info, zones, details, learned, (source["frames"] or [1])[0])
            bar.update(1)
    report = {
        "out": str(args.out),
        "activity_mask": str(written[1]) if len(written) > 1 else None,
        "figure": args.figure,
        **source,
        "zones": [
            {**dict(zip("xywh", np.round(box, 3).tolist(), strict=True)), **extra}
            for box, extra in zip(np.asarray(zones.boxes), details, strict=True)
        ],
        "seconds": time.perf_counter() - start,
    }
    if not details:
        warnings.warn(InputWarning("no zone found (see the counts printed)"), stacklevel=2)
    print(json.dumps(report) if args.json else _listing(report, zones))
    return 0


def _check_arguments(args: argparse.Namespace, from_context: bool) -> None:
    """Refuses bad or ignored options and outputs that collide with inputs."""
    if from_context and not Path(args.source).is_file():
        raise InputError(f"--from must be tracks, gt or a context file; {args.source!r} is neither")
    if from_context:
        refuse_ignored(args, ["frames", "margin"], "does not apply to --from CTX.npz")
    if args.source != "tracks" and args.seed != 0:
        raise InputError("--seed seeds the tracker run of --from tracks")
    if not args.figure:
        refuse_ignored(args, ["video"], "needs --figure (its frame is drawn under the zones)")
    if args.video is not None and not Path(args.video).exists():
        raise InputError(f"--video {args.video}: not found")
    if not Path(args.sequence).is_dir():
        raise FileFormatError(args.sequence, None, "sequence folder not found")
    outputs = [output_file("--out", args.out)]
    if not from_context:
        outputs.append(output_file("--out", args.out, activity_file(args.out)))
    if args.figure:
        outputs.append(figure_output("--figure", args.figure))
    inputs = [
        *sequence_inputs(args.sequence),
        *(file_input(args.source, f"the context --from {args.source}") if from_context else []),
        *video_input(args.video, f"the frames --video {args.video}"),
    ]
    check_outputs(outputs, inputs)


def _counts(learned: LearnedZones) -> list[dict]:
    """Entries and exits of each zone."""
    return [
        {"entries": int(entries), "exits": int(exits)}
        for entries, exits in zip(learned.entries, learned.exits, strict=True)
    ]


def _clusters(learned: LearnedZones) -> dict:
    """How many points and clusters the zones came from, and which clusters were dropped."""
    entry = learned.endpoints.is_entry
    return {
        "points": {"starts": int(np.sum(entry)), "ends": int(np.sum(~entry))},
        "clusters": {
            "total": int(learned.cluster_sizes.size),
            "too_small": int(np.sum(learned.cluster_sizes < MIN_POINTS)),
            "interior": int(np.sum(learned.interior)),
        },
    }


def _context_zones(path: str, image_size: tuple[int, int]):
    """``(zones, details, summary)`` from the birth intensity of a context file (its training
    span from its metadata, None when it has none, e.g. a synthetic scene's true context)."""
    birth, _, metadata = load_context(path)
    boxes, shares = zones_from_intensity(birth, *image_size)
    details = [{"share": round(float(share), 4)} for share in shares]
    summary = {"frames": metadata.get("frames"), "min_share": MIN_SHARE}
    return SceneZones(boxes=boxes, activity=None, cell_size=None), details, summary


def _figure(args, info, zones: SceneZones, details, learned, frame: int) -> None:
    """Draws the zones over the span's first frame (when the sequence has frames)."""
    frames = find_frame_source(args.sequence, info.name, args.video)
    background = None
    if frames is not None:
        with VideoReader(frames) as reader:
            background = reader.read(frame)
    labels = [
        f"{k + 1}: {d['entries']} in, {d['exits']} out" if "entries" in d else f"{k + 1}"
        for k, d in enumerate(details)
    ]
    save_zones_figure(
        args.figure,
        zones,
        (info.im_width, info.im_height),
        labels,
        learned,
        background,
        title=f"{info.name}: entry/exit zones from {args.source} (frame {frame} shown)",
    )


def _listing(report: dict, zones: SceneZones) -> str:
    """The human-readable summary."""
    span = "" if report["frames"] is None else " frames {}:{},".format(*report["frames"])
    lines = [
        f"wrote {report['out']} ({len(report['zones'])} zones from {report['from']},{span} "
        f"{report['seconds']:.1f} s)"
    ]
    if "points" in report:
        points, clusters = report["points"], report["clusters"]
        lines.append(
            f"  {points['starts']} starts and {points['ends']} ends in {clusters['total']} "
            f"clusters: {clusters['too_small']} with fewer than {MIN_POINTS} points and "
            f"{clusters['interior']} interior dropped"
        )
    for k, zone in enumerate(report["zones"]):
        counts = (
            f"{zone['entries']} {_plural(zone['entries'], 'entry', 'entries')}, "
            f"{zone['exits']} {_plural(zone['exits'], 'exit', 'exits')}"
            if "entries" in zone
            else f"share {zone['share']:.3g} of the birth density"
        )
        lines.append(
            f"  zone {k + 1}: x {zone['x']:.0f}-{zone['x'] + zone['w']:.0f}, "
            f"y {zone['y']:.0f}-{zone['y'] + zone['h']:.0f} ({counts})"
        )
    if report["activity_mask"]:
        rows, columns = zones.activity.shape
        lines.append(
            f"  activity mask: {report['activity_mask']} ({columns}x{rows} cells of "
            f"{zones.cell_size:g} px, {100 * np.mean(zones.activity):.0f}% active)"
        )
    if report["figure"]:
        lines.append(f"  figure: {report['figure']}")
    return "\n".join(lines)


def _plural(count: int, one: str, many: str) -> str:
    return one if count == 1 else many
