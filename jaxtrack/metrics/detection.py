"""Detector quality: precision and recall of detections against ground truth."""

from __future__ import annotations

import numpy as np

from jaxtrack.metrics.preprocess import SequenceData, prepare_sequence
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
    data, mapped = map_detections(det_table, gt_table, frames, iou_threshold)
    matched = int(mapped.sum())
    num_gt = int(data.gt_frame.shape[0])
    precision = matched / len(det_table) if len(det_table) else 0.0
    recall = matched / num_gt if num_gt else 0.0
    return precision, recall


def true_identity_rows(
    det_table: MotTable,
    gt_table: MotTable,
    frames: tuple[int, int],
    iou_threshold: float = 0.5,
) -> MotTable:
    """The detections that match the ground truth, each under its true identity.

    A reference for trackers that report the detector's boxes: what perfect association
    scores with these detections. Each frame's detections are mapped one-to-one to the kept
    gt boxes (:func:`jaxtrack.metrics.vace.detection_mapping`: most pairs with
    IoU >= ``iou_threshold``, then the largest summed IoU; gt rows with ``conf == 0``
    dropped); a mapped detection keeps its box and takes its gt box's identity, the others
    are dropped. No identity switch is possible, and every row is a true positive at the
    threshold, so the scores count only what the detector missed or placed badly: a
    trajectory mostly tracked here has a well-placed detection on at least 80 % of its
    frames. Arguments as :func:`detection_precision_recall`.

    Returns:
        The mapped detections (score 1), in the detections' row order.
    """
    data, mapped = map_detections(det_table, gt_table, frames, iou_threshold)
    det_rows = data.tracker_labels[data.tracker_id[data.pairs.tracker_row[mapped]]]
    identities = data.gt_labels[data.gt_id[data.pairs.gt_row[mapped]]]
    order = np.argsort(det_rows, kind="stable")
    det_rows, identities = det_rows[order], identities[order]
    return MotTable.from_arrays(det_table.frames[det_rows], identities, det_table.boxes[det_rows])


def map_detections(
    det_table: MotTable,
    gt_table: MotTable,
    frames: tuple[int, int],
    iou_threshold: float = 0.5,
    centre_threshold: float | None = None,
    distractors: bool = False,
) -> tuple[SequenceData, np.ndarray]:
    """The detections' one-to-one mapping to the ground truth, frame by frame
    (:func:`jaxtrack.metrics.vace.detection_mapping`).

    Args:
        det_table: detections (ids ignored).
        gt_table: ground truth, all rows as read (the conventions are applied here).
        frames: ``(first, last)`` 1-based inclusive span holding every row of both tables.
        iou_threshold: minimum similarity of a mapped pair.
        centre_threshold, distractors: as :func:`~jaxtrack.metrics.preprocess.prepare_sequence`.

    Returns:
        ``(data, mapped)``: the scored boxes, the detections numbered by row as tracker ids,
        and the ``[P]`` mask of their mapped pairs.
    """
    numbered = MotTable.from_arrays(det_table.frames, np.arange(len(det_table)), det_table.boxes)
    data = prepare_sequence(gt_table, numbered, frames, centre_threshold, distractors)
    return data, detection_mapping(data, iou_threshold)
