"""``jaxtrack inspect SEQ_DIR``: what a MOTChallenge sequence folder holds.

Reports frames, image size, where the frames are (``img1/`` or ``NAME.mp4`` / ``NAME.avi`` in
the folder, with the video's frame count, size and rate), detection counts (total, per frame
min/mean/max), ground-truth boxes and identities, and the detector's precision and recall
against the ground truth at IoU >= 0.5 (optimal one-to-one assignment per frame; gt rows with
``conf == 0`` excluded).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from jaxtrack.commands.arguments import IOU, add_frames, add_json, ranged, refuse_ignored
from jaxtrack.io import load_sequence
from jaxtrack.io.video import VideoReader, find_frame_source
from jaxtrack.metrics.detection import detection_precision_recall

#: IoU threshold of a match (default of --iou).
DEFAULT_IOU = 0.5


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "inspect",
        help="summarise a MOTChallenge sequence folder (counts, detector precision/recall)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("sequence", metavar="SEQ_DIR", help="folder with seqinfo.ini, det/, gt/")
    add_frames(parser)
    parser.add_argument(
        "--iou",
        type=ranged(IOU),
        help="IoU threshold for a detection to match the ground truth (default 0.5)",
    )
    add_json(parser)
    parser.set_defaults(func=run)


def summarise(sequence_dir, frames=None, iou_threshold: float = DEFAULT_IOU) -> dict:
    """Statistics of a sequence folder, as printed by ``jaxtrack inspect --json``."""
    seq = load_sequence(sequence_dir, frames=frames)
    counts = np.bincount(seq.det_table.frames - seq.first_frame, minlength=seq.num_frames)
    summary = {
        "name": seq.info.name,
        "frames": seq.num_frames,
        "first_frame": seq.first_frame,
        "last_frame": seq.last_frame,
        "image_width": seq.info.im_width,
        "image_height": seq.info.im_height,
        "frame_rate": seq.info.frame_rate,
        "frames_source": frames_source(seq.path, seq.info.name),
        "detections": len(seq.det_table),
        "detections_per_frame": {
            "min": int(counts.min()),
            "mean": float(counts.mean()),
            "max": int(counts.max()),
        },
        "gt_boxes": None,
        "gt_ignored_boxes": None,
        "gt_ids": None,
        "precision": None,
        "recall": None,
    }
    if seq.gt_table is not None:
        gt = seq.gt_table
        precision, recall = detection_precision_recall(
            seq.det_table, gt, (seq.first_frame, seq.last_frame), iou_threshold
        )
        summary.update(
            gt_boxes=len(gt),
            gt_ignored_boxes=int(gt.ignored.sum()),
            gt_ids=len(np.unique(gt.ids)),
            precision=precision,
            recall=recall,
        )
    return summary


def frames_source(sequence_dir, name: str) -> dict | None:
    """The sequence's frames (``img1/``, else ``NAME.mp4`` / ``NAME.avi``) and what they hold.

    Returns:
        ``{"path", "frames", "width", "height", "fps"}`` (fps None when unknown), or None
        when the folder has no frames.

    Raises:
        FileFormatError: the video or image folder is unreadable.
    """
    source = find_frame_source(sequence_dir, name)
    if source is None:
        return None
    with VideoReader(source) as reader:
        return {
            "path": str(source),
            "frames": reader.num_frames,
            "width": reader.width,
            "height": reader.height,
            "fps": reader.fps,
        }


def run(args) -> int:
    if not (Path(args.sequence) / "gt" / "gt.txt").exists():
        refuse_ignored(args, ["iou"], "needs ground truth, and SEQ_DIR has no gt/gt.txt")
    iou = DEFAULT_IOU if args.iou is None else args.iou
    summary = summarise(args.sequence, args.frames, iou)
    if args.json:
        print(json.dumps(summary))
        return 0
    per_frame = summary["detections_per_frame"]
    lines = [
        f"sequence      {summary['name']}  ({args.sequence})",
        f"frames        {summary['frames']}  ({summary['first_frame']}..{summary['last_frame']})",
        f"image         {summary['image_width']} x {summary['image_height']}"
        f"  at {summary['frame_rate'] or '?'} fps",
        _source_line(summary["frames_source"]),
        f"detections    {summary['detections']}  per frame min {per_frame['min']}"
        f" / mean {per_frame['mean']:.2f} / max {per_frame['max']}",
    ]
    if summary["gt_boxes"] is None:
        lines.append("ground truth  none (no gt/gt.txt)")
    else:
        lines += [
            f"ground truth  {summary['gt_boxes']} boxes ({summary['gt_ignored_boxes']} ignored),"
            f" {summary['gt_ids']} ids",
            f"detector      precision {summary['precision']:.4f}  recall {summary['recall']:.4f}"
            f"  (IoU >= {iou}, one-to-one per frame, ignored gt excluded)",
        ]
    print("\n".join(lines))
    return 0


def _source_line(source: dict | None) -> str:
    if source is None:
        return "frames from   none (no img1/ or NAME.mp4/.avi in the folder)"
    return (
        f"frames from   {source['path']}  ({source['frames']} frames, {source['width']} x "
        f"{source['height']} at {source['fps'] or '?'} fps)"
    )
