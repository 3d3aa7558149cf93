"""``jaxtrack track``: run the particle PHD tracker on MOTChallenge sequences.

One sequence:  ``jaxtrack track SEQ_DIR --out RES.txt [--frames A:B] [--config FILE]
[--detections DET.txt|det|bs] [--context CTX.npz [--variant GM|A1..A6|UM]] [--figure PNG
[--figure-frame N]]``
All sequences: ``jaxtrack track --benchmark MOT_ROOT --out RES_DIR`` (one ``<SEQ>.txt`` each,
one compile per detection capacity; each sequence's result is the one it gets alone)

The detections are ``SEQ_DIR/det/det.txt`` unless ``--detections DET.txt`` gives others
(e.g. from ``jaxtrack detect`` on the sequence's frames).

The default configuration (uniform birth and clutter intensities, UM) is the same for every
sequence; image size and frame rate come from each ``seqinfo.ini``. ``--config FILE.json``
is a tracker configuration: a JSON object whose keys override the defaults of the chosen
tracker (``jaxtrack.filters.phd_tracker.PHDConfig``: ``num_particles``,
``births_per_detection``, ``extraction`` ("partition" or "gmm"), ``birth_rate`` (lambda_s,
births per frame), ``initial_rate`` (the first frame's uniform birth magnitude),
``clutter_rate`` (lambda_r), ``detection_prob``, ``survival_prob``, ``motion_noise_std``,
``measurement_noise_std``, ``output`` ("offline": confirmed tracks over their whole life,
gaps of up to ``max_gap`` frames interpolated; "online": the filter's frame-by-frame
output), ``max_gap`` and ``frame_capacity`` ("full", default, or "split": a frame whose
detections fit in half the run's detection slots runs on that half; faster on long runs and
sweeps, twice the compile, results equal up to float32 rounding) and ``confirmation``
("score": a track is output once one of its detections scores 0.97 or more; "evidence":
once the score log-odds of its detections, read through the context's detector
calibration, add up to logit(0.97), so that a target detected at lower scores is tracked
too; "auto", default: "evidence" with a context that carries a calibration, "score"
without) and ``retrodiction`` (0, default; N: the
offline output extends each confirmed track back by up to N frames onto the detections
before its first box, IoU >= 0.5 with its constant-velocity box) and ``smoothing``
("none", default, or "rts": the offline output's boxes re-estimated by the
Rauch-Tung-Striebel smoother under the tracker's own dynamics and noise; every tracker has
the key, the others smooth under the PHD tracker's default noise; the Fusion tracker's
default is "rts")). Unknown keys, wrong
types and out-of-range values are errors naming the key.

``--context CTX.npz`` (from ``jaxtrack learn-context``) uses learned intensities; ``--variant``
picks the parts (PHD-context Sec. V): GM (default) learned birth and clutter; A1 learned birth
+ uniform clutter; A2 uniform birth + learned clutter; A3 uniform both with the magnitudes
measured on the training span; A4 = A3 with learned birth; A5 = A3 with learned clutter; A6 =
GM (learn the context with ``--birth-from gt``); UM uniform intensities at the configuration's
magnitudes, reading only the context's detector score calibration (which the
``"evidence"`` and the default ``"auto"`` confirmation use; every variant reads it).

``--tracker kalman`` runs the baseline data-association tracker instead (a bank of
constant-velocity Kalman filters, gating, optimal assignment, M-of-N confirmation, no clutter
model; ``jaxtrack.filters.kalman``) with ``--preset default`` (Mahalanobis gate) or
``--preset sort`` (SORT's defaults: IoU gate 0.3, 3 hits to confirm, deleted after one missed
frame). Its configuration (``KalmanConfig``) takes ``preset``, ``output`` and ``max_gap``;
``--context`` and ``--figure`` are for the PHD tracker.

``--tracker cmt`` runs contextual mixture tracking (CMT, ``jaxtrack.filters.cmt``): one
local particle tracker per target (``max_components`` slots x ``particles_per_component``),
a contextual proposal driven by the blobs (the detections) and the scene's entry/exit zones,
and a contextual observation model weighting colour and shape features by how well they
tell nearby targets apart. ``--variant mtb|cpd|cmt`` picks the ablation's variant (plain
mixture tracker; + contextual proposal; + contextual observation model, the default).
``--zones zones.json`` (``jaxtrack learn-zones``) gives its entry/exit zones; without it they
are learned on the fly from the PHD tracker's trajectories on the tracked span (the run says
which, and ``.config.json`` records it). Its configuration (``CMTConfig``) takes
``variant``, ``max_components``, ``particles_per_component``,
``max_misses``, ``appearance_weight`` (3 since session 56; 1 before), ``group_area_ratio``
(group blobs, off by default),
``velocity_rate`` (0.1: a component keeps its long-run velocity while one blob covers it
and another; 0 gives the paper's tracker), ``reidentify_seconds`` (1; 0: off, the paper's
tracker; a new component takes back the identity of a confirmed one deleted that recently,
nearby and alike in colour), ``free_blob_frames`` (2; 0: off, the paper's tracker; a blob no
component owns that many frames in a row starts one whatever explains it),
``confirm_quantile`` (0.75; 1: off; a component is output once a blob scoring 0.97, or at
least this quantile of the scores seen so far, explains it), ``support`` (``box`` since
session 56: a component's support from the blobs' box likelihood alone, so
``appearance_weight`` above 1 does not delete followed targets; ``likelihood``, the paper's,
before), ``information_correction``
(0, the paper's; COM's mutual information lowered by this multiple of its chance level),
``exchange_margin`` (0.1 since session 61; negative: never, the paper's tracker; two
components that collided swap identities and appearance models when they separate if each
one's model explains the other's blob better by this many nats), ``output``, ``max_gap``.

``--tracker hierarchical`` runs the Hierarchical tracker (SPEC section 4,
``jaxtrack.filters.hierarchical``): a bank of constant-velocity Kalman filters whose tracks
are confirmed and removed by ``|S_k|^1/2`` (the low level), appearance trackers on the
confirmed tracks (Collins' 49 colour features ranked against the background model, mean
histograms, Bhattacharyya gates) that survive occlusions and take their target back when it
is seen again (re-association), and the event states (single, grouping, grouped, splitting,
entering, exiting) written beside the results as ``<RES>.events.csv`` (``frame,id,event``).
``--variant kalman|managed|full`` picks the Kalman bank alone, the low level, or both levels
(default). Its background model is the per-pixel median of 25 frames of the tracked span.
``--detections bs`` detects by background subtraction on the frames first (the paper's
blobs; ``jaxtrack detect``'s defaults), ``--detections det`` (default) uses ``det/det.txt``.
Its configuration (``HierarchicalConfig``) takes ``variant``, ``measurement`` ("box" or
"ellipse"), ``max_tracks``, ``max_trackers`` (64 each; a run whose tables were full warns),
``lost_seconds``, ``resume_seconds`` (a track
resuming after coasting this long is checked against its tracker's appearance; 0: never),
``noise`` ("auto": the low
level's noise measured on the tracked detections, except on the ``bs`` blobs, which keep the
a priori noise; "estimated"; "default"), ``min_score``, ``confirm_score`` (0.97: a low-level
track is confirmed only once it has held a detection scoring this; 0: the paper's rule),
``confirm_quantile`` (0.75: or, when lower, the 75th percentile of the detector's scores
seen so far; 1: off), ``exchange_margin`` (0.1: two trackers that collided swap their
tracks once apart when each one's appearance is nearer the other's box; negative: never),
``drift_check`` (0; 1: a tracker single again after colliding lets its track go when its
appearance gate refuses the track's box), ``fallback_appearance`` (1: a tracker never
single learns its appearance while colliding, used only to re-associate it when lost, and no
gap is interpolated across such a re-association; 0: learned only while single; 2: group
trackers learn one too),
``score_weight`` (1: the detections' score log-odds lower the association cost; 0: the
paper's cost), ``output``, ``max_gap``; the noise used
is printed and recorded in ``RES.config.json`` (``low_noise``).

``--tracker fusion`` runs the context-aware multi-tracker Fusion tracker (SPEC section 3,
``jaxtrack.filters.fusion``): a pool of trackers (``--pool``, any non-empty subset of
``detection`` (detections assigned to the targets), ``classifier`` (a correlation filter per
target) and ``predictor`` (local motion models), comma-separated in any order; default all
three; one member is that tracker alone) whose responses are fused per target (``--fusion
proposed``: weighted by confidence and accordance, the paper's eq. 6, default; ``--fusion
naive``: their mean), targets initiated and terminated by voting with thresholds per region,
occlusion reasoning and re-identification, and identity exchanges undone once two targets
that met are apart again. It first learns its scene on a training span
(``--train-frames A:B``, inside the tracked frames; default: the first half of the tracked
frames, ``train_fraction`` of its configuration): the entry/exit zones and activity mask
and the local motion models of the span's trajectories (its ground truth when the folder has
``gt/gt.txt``, else the PHD tracker's tracks), and the voting thresholds calibrated on the
detections' false positives against that ground truth (without one: the paper's). The
training span is scored with the rest: hold it out when evaluating (``jaxtrack eval
--frames``). With ``--benchmark`` each sequence trains on the first ``train_fraction`` of its
own frames (``--train-frames`` is refused). ``.config.json`` records the pool, the fusion
and how the context was learned (``training``). Its configuration (``FusionConfig``) takes
``pool``, ``fusion``, ``train_fraction``, ``share``, ``init_rule`` (``"share"``, the paper's
99 % rule, or ``"cost"``: th_init with the fewest false-target and late-start frames on the
training span), ``learning_rate``, ``appearance_weight`` (the detection member's signature
term, 60; 0: motion alone), ``exchange_margin`` (two targets that met swap identities once
apart when each one's signature is nearer the other's detection by this much, 0.2;
negative: never), ``max_targets``, ``output``, ``max_gap``, ``retrodiction`` (the offline
output extends each target backwards onto the detections before its first box, at the
detection member's support gate IoU 0.3; 0, off, by default), ``hypothesis_rows``
(``"chained"``, default: the hypotheses dropped just before a target's voted-in one, at its
walked-back place, are its rows too; ``"voted"``: its rows start with the one voted in),
``smoothing`` (``"rts"``, default since session 63, beyond the paper: the offline output's
boxes re-estimated by the Rauch-Tung-Striebel smoother; ``"none"``: the fused boxes as the
tracker estimated them online; the online output is never smoothed);
``--pool`` and ``--fusion`` override the file's.

A tracker that looks at the images (its registry entry ``uses_frames``, e.g. the appearance
trackers) gets each frame beside its detections, streamed from the sequence's frames:
``--video FILE`` (a video file or image folder), else ``SEQ_DIR/img1/``, else
``SEQ_DIR/<name>.mp4`` or ``.avi``; their frame count and size must be those of
``seqinfo.ini``. The frames are decoded a chunk ahead while the tracker runs, so a run holds
a few chunks of frames, never the whole video. For the other trackers ``--video`` is only
the image behind ``--figure``. PETS09-S2L1's frames are ``vtest.avi``:
``jaxtrack track mot15/PETS09-S2L1 --tracker NAME --video video/vtest.avi --out r.txt``.

The configuration used (the tracker included) is written beside the results as
``<RES>.config.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import jax
from tqdm import tqdm

from jaxtrack.commands.arguments import (
    DEFAULT_VARIANT,
    add_config,
    add_frames,
    add_fusion_arguments,
    add_json,
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
    benchmark_inputs,
    check_outputs,
    figure_output,
    file_input,
    output_file,
    output_folder,
    sequence_inputs,
    side_file,
    video_input,
)
from jaxtrack.configs import TrackerConfig
from jaxtrack.errors import InputError
from jaxtrack.filters.kalman import KALMAN_PRESETS
from jaxtrack.filters.registry import build_tracker, tracker_entry, writes_events
from jaxtrack.io import (
    load_sequence,
    parse_frame_span,
    read_seqinfo,
    write_results,
)
from jaxtrack.io.events import events_path, write_events
from jaxtrack.io.video import VideoReader, find_frame_source, open_sequence_frames
from jaxtrack.limits import FRAME_NUMBER
from jaxtrack.metrics.events import onset_summary
from jaxtrack.pipelines.frame_context import load_tracked_sequence, streamed_params
from jaxtrack.pipelines.stream import track_streamed_events
from jaxtrack.pipelines.tracking import (
    load_tracker_context,
    phd_frame_snapshot,
    track_sequences,
    tracker_description,
    warn_if_scores_ignored,
)
from jaxtrack.plot.tracks import phd_frame_figure

#: ``--detections`` keywords: the folder's own ``det/det.txt``, background subtraction.
DETECTION_KEYWORDS = ("det", "bs")


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "track",
        help="run a tracker (PHD by default) on a sequence folder or benchmark root",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("sequence", nargs="?", metavar="SEQ_DIR", help="MOTChallenge sequence")
    parser.add_argument("--benchmark", metavar="MOT_ROOT", help="folder of sequence folders")
    add_out(parser, "result file (RES.txt), or a folder with --benchmark")
    add_frames(parser)
    parser.add_argument(
        "--detections",
        metavar="DET.txt",
        help="detections to track instead of SEQ_DIR/det/det.txt (e.g. from jaxtrack detect), "
        "or 'det' (those, the default) or 'bs' (detect by background subtraction on the "
        "sequence's frames first; trackers that read frames)",
    )
    add_config(parser)
    add_seed(parser)
    add_variant_and_scene_arguments(parser, "see above")
    add_tracker(parser)
    parser.add_argument(
        "--preset",
        choices=list(KALMAN_PRESETS),
        help="preset of --tracker kalman (default: default)",
    )
    add_fusion_arguments(
        parser,
        "; refused with --benchmark, where each sequence trains on the first train_fraction of "
        "its own frames",
    )
    parser.add_argument(
        "--figure", metavar="PNG", help="also draw particles, estimates and tracks of one frame"
    )
    parser.add_argument(
        "--figure-frame",
        type=ranged(FRAME_NUMBER),
        metavar="N",
        help="MOT frame number of --figure (default: the middle of the span)",
    )
    parser.add_argument(
        "--video",
        metavar="FILE",
        help="the sequence's frames (video file or image folder) for a tracker that uses "
        "frames, or behind --figure (default: SEQ_DIR/img1/, else SEQ_DIR/<name>.mp4/.avi)",
    )
    add_quiet(parser)
    add_json(parser)
    parser.set_defaults(func=run)


def track_sequence(
    sequence_dir,
    out_path,
    config: TrackerConfig,
    seed: int = 0,
    frames=None,
    context_path: str | None = None,
    variant: str = "GM",
    detections: str | None = None,
    video: str | None = None,
    zones: str | None = None,
    train_frames: str | None = None,
) -> tuple[int, int]:
    """Tracks one sequence folder and writes MOTChallenge results.

    Args:
        sequence_dir: the sequence folder.
        out_path: the result file (``<RES>.config.json`` is written beside it).
        config: the tracker's configuration.
        seed: PRNG seed.
        frames: 1-based inclusive span (``--frames``), or None for every frame.
        context_path: a learned context (``--context``), or None.
        variant: the context's parts used.
        detections: a detections file used instead of ``det/det.txt``, or None.
        video: for a tracker that uses frames, its frames instead of those found in the
            folder (:func:`~jaxtrack.io.video.open_sequence_frames`).
        zones: for a tracker that takes zones, the zones file (default: learned on the fly,
            :func:`~jaxtrack.pipelines.zones.tracker_zones`; what was used is printed and
            written to ``.config.json``).
        train_frames: for a tracker that learns from a training span, that span (``"A:B"``
            inside ``frames``; default: the first half of ``frames``,
            :func:`~jaxtrack.pipelines.fusion_context.training_frames`).

    Returns:
        The number of result rows (boxes) and of frames tracked.
    """
    entry = tracker_entry(config.tracker)
    used = {}
    if not entry.uses_frames:
        seq = load_tracked_sequence(sequence_dir, frames, detections)
        _, params = build_tracker(config, seq.info, load_tracker_context(context_path), variant)
        (rows,) = track_sequences([seq], config, seed, [params])
        events = None
    else:
        info = read_seqinfo(Path(sequence_dir) / "seqinfo.ini")
        tracked = parse_frame_span(frames, info.seq_length)
        check_train_frames(train_frames, tracked, info.seq_length)
        with open_sequence_frames(sequence_dir, info, video) as reader:
            seq = load_tracked_sequence(sequence_dir, frames, detections, reader)
            params, used = streamed_params(
                config, seq, reader, seed, zones, train_frames, blobs=detections == "bs"
            )
            for value in used.values():
                print(f"{seq.info.name}: {value}", file=sys.stderr)
            warn_if_scores_ignored(seq, params, config)
            rows, events = track_streamed_events(seq, reader, config, seed, params)
        used["video"] = str(reader.path)
    if detections is not None:
        used["detections"] = str(detections)
    if not entry.takes_context:
        variant = None
    elif context_path is None:
        variant = "UM"
    _write(out_path, rows, config, seed, seq, context_path, variant, used)
    if events is not None:
        written = write_events(events_path(out_path), events)
        print(f"  events: {written} ({onset_summary(events)})", file=sys.stderr)
    return len(rows.frames), seq.num_frames


def run(args) -> int:
    if (args.sequence is None) == (args.benchmark is None):
        raise InputError("give either SEQ_DIR or --benchmark MOT_ROOT (not both)")
    if args.benchmark is not None:
        options = ["frames", "detections", "context", "figure", "figure_frame", "video"]
        options += ["zones", "train_frames"]
        if args.variant not in tracker_variant_names():  # picks the tracker, not a context
            options.append("variant")
        refuse_ignored(args, options, "applies to one sequence, not to --benchmark")
    if args.figure is None:
        refuse_ignored(args, ["figure_frame"], "needs --figure (it is only read for it)")
        if not tracker_entry(args.tracker).uses_frames:
            refuse_ignored(
                args, ["video"], f"needs --figure (the {args.tracker} tracker reads no frames)"
            )
    config = _config(args)
    variant = DEFAULT_VARIANT
    if not tracker_entry(config.tracker).variants:  # --variant is the context's
        variant = context_variant(args) or DEFAULT_VARIANT
    if args.sequence is None:
        return _benchmark(args, config)
    check_outputs(
        [
            output_file("--out", args.out),
            side_file("--out", args.out, ".config.json"),
            *([figure_output("--figure", args.figure)] if args.figure else []),
            *_events_output(config, args.out),
        ],
        [
            *sequence_inputs(args.sequence),
            *file_input(args.config, f"the tracker configuration --config {args.config}"),
            *_detections_input(args.detections),
            *file_input(args.context, f"the context --context {args.context}"),
            *video_input(args.video, f"the frames --video {args.video}"),
            *file_input(args.zones, f"the zones --zones {args.zones}"),
        ],
    )
    start = time.perf_counter()
    rows, frames = track_sequence(
        args.sequence,
        args.out,
        config,
        args.seed,
        args.frames,
        args.context,
        variant,
        args.detections,
        args.video,
        args.zones,
        args.train_frames,
    )
    seconds = time.perf_counter() - start
    summary = {"out": str(args.out), "rows": rows, "frames": frames, "seconds": seconds}
    if not args.json:
        print(f"wrote {args.out} ({rows} boxes, {seconds:.1f} s)")
    if args.figure:
        path, frame = _figure(args, config, variant)
        summary.update(figure=str(path), figure_frame=frame)
        if not args.json:
            print(f"wrote {path} (frame {frame})")
    if args.json:
        print(json.dumps(summary))
    return 0


def _config(args) -> TrackerConfig:
    """The tracker configuration of the options; refuses options the tracker does not take."""
    config = load_config(args.config, args.tracker)
    entry = tracker_entry(args.tracker)
    if not entry.takes_zones:
        refuse_ignored(args, ["zones"], f"applies to --tracker cmt, not to {args.tracker}")
    config = apply_tracker_variant(args, config)
    config = apply_fusion_arguments(args, config)
    if args.preset is not None:
        if args.tracker != "kalman":
            raise InputError("--preset applies to --tracker kalman")
        config = config.replace(preset=args.preset)
    if not tracker_entry(args.tracker).takes_context:
        for option in ("context", "figure"):
            if getattr(args, option) is not None:
                raise InputError(
                    f"--{option} applies to the PHD tracker, not to --tracker {args.tracker}"
                )
    return config


def _benchmark(args, config: TrackerConfig) -> int:
    root = Path(args.benchmark)
    folders = (
        sorted(p for p in root.iterdir() if (p / "seqinfo.ini").is_file()) if root.is_dir() else []
    )
    if not folders:
        raise InputError(f"{root}: no sequence folders (with seqinfo.ini) found")
    out = Path(args.out)
    suffixes = (".txt", ".config.json")
    if writes_events(config):
        suffixes += (".events.csv",)
    names = [f"{folder.name}{suffix}" for folder in folders for suffix in suffixes]
    check_outputs(
        output_folder("--out", args.out, names),
        [
            *benchmark_inputs(root, folders),
            *file_input(args.config, f"the tracker configuration --config {args.config}"),
        ],
    )
    out.mkdir(parents=True, exist_ok=True)
    sequences = [load_sequence(folder) for folder in folders]
    start = time.perf_counter()
    if tracker_entry(config.tracker).uses_frames:
        results, used = _track_streamed_all(sequences, config, args.seed, not args.quiet)
    else:
        results = track_sequences(sequences, config, args.seed, progress=not args.quiet)
        used = [{} for _ in sequences]
    variant = "UM" if tracker_entry(config.tracker).takes_context else None
    for seq, rows, seq_used in zip(sequences, results, used, strict=True):
        if "events" in seq_used:
            write_events(out / f"{seq.path.name}.events.csv", seq_used.pop("events"))
        _write(
            out / f"{seq.path.name}.txt",
            rows,
            config,
            args.seed,
            seq,
            None,
            variant,
            seq_used,
        )
    frames = sum(seq.num_frames for seq in sequences)
    seconds = time.perf_counter() - start
    if args.json:
        rows = sum(len(result.frames) for result in results)
        summary = {"out": str(out), "sequences": len(sequences), "rows": rows}
        print(json.dumps({**summary, "frames": frames, "seconds": seconds}))
    else:
        print(
            f"wrote {len(sequences)} result files to {out} "
            f"({frames} frames, {seconds:.1f} s compiles included)"
        )
    return 0


def _events_output(config: TrackerConfig, out: str) -> list:
    """``RES.events.csv`` beside ``--out`` for a tracker that writes events."""
    if not writes_events(config):
        return []
    return [side_file("--out", out, ".events.csv")]


def _detections_input(detections: str | None) -> list:
    """The ``--detections`` file to check (none for the keywords ``det`` and ``bs``)."""
    if detections in DETECTION_KEYWORDS:
        return []
    return file_input(detections, f"the detections --detections {detections}")


def _track_streamed_all(sequences, config: TrackerConfig, seed: int, progress: bool):
    """Each sequence with a tracker that uses frames (found in its folder, all checked before
    the first is tracked; zones learned on the fly for a tracker that takes them, the
    background image for one that takes it); the results and, per sequence, what was used."""
    readers = []
    try:
        for seq in sequences:
            readers.append(open_sequence_frames(seq.path, seq.info))
        results, used = [], []
        for seq, reader in tqdm(
            list(zip(sequences, readers, strict=True)),
            desc="tracking",
            unit="seq",
            disable=not progress,
        ):
            params, seq_used = streamed_params(config, seq, reader, seed)
            seq_used["video"] = str(reader.path)
            rows, events = track_streamed_events(seq, reader, config, seed, params)
            if events is not None:
                seq_used["events"] = events
            results.append(rows)
            used.append(seq_used)
    finally:
        for reader in readers:
            reader.close()
    return results, used


def _write(out_path, rows, config, seed, seq, context_path, variant, inputs) -> None:
    """Writes the results and ``<RES>.config.json`` (``inputs``: the detections and frames
    used, when not the folder's ``det/det.txt`` alone)."""
    write_results(out_path, rows.frames, rows.ids, rows.boxes, rows.confs)
    used = {**tracker_description(config), "seed": seed}
    used["sequence"] = str(seq.path)
    used.update(inputs)
    if variant is not None:
        used["variant"] = variant
    used["frames"] = [seq.first_frame, seq.last_frame]
    if context_path is not None:
        used["context"] = str(context_path)
    Path(f"{Path(out_path).with_suffix('')}.config.json").write_text(json.dumps(used, indent=2))


def _figure(args, config: TrackerConfig, variant: str) -> tuple[Path, int]:
    """Draws ``--figure`` (PHD-context Fig. 3) for the span tracked; its path and frame."""
    seq = load_tracked_sequence(args.sequence, args.frames, args.detections)
    frame = args.figure_frame or (seq.first_frame + seq.last_frame) // 2
    if not seq.first_frame <= frame <= seq.last_frame:
        raise InputError(
            f"--figure-frame {frame} is outside the frames tracked "
            f"({seq.first_frame}..{seq.last_frame})"
        )
    source = find_frame_source(args.sequence, seq.info.name, args.video)
    image = None
    if source is not None:
        with VideoReader(source) as reader:
            image = reader.read(frame)
    filt, params = build_tracker(config, seq.info, load_tracker_context(args.context), variant)
    snapshot = phd_frame_snapshot(
        filt, jax.random.PRNGKey(args.seed), params, seq.detections, frame - seq.first_frame
    )
    path = phd_frame_figure(
        snapshot,
        args.figure,
        image=image,
        first_frame=seq.first_frame,
        image_size=(seq.info.im_width, seq.info.im_height),
    )
    return path, frame
