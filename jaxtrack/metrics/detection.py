"""Detector quality: precision and recall of detections against ground truth."""

from __future__ import annotations

import numpy as np

from jaxtrack.metrics.preprocess import prepare_sequence
from jaxtrack.metrics.vace import detection_mapping
from jaxtrack.types import MotTable


def detection_precision_recall(
    det_table: MotTable,
    gt_table: MotTable,
    frames: tuple[int, int],
    iou_threshold: float = 0.5,
) -> tuple[float, float]:
    """Precision = matches / detections, recall = matches / kept gt boxes.

    Matches are the per-frame one-to-one detection mapping of
    :func:`jaxtrack.metrics.vace.detection_mapping` (most pairs with IoU >= threshold, then
    the largest summed IoU); gt rows with ``conf == 0`` are dropped (MOT15 convention).

    Args:
        det_table: detections.
        gt_table: ground truth, all rows as read.
        frames: ``(first, last)`` 1-based inclusive span holding every row of both tables.
        iou_threshold: minimum IoU of a match.

    Returns:
        ``(precision, recall)``; a ratio with a zero denominator is 0.0.
    """
    numbered = MotTable.from_arrays(det_table.frames, np.arange(len(det_table)), det_table.boxes)
    data = prepare_sequence(gt_table, numbered, frames)
    matched = int(detection_mapping(data, iou_threshold).sum())
    num_gt = int(data.gt_frame.shape[0])
    precision = matched / len(det_table) if len(det_table) else 0.0
    recall = matched / num_gt if num_gt else 0.0
    return precision, recall
