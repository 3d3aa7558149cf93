"""Where the misses and false positives come from, given the detector's boxes.

A tracker that works on a detector's output cannot be judged by its FN and FP alone: some
misses are the detector's (no box on the object), and some false positives follow the
detector's false alarms. This module gives every CLEAR MOT miss and false positive
(:mod:`jaxtrack.metrics.clear`, same matching, threshold ``T``) one kind, from the boxes of
the same frame. "Overlaps" means similarity (IoU, or the centre similarity) of at least
``near`` (default 0.3, below ``T``: a box on the object but not well enough placed to
count). A gt box is **well detected** when the detections' one-to-one mapping at ``T``
(:func:`jaxtrack.metrics.detection.map_detections`, the mapping of
:func:`jaxtrack.metrics.detection.true_identity_rows`) gives it a detection.

Misses (gt boxes that no output box matched), first kind that applies:

======================  ========================================================================
``not_detected``        no detection overlaps it: only prediction could have covered it.
``detection_misplaced`` a detection overlaps it, none well: the detector's box is off.
``output_misplaced``    well detected, and an unmatched output box overlaps it: the tracker
                        was there but its box is off (this box is also a false positive).
``dropped``             well detected and no unmatched output box overlaps it: the tracker
                        had no box there (a late start, an unconfirmed or lost track).
======================  ========================================================================

False positives (output boxes matched to no gt box), first kind that applies:

=============  ===============================================================================
``misplaced``  it overlaps a missed gt box (the same error seen from the output side).
``duplicate``  it overlaps a matched gt box: a second box on a tracked object.
``clutter``    it overlaps a detection that no gt box was mapped to: a false alarm followed.
``phantom``    none of these: a box where neither an object nor a detection is (a track
               coasting after its object left, or drifting).
=============  ===============================================================================

The kinds are exhaustive and exclusive: they add up to ``FN`` and ``FP``. With the ground
truth's conventions (MOT15: gt rows with ``conf == 0`` dropped) applied to the detections
as to the output, a detection on a dropped gt box maps to nothing, so a box following it
counts as ``clutter``, as the CLEAR counts make it a false positive.

A learned scene context acts on some of these kinds and not others: a clutter intensity on
``clutter`` (and the tracks it keeps from confirming), a birth intensity on ``dropped``
targets born late; no context gives a target the detector missed (``not_detected``) or
moves a misplaced box onto it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from jaxtrack.errors import InputError
from jaxtrack.metrics.clear import clear_matching
from jaxtrack.metrics.detection import map_detections
from jaxtrack.metrics.matching import EPS, box_similarity, build_pairs
from jaxtrack.metrics.preprocess import prepare_sequence
from jaxtrack.types import MotTable

#: Kinds of misses, in the order of the codes of :attr:`ErrorTable.fn_kind`.
FN_KINDS = ("not_detected", "detection_misplaced", "output_misplaced", "dropped")
#: Kinds of false positives, in the order of the codes of :attr:`ErrorTable.fp_kind`.
FP_KINDS = ("misplaced", "duplicate", "clutter", "phantom")
#: Default similarity at which two boxes "overlap" (below the match threshold).
DEFAULT_NEAR = 0.3


class ErrorTable(NamedTuple):
    """Every miss and false positive of a sequence, each with its kind.

    Attributes:
        fn_frame: ``[FN]`` 1-based frame of each miss.
        fn_gt_id: ``[FN]`` the missed object's id as in the ground-truth file.
        fn_kind: ``[FN]`` index into :data:`FN_KINDS`.
        fp_frame: ``[FP]`` 1-based frame of each false positive.
        fp_track_id: ``[FP]`` the output box's track id as in the result file.
        fp_kind: ``[FP]`` index into :data:`FP_KINDS`.
    """

    fn_frame: np.ndarray
    fn_gt_id: np.ndarray
    fn_kind: np.ndarray
    fp_frame: np.ndarray
    fp_track_id: np.ndarray
    fp_kind: np.ndarray

    def counts(self) -> dict[str, dict[str, int]]:
        """``{"FN": {kind: n}, "FP": {kind: n}}`` for every kind (zeros included)."""
        return {
            "FN": _count(self.fn_kind, FN_KINDS),
            "FP": _count(self.fp_kind, FP_KINDS),
        }


def _count(kind: np.ndarray, names: tuple[str, ...]) -> dict[str, int]:
    totals = np.bincount(kind, minlength=len(names))
    return {name: int(n) for name, n in zip(names, totals, strict=True)}


def classify_errors(
    gt: MotTable,
    result: MotTable,
    detections: MotTable,
    frames: tuple[int, int],
    threshold: float = 0.5,
    near: float = DEFAULT_NEAR,
    centre_threshold: float | None = None,
    distractors: bool = False,
) -> ErrorTable:
    """Classifies every CLEAR MOT miss and false positive (module docstring).

    Args:
        gt: ground truth (all rows as read; the conventions are applied here).
        result: the tracker's output.
        detections: the detector's boxes the tracker was given (ids ignored).
        frames: ``(first, last)`` 1-based inclusive span; every row of the three tables
            must lie in it.
        threshold: the match threshold ``T`` of the CLEAR matching and of the detection
            mapping.
        near: similarity at which two boxes overlap, in ``(0, threshold]``.
        centre_threshold: as :class:`~jaxtrack.metrics.evaluate.EvalConfig`'s (boxes compared
            by centre distance; ``threshold`` and ``near`` then apply to that similarity).
        distractors: the MOT16/17 rules (applied to the output and to the detections).

    Returns:
        The :class:`ErrorTable`; its kinds add up to the sequence's ``FN`` and ``FP``.

    Raises:
        InputError: ``near`` outside ``(0, threshold]``, or a row outside ``frames``.
    """
    if not (0.0 < near <= threshold):
        raise InputError(f"near must lie in (0, threshold = {threshold}], got {near}")
    data = prepare_sequence(gt, result, frames, centre_threshold, distractors)
    det_data, mapped = map_detections(
        detections, gt, frames, threshold, centre_threshold, distractors
    )
    num_gt, num_out = data.num_rows
    num_det = det_data.num_rows[1]

    matched = clear_matching(data, threshold).matched
    gt_matched = _rows(data.pairs.gt_row, matched, num_gt)
    out_matched = _rows(data.pairs.tracker_row, matched, num_out)
    gt_detected = _rows(det_data.pairs.gt_row, mapped, num_gt)
    det_mapped = _rows(det_data.pairs.tracker_row, mapped, num_det)
    gt_det_near = _rows(det_data.pairs.gt_row, det_data.similarity >= near - EPS, num_gt)

    # output boxes against gt boxes: overlaps with the unmatched side
    close = data.similarity >= near - EPS
    pair_gt, pair_out = data.pairs.gt_row, data.pairs.tracker_row
    gt_output_near = _rows(pair_gt, close & ~out_matched[pair_out], num_gt)
    out_on_missed = _rows(pair_out, close & ~gt_matched[pair_gt], num_out)
    out_on_matched = _rows(pair_out, close & gt_matched[pair_gt], num_out)

    # output boxes against detections
    det_pairs = build_pairs(data.tracker_frame, det_data.tracker_frame, data.num_frames)
    det_similarity = box_similarity(
        data.tracker_boxes[det_pairs.gt_row],
        det_data.tracker_boxes[det_pairs.tracker_row],
        centre_threshold,
    )
    on_false_alarm = (det_similarity >= near - EPS) & ~det_mapped[det_pairs.tracker_row]
    out_on_clutter = _rows(det_pairs.gt_row, on_false_alarm, num_out)

    fn_kind = np.select(
        [~gt_det_near, ~gt_detected, gt_output_near],
        [0, 1, 2],
        default=3,
    )[~gt_matched]
    fp_kind = np.select(
        [out_on_missed, out_on_matched, out_on_clutter],
        [0, 1, 2],
        default=3,
    )[~out_matched]
    return ErrorTable(
        fn_frame=(data.gt_frame[~gt_matched] + data.first_frame).astype(np.int64),
        fn_gt_id=data.gt_labels[data.gt_id[~gt_matched]].astype(np.int64),
        fn_kind=fn_kind.astype(np.int64),
        fp_frame=(data.tracker_frame[~out_matched] + data.first_frame).astype(np.int64),
        fp_track_id=data.tracker_labels[data.tracker_id[~out_matched]].astype(np.int64),
        fp_kind=fp_kind.astype(np.int64),
    )


def _rows(row_of_pair: np.ndarray, selected: np.ndarray, num_rows: int) -> np.ndarray:
    """``[num_rows]`` mask of the rows that have at least one selected pair."""
    mask = np.zeros(num_rows, dtype=bool)
    mask[row_of_pair[selected]] = True
    return mask
