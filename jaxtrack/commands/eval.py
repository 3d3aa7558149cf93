"""``jaxtrack eval``: score tracker output against MOTChallenge ground truth.

One sequence:

  jaxtrack eval SEQ_DIR RES.txt              gt and seqinfo.ini from the sequence folder
  jaxtrack eval --gt GT.txt --res RES.txt [--seqinfo seqinfo.ini]

A benchmark (one result file <SEQ>.txt per sequence folder of MOT_ROOT), printed as a table
with one row per sequence and the combined row:

  jaxtrack eval --benchmark MOT_ROOT --results RES_DIR

Metrics (numbers identical to TrackEval 1.3.0 where it has them): CLEAR MOT (MOTA, MOTP as
mean IoU, FP, FN, IDSW, Frag, MT/PT/ML, Recall, Precision), identity (IDF1, IDP, IDR), HOTA
(DetA, AssA, LocA; means over IoU thresholds 0.05..0.95), VACE / CLEAR-2007 (MODA, MODP
pooled; VACE_MODA, VACE_MODP averaged over frames; VACE_MOTA with a log10 identity-switch
penalty), set distances (OSPA, GOSPA with alpha = 2; frame averages) and CMT's error rates
(below). Ground truth follows TrackEval's MOT15 conventions: gt rows with conf 0 are
dropped, tracker boxes on them still count; --distractors applies the MOT16/17 rules
instead. --frames A:B scores only that span (gt and results are cut to it). --json prints
one JSON object with the scores as fractions (or counts). Bad files exit with status 2 and
name the file and line.

CMT error rates (Cui et al. Sec. VII-B), on the CLEAR matching (per frame, one-to-one
Hungarian assignment among pairs with IoU >= 0.5, keeping the previous correspondences
first); F = frames of the span:
  OE  falsely tracked frames / F: frames with a missed gt target, an identity switch
      (a target matched to another track than the one it was last matched to) or an
      unmatched tracker box
  SE  frames with at least one identity switch / F
  DE  (entering targets not matched within --delay-tolerance frames of their first frame
      + exiting targets whose last track is still an unmatched box in each of the
      --delay-tolerance + 1 frames after their last frame) / (entering + exiting targets);
      a target enters when its first frame is after the span's first, exits when its
      last frame is before the span's last

--switches (one sequence) lists every identity switch with its kind, from what its two
tracks did (jaxtrack.metrics.switches): exchange (the tracks traded objects), drift (the old
track left for another object), takeover (the new track came from another object), lost
(the old track ended; what re-identification fixes), replaced (the old track stayed on
nothing). The kinds add up to IDSW.

--errors sorts every miss and false positive by what the detections the
tracker was given offered in that frame (jaxtrack.metrics.errors; "overlaps" = IoU >= 0.3,
"well detected" = the detections' one-to-one mapping at the match threshold gives the
object a box). Misses: not_detected (no detection overlaps the object), detection_misplaced
(one overlaps it, none well), output_misplaced (well detected, and an unmatched output box
overlaps it), dropped (well detected, no output box there). False positives: misplaced (on
a missed object), duplicate (on a matched object), clutter (on a detection mapped to no
object), phantom (on nothing). The detections are SEQ_DIR/det/det.txt unless --det FILE;
with --benchmark, each sequence's det/det.txt, one row per sequence and the summed row.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from jaxtrack.commands.arguments import (
    DISTANCE,
    FRAMES_OR_NONE,
    IOU,
    OSPA_ORDER,
    add_frames,
    add_json,
    ranged,
    refuse_ignored,
)
from jaxtrack.errors import FileFormatError, InputError
from jaxtrack.io import parse_frame_span, read_mot_file, read_seqinfo
from jaxtrack.metrics import SUMMARY_KEYS, EvalConfig, combine_sequences, evaluate_sequence
from jaxtrack.metrics.cmt import ADDITIVE_FIELDS as CMT_COUNTS
from jaxtrack.metrics.cmt import DEFAULT_TOLERANCE
from jaxtrack.metrics.errors import ErrorTable, classify_errors
from jaxtrack.metrics.evaluate import switch_table
from jaxtrack.metrics.switches import SCORE_NAMES as SWITCH_SCORE_NAMES
from jaxtrack.metrics.switches import SwitchTable

#: Minimum IoU of a match (default of --iou-threshold).
DEFAULT_IOU_THRESHOLD = 0.5
#: Columns of the benchmark table (ratios printed in %).
TABLE_COLUMNS = (
    "HOTA",
    "DetA",
    "AssA",
    "LocA",
    "MOTA",
    "MOTP",
    "IDF1",
    "MODA",
    "MODP",
    "FP",
    "FN",
    "IDSW",
    "Frag",
    "MT",
    "PT",
    "ML",
    "GT_IDs",
    "OSPA",
    "OE",
    "DE",
    "SE",
)
#: Scores printed as plain numbers rather than percentages.
NOT_PERCENT = (
    "FP",
    "FN",
    "IDSW",
    "Frag",
    "MT",
    "PT",
    "ML",
    "GT_IDs",
    "TP",
    "IDTP",
    "IDFN",
    "IDFP",
    *CMT_COUNTS,
    *SWITCH_SCORE_NAMES.values(),
)


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "eval",
        help="score tracker output against ground truth (CLEAR, VACE, IDF1, HOTA, OSPA, CMT)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "inputs",
        nargs="*",
        metavar="SEQ_DIR RES.txt",
        help="a sequence folder (seqinfo.ini, gt/gt.txt) and a result file",
    )
    parser.add_argument("--gt", metavar="GT.txt", help="ground-truth file (with --res)")
    parser.add_argument("--res", metavar="RES.txt", help="tracker result file (with --gt)")
    parser.add_argument(
        "--seqinfo",
        metavar="INI",
        help="seqinfo.ini for --gt/--res: frames must lie in 1..seqLength, and set distances "
        "average over those frames (default: up to the last frame present)",
    )
    parser.add_argument(
        "--benchmark", metavar="MOT_ROOT", help="folder of sequence folders (with --results)"
    )
    parser.add_argument(
        "--results", metavar="RES_DIR", help="folder with one <SEQ>.txt per sequence"
    )
    add_frames(parser)
    add_json(parser)
    parser.add_argument(
        "--iou-threshold",
        type=ranged(IOU),
        metavar="T",
        help="minimum IoU of a match for CLEAR, identity and MODA/MODP (default 0.5)",
    )
    parser.add_argument(
        "--centre-threshold",
        type=ranged(DISTANCE),
        metavar="PIXELS",
        help="match by box-centre distance instead of IoU: boxes match when their centres are "
        "at most PIXELS apart (similarity 1 - d / (2 PIXELS); for point-like data)",
    )
    parser.add_argument(
        "--distractors",
        action="store_true",
        help="MOT16/17 rules: drop tracker boxes matched to distractor-class gt, then keep only "
        "pedestrian gt (class column 8) that is not zero-marked",
    )
    parser.add_argument(
        "--ospa-c",
        type=ranged(DISTANCE),
        default=1.0,
        metavar="C",
        help="OSPA/GOSPA cut-off, in units of --ospa-distance (default 1)",
    )
    parser.add_argument(
        "--ospa-p",
        type=ranged(OSPA_ORDER),
        default=1.0,
        metavar="P",
        help="OSPA/GOSPA order (default 1)",
    )
    parser.add_argument(
        "--ospa-distance",
        choices=("iou", "centre"),
        default="iou",
        help="OSPA/GOSPA base distance: 1 - IoU (default) or box-centre distance in pixels",
    )
    parser.add_argument(
        "--delay-tolerance",
        type=ranged(FRAMES_OR_NONE),
        default=DEFAULT_TOLERANCE,
        metavar="N",
        help=f"CMT's DE: frames allowed to pick up an entering target or release an exiting "
        f"one (default {DEFAULT_TOLERANCE}; the paper states none)",
    )
    parser.add_argument(
        "--switches",
        action="store_true",
        help="also list every identity switch and its kind (exchange, drift, takeover, lost, "
        "replaced; one sequence only); with --json, under the key 'switches'",
    )
    parser.add_argument(
        "--errors",
        action="store_true",
        help="also sort the misses and false positives by what the detections offered "
        "(not_detected, detection_misplaced, output_misplaced, dropped; misplaced, duplicate, "
        "clutter, phantom); with --benchmark, per sequence and summed; with --json, under the "
        "key 'errors'",
    )
    parser.add_argument(
        "--det",
        metavar="DET.txt",
        help="the detections the tracker was given, for --errors (default SEQ_DIR/det/det.txt)",
    )
    parser.set_defaults(func=run)


def run(args) -> int:
    if args.centre_threshold is not None:
        reason = "is unused with --centre-threshold (boxes match by centre distance)"
        refuse_ignored(args, ["iou_threshold"], reason)
    config = EvalConfig(
        iou_threshold=DEFAULT_IOU_THRESHOLD if args.iou_threshold is None else args.iou_threshold,
        centre_threshold=args.centre_threshold,
        distractors=args.distractors,
        ospa_cutoff=args.ospa_c,
        ospa_order=args.ospa_p,
        ospa_distance=args.ospa_distance,
        delay_tolerance=args.delay_tolerance,
    )
    if args.benchmark or args.results:
        refuse_ignored(args, ["switches"], "lists one sequence's switches: give SEQ_DIR RES.txt")
        refuse_ignored(args, ["det"], "names one sequence's detections; a benchmark reads "
                       "each sequence's det/det.txt")  # fmt: skip
        return _run_benchmark(args, config)
    if args.det and not args.errors:
        raise InputError("--det gives the detections for --errors; add --errors")
    gt_path, res_path, seqinfo_path = _single_inputs(args)
    info = read_seqinfo(seqinfo_path) if seqinfo_path else None
    gt = read_mot_file(gt_path, "gt", info=info)
    result = read_mot_file(res_path, "res", info=info)
    last = (
        info.seq_length
        if info
        else max(int(np.max(gt.frames, initial=1)), int(np.max(result.frames, initial=1)))
    )
    first, last = parse_frame_span(args.frames, last)
    if args.frames is not None:
        gt, result = gt.frame_span(first, last), result.frame_span(first, last)
    scores = evaluate_sequence(gt, result, (first, last), config).scores()
    switches = switch_table(gt, result, (first, last), config) if args.switches else None
    errors = None
    if args.errors:
        errors = _error_table(args, gt, result, info, (first, last), config)
    if args.json:
        record = {key: scores[key] for key in SUMMARY_KEYS}
        if switches is not None:
            record["switches"] = {"counts": switches.counts(), "rows": switches.rows()}
        if errors is not None:
            record["errors"] = errors.counts()
        print(json.dumps(record))
    else:
        print(f"ground truth  {gt_path}\nresults       {res_path}\nframes        {first}..{last}")
        print(_score_listing(scores))
        if switches is not None:
            print(_switch_listing(switches))
        if errors is not None:
            print(_error_listing(errors))
    return 0


def _error_table(args, gt, result, info, span, config) -> ErrorTable:
    """The classified misses and false positives, with the detections of ``--det`` or of the
    sequence folder."""
    if args.det:
        det_path, missing = Path(args.det), "detection file not found (--det)"
    elif args.inputs:
        det_path, missing = Path(args.inputs[0]) / "det" / "det.txt", "detection file not found"
    else:
        raise InputError("--errors with --gt/--res needs --det DET.txt (the tracker's detections)")
    return _classified(gt, result, det_path, missing, info, span, config)


def _classified(gt, result, det_path, missing, info, span, config) -> ErrorTable:
    """:func:`classify_errors` against the detections of ``det_path`` (cut to ``span``; an
    error with ``missing`` when the file is not there) with the evaluation's settings."""
    if not det_path.is_file():
        raise FileFormatError(det_path, None, missing)
    detections = read_mot_file(det_path, "det", info=info).frame_span(*span)
    return classify_errors(
        gt,
        result,
        detections,
        span,
        threshold=config.match_threshold,
        centre_threshold=config.centre_threshold,
        distractors=config.distractors,
    )


def _error_listing(errors: ErrorTable) -> str:
    """The count of each kind of miss and false positive, with its share."""
    lines = []
    for name, counts in errors.counts().items():
        total = sum(counts.values())
        lines.append(f"{name} by what the detections offered ({total}):")
        lines += [
            f"  {kind:<22}{n:>8}  {100 * n / max(total, 1):5.1f} %" for kind, n in counts.items()
        ]
    return "\n".join(lines)


def _switch_listing(switches: SwitchTable) -> str:
    """The switches, one per line in frame order, then the count of each kind."""
    lines = [f"identity switches ({len(switches.frame)}):"]
    rows = sorted(switches.rows(), key=lambda row: (row["frame"], row["gt_id"]))
    lines += [
        f"  frame {r['frame']:>6}  gt {r['gt_id']:>5}  track {r['from_id']} -> {r['to_id']}  "
        f"after {r['gap']} frame(s)  {r['kind']}"
        for r in rows
    ]
    lines.append("  " + ", ".join(f"{kind} {n}" for kind, n in switches.counts().items()))
    return "\n".join(lines)


def _single_inputs(args):
    if args.gt or args.res:
        if args.inputs:
            raise InputError("give either SEQ_DIR RES.txt or --gt/--res, not both")
        if not (args.gt and args.res):
            raise InputError("--gt and --res go together")
        return Path(args.gt), Path(args.res), Path(args.seqinfo) if args.seqinfo else None
    if len(args.inputs) != 2:
        raise InputError(
            "expected SEQ_DIR RES.txt, --gt GT.txt --res RES.txt, or "
            "--benchmark MOT_ROOT --results RES_DIR (see --help)"
        )
    if args.seqinfo:
        raise InputError("--seqinfo goes with --gt/--res; SEQ_DIR has its own seqinfo.ini")
    sequence = Path(args.inputs[0])
    if not sequence.is_dir():
        raise FileFormatError(sequence, None, "sequence folder not found")
    return sequence / "gt" / "gt.txt", Path(args.inputs[1]), sequence / "seqinfo.ini"


def _run_benchmark(args, config) -> int:
    if not (args.benchmark and args.results):
        raise InputError("--benchmark and --results go together")
    if args.inputs or args.gt or args.res or args.seqinfo or args.frames:
        raise InputError("--benchmark takes no SEQ_DIR, --gt, --res, --seqinfo or --frames")
    root, results_dir = Path(args.benchmark), Path(args.results)
    if not root.is_dir():
        raise FileFormatError(root, None, "benchmark folder not found")
    if not results_dir.is_dir():
        raise FileFormatError(results_dir, None, "results folder not found")
    sequences = sorted(p.name for p in root.iterdir() if (p / "seqinfo.ini").is_file())
    if not sequences:
        raise FileFormatError(root, None, "no sequence folders (with seqinfo.ini) inside")
    evaluations, errors = {}, {}
    for name in sequences:
        info = read_seqinfo(root / name / "seqinfo.ini")
        result_path = results_dir / f"{name}.txt"
        if not result_path.is_file():
            raise FileFormatError(result_path, None, f"no result file for sequence {name}")
        gt = read_mot_file(root / name / "gt" / "gt.txt", "gt", info=info)
        result = read_mot_file(result_path, "res", info=info)
        span = (1, info.seq_length)
        evaluations[name] = evaluate_sequence(gt, result, span, config)
        if args.errors:
            det_path = root / name / "det" / "det.txt"
            missing = f"no detections for sequence {name} (--errors)"
            errors[name] = _classified(gt, result, det_path, missing, info, span, config).counts()
    rows = {name: evaluation.scores() for name, evaluation in evaluations.items()}
    rows["COMBINED"] = combine_sequences(evaluations.values()).scores()
    if errors:
        errors["COMBINED"] = {
            side: {kind: sum(e[side][kind] for e in errors.values()) for kind in counts}
            for side, counts in next(iter(errors.values())).items()
        }
    if args.json:
        summary = {name: {key: row[key] for key in SUMMARY_KEYS} for name, row in rows.items()}
        combined = summary.pop("COMBINED")
        report = {"sequences": summary, "combined": combined}
        if errors:
            report["errors"] = errors
        print(json.dumps(report))
    else:
        print(_table(rows))
        if errors:
            print(_error_columns(errors))
    return 0


def _error_columns(errors: dict) -> str:
    """Misses and false positives by kind, one row per sequence and the combined row."""
    columns = [(side, kind) for side, counts in errors["COMBINED"].items() for kind in counts]
    width = max(len("Sequence"), *(len(name) for name in errors)) + 2
    cells = [f"{side} {kind}" for side, kind in columns]
    lines = ["", "Sequence".ljust(width) + "".join(c.rjust(max(len(c) + 2, 9)) for c in cells)]
    for name, counts in errors.items():
        values = [str(counts[side][kind]) for side, kind in columns]
        lines.append(
            name.ljust(width)
            + "".join(v.rjust(max(len(c) + 2, 9)) for v, c in zip(values, cells, strict=True))
        )
    lines.append("(misses and false positives by what the detections offered: --help)")
    return "\n".join(lines)


def _format(key: str, value) -> str:
    if key in NOT_PERCENT:
        return str(int(value))
    if key.startswith(("OSPA", "GOSPA")):
        return f"{value:.4f}"
    return f"{100 * value:.3f}"


def _table(rows: dict) -> str:
    width = max(len("Sequence"), *(len(name) for name in rows)) + 2
    header = "Sequence".ljust(width) + "".join(c.rjust(9) for c in TABLE_COLUMNS)
    lines = [header]
    for name, row in rows.items():
        cells = "".join(_format(c, row[c]).rjust(9) for c in TABLE_COLUMNS)
        lines.append(name.ljust(width) + cells)
    lines.append("(ratios in %; OSPA as a fraction; --json for every score)")
    return "\n".join(lines)


def _score_listing(scores: dict) -> str:
    lines = []
    for key, value in scores.items():
        unit = "" if key in NOT_PERCENT or key.startswith(("OSPA", "GOSPA")) else " %"
        lines.append(f"{key:<20}{_format(key, value):>12}{unit}")
    return "\n".join(lines)
