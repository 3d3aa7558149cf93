"""Ground-truth conventions: which gt and tracker boxes an evaluation scores.

Two rule sets, both exactly as TrackEval 1.3.0's ``MotChallenge2DBox`` applies them:

* **MOT15** (default): gt rows whose ``conf`` column truncates to 0 (``conf == 0`` in MOT
  files) are dropped; every tracker box is kept, so a tracker box on a dropped gt object is a
  false positive.
* **MOT16/17 distractors** (``distractors=True``; gt column 8 is the class, column 9 the
  visibility): per frame, tracker boxes are matched one-to-one to *all* gt boxes at IoU >= 0.5
  (Hungarian algorithm, maximum summed IoU); tracker boxes matched to a distractor-class gt
  box (2 person on vehicle, 7 static person, 8 distractor, 12 reflection) are removed. Then
  every gt box that is not a pedestrian (class 1) or is zero-marked is removed.

Identities are relabelled ``0..n-1`` in increasing order of the original id (TrackEval's
order, so that dense sums run in the same order).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from jaxtrack.errors import FileFormatError, InputError
from jaxtrack.metrics.matching import (
    EPS,
    FramePairs,
    assign_frames,
    box_similarity,
    build_pairs,
    select_pairs,
)

#: MOT16/17 gt classes (column 8): 1 pedestrian ... 13 crowd.
PEDESTRIAN_CLASS = 1
VALID_CLASSES = np.arange(1, 14)
#: Classes whose matched tracker boxes are removed (person_on_vehicle, static_person,
#: distractor, reflection).
DISTRACTOR_CLASSES = np.array([2, 7, 8, 12])
#: IoU at which tracker boxes are matched to distractors (fixed by TrackEval, not the
#: evaluation threshold).
DISTRACTOR_IOU = 0.5


class SequenceData(NamedTuple):
    """The boxes an evaluation scores, sorted by frame, with all same-frame pairs.

    Attributes:
        first_frame: 1-based number of frame index 0.
        num_frames: number of frames ``F`` in the evaluated span.
        gt_frame: ``[num_gt_rows]`` 0-based frame index of each gt box (non-decreasing).
        gt_id: ``[num_gt_rows]`` gt identity relabelled to ``0..num_gt_ids-1``.
        gt_boxes: ``[num_gt_rows, 4]`` ``(x, y, w, h)``.
        tracker_frame: ``[num_tracker_rows]`` frame index of each tracker box.
        tracker_id: ``[num_tracker_rows]`` tracker identity relabelled ``0..num_tracker_ids-1``.
        tracker_boxes: ``[num_tracker_rows, 4]``.
        num_gt_ids: number of distinct gt identities.
        num_tracker_ids: number of distinct tracker identities.
        pairs: every same-frame (gt, tracker) pair.
        similarity: ``[P]`` similarity of each pair (IoU, or centre similarity).
        gt_labels: ``[num_gt_ids]`` the ground-truth file's id of each relabelled ``gt_id``.
        tracker_labels: ``[num_tracker_ids]`` the result file's id of each ``tracker_id``.
    """

    first_frame: int
    num_frames: int
    gt_frame: np.ndarray
    gt_id: np.ndarray
    gt_boxes: np.ndarray
    tracker_frame: np.ndarray
    tracker_id: np.ndarray
    tracker_boxes: np.ndarray
    num_gt_ids: int
    num_tracker_ids: int
    pairs: FramePairs
    similarity: np.ndarray
    gt_labels: np.ndarray
    tracker_labels: np.ndarray

    @property
    def num_rows(self) -> tuple[int, int]:
        """``(num_gt_rows, num_tracker_rows)``."""
        return int(self.gt_frame.shape[0]), int(self.tracker_frame.shape[0])


def prepare_sequence(
    gt,
    result,
    frames: tuple[int, int],
    centre_threshold: float | None = None,
    distractors: bool = False,
) -> SequenceData:
    """Applies the ground-truth conventions and pairs up same-frame boxes.

    Args:
        gt: ground truth (:class:`jaxtrack.types.MotTable`, all rows as read).
        result: tracker output (:class:`jaxtrack.types.MotTable`).
        frames: ``(first, last)``, the 1-based inclusive span being scored; every row of
            both tables must lie in it.
        centre_threshold: None to compare boxes by IoU, else the centre distance (pixels)
            at which similarity is 0.5 (see :func:`jaxtrack.metrics.matching.box_similarity`).
        distractors: apply the MOT16/17 distractor rules instead of the MOT15 ones.

    Returns:
        The scored boxes and their pairs.

    Raises:
        InputError: a row outside ``frames``, or an id twice in one frame.
        FileFormatError: with ``distractors``, a gt file without a class column or with a
            class outside 1..13 (names the file and line).
    """
    first, last = frames
    num_frames = last - first + 1
    for table in (gt, result):
        _check_span(table, first, last)
        _check_unique_ids(table)
    gt_order = np.argsort(gt.frames, kind="stable")
    tracker_order = np.argsort(result.frames, kind="stable")
    gt_frame = gt.frames[gt_order] - first
    tracker_frame = result.frames[tracker_order] - first
    gt_boxes = gt.boxes[gt_order]
    tracker_boxes = result.boxes[tracker_order]
    pairs = build_pairs(gt_frame, tracker_frame, num_frames)
    similarity = box_similarity(
        gt_boxes[pairs.gt_row], tracker_boxes[pairs.tracker_row], centre_threshold
    )
    keep_gt = np.trunc(gt.confs[gt_order]) != 0
    keep_tracker = np.ones(tracker_frame.shape[0], dtype=bool)
    if distractors:
        gt_class = _gt_classes(gt)[gt_order]
        keep_tracker = ~_matched_to_distractor(pairs, similarity, gt_class, tracker_frame.size)
        keep_gt &= gt_class == PEDESTRIAN_CLASS
    pairs, kept = select_pairs(pairs, keep_gt, keep_tracker)
    gt_ids, gt_id = np.unique(gt.ids[gt_order][keep_gt], return_inverse=True)
    tracker_ids, tracker_id = np.unique(
        result.ids[tracker_order][keep_tracker], return_inverse=True
    )
    return SequenceData(
        first_frame=first,
        num_frames=num_frames,
        gt_frame=gt_frame[keep_gt],
        gt_id=gt_id.reshape(-1),
        gt_boxes=gt_boxes[keep_gt],
        tracker_frame=tracker_frame[keep_tracker],
        tracker_id=tracker_id.reshape(-1),
        tracker_boxes=tracker_boxes[keep_tracker],
        num_gt_ids=int(gt_ids.size),
        num_tracker_ids=int(tracker_ids.size),
        pairs=pairs,
        similarity=similarity[kept],
        gt_labels=gt_ids,
        tracker_labels=tracker_ids,
    )


def _check_span(table, first: int, last: int) -> None:
    outside = (table.frames < first) | (table.frames > last)
    if np.any(outside):
        i = int(np.argmax(outside))
        where = _where(table, i)
        raise InputError(
            f"{where}frame {int(table.frames[i])} outside the scored span {first}:{last}"
        )


def _check_unique_ids(table) -> None:
    order = np.lexsort((table.ids, table.frames))
    frames, ids = table.frames[order], table.ids[order]
    repeated = np.flatnonzero((frames[1:] == frames[:-1]) & (ids[1:] == ids[:-1]))
    if repeated.size:
        i = int(order[repeated[0] + 1])
        frame, track = int(table.frames[i]), int(table.ids[i])
        raise InputError(f"{_where(table, i)}id {track} appears twice in frame {frame}")


def _where(table, row: int) -> str:
    if table.path is None:
        return ""
    if table.lines[row] > 0:
        return f"{table.path}, line {int(table.lines[row])}: "
    return f"{table.path}: "


def _gt_classes(gt) -> np.ndarray:
    if gt.extra.shape[1] < 1:
        raise FileFormatError(
            gt.path or "<ground truth>",
            None,
            "the MOT16/17 distractor rules need a class column (column 8) in the ground truth",
        )
    classes = gt.extra[:, 0]
    invalid = ~np.isin(classes, VALID_CLASSES)
    if np.any(invalid):
        i = int(np.argmax(invalid))
        line = int(gt.lines[i]) if gt.lines[i] > 0 else None
        raise FileFormatError(
            gt.path or "<ground truth>",
            line,
            f"class {classes[i]:g} in column 8 is not a MOT16/17 class (1..13); "
            "MOT15 ground truth has no classes: evaluate it without the distractor rules",
        )
    return classes.astype(np.int64)


def _matched_to_distractor(pairs, similarity, gt_class, num_tracker_rows) -> np.ndarray:
    """Tracker rows matched (IoU >= 0.5, optimal per frame) to a distractor-class gt box."""
    score = np.where(similarity < DISTRACTOR_IOU - EPS, 0.0, similarity)
    candidate = score > EPS
    num_rows = (gt_class.shape[0], num_tracker_rows)
    matched = assign_frames(pairs, score, candidate, num_rows)
    to_distractor = matched & np.isin(gt_class[pairs.gt_row], DISTRACTOR_CLASSES)
    removed = np.zeros(num_tracker_rows, dtype=bool)
    removed[pairs.tracker_row[to_distractor]] = True
    return removed
