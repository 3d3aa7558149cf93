"""Detector quality: precision and recall of detections against ground truth."""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment

from jaxtrack.boxes import iou_matrix


def count_detection_matches(det_table, gt_table, iou_threshold: float = 0.5) -> int:
    """Number of one-to-one detection-gt matches with IoU >= threshold, summed over frames.

    Per frame, the assignment maximises the number of matched pairs (ties broken by the summed
    IoU), so the count is the largest achievable at this threshold.

    Args:
        det_table: detections (:class:`jaxtrack.io.MotTable`).
        gt_table: ground truth rows to match against (drop ignored rows beforehand).
        iou_threshold: minimum IoU of a match.

    Returns:
        The number of matched pairs.
    """
    matched = 0
    det_order = np.argsort(det_table.frames, kind="stable")
    gt_order = np.argsort(gt_table.frames, kind="stable")
    det_frames = det_table.frames[det_order]
    gt_frames = gt_table.frames[gt_order]
    for frame in np.intersect1d(det_frames, gt_frames):
        dets = det_table.boxes[
            det_order[
                np.searchsorted(det_frames, frame) : np.searchsorted(det_frames, frame, "right")
            ]
        ]
        gts = gt_table.boxes[
            gt_order[np.searchsorted(gt_frames, frame) : np.searchsorted(gt_frames, frame, "right")]
        ]
        iou = iou_matrix(dets, gts)
        valid = iou >= iou_threshold - np.finfo(float).eps
        weight = np.where(valid, 1.0 + iou / (1 + min(iou.shape)), 0.0)
        rows, cols = linear_sum_assignment(weight, maximize=True)
        matched += int(valid[rows, cols].sum())
    return matched


def detection_precision_recall(
    det_table, gt_table, iou_threshold: float = 0.5
) -> tuple[float, float]:
    """Precision = matches / detections and recall = matches / gt boxes (see above).

    Returns 0.0 for a ratio whose denominator is zero.
    """
    matched = count_detection_matches(det_table, gt_table, iou_threshold)
    precision = matched / len(det_table) if len(det_table) else 0.0
    recall = matched / len(gt_table) if len(gt_table) else 0.0
    return precision, recall
