"""Per-frame candidate pairs and optimal one-to-one assignment, batched over a sequence.

Every metric compares the ground-truth boxes of a frame with the tracker boxes of the same
frame. Instead of one small matrix per frame, all ``(gt, tracker)`` pairs of a sequence are
laid out in one flat array, frame after frame, each frame's block in row-major order
(gt row ``i``, tracker row ``j`` -> ``start[t] + i * num_tracker[t] + j``). Similarities are
then computed for the whole sequence at once, and a frame's matrix is a reshaped slice.

Optimal assignment (Hungarian algorithm, ``scipy.optimize.linear_sum_assignment``) is only
needed in *conflict* frames. If the candidate pairs of a frame (the pairs with a positive
score) share no gt row and no tracker row, every optimal assignment takes all of them, so the
assignment is known without solving; only frames where a row or column holds two or more
candidates are solved, on the frame's full score matrix exactly as TrackEval builds it (same
values, same row and column order, hence the same tie-breaking).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.optimize import linear_sum_assignment

from jaxtrack.boxes import iou_matrix, xywh_to_cxcywh

#: float64 machine epsilon; TrackEval's tolerance in every threshold comparison.
EPS = float(np.finfo(np.float64).eps)


class FramePairs(NamedTuple):
    """All same-frame ``(gt row, tracker row)`` pairs of a sequence.

    Rows of both tables are sorted by frame (file order within a frame). ``num_frames`` is
    ``F``, ``P`` the number of pairs.

    Attributes:
        gt_start: ``[F + 1]`` offsets: gt rows of frame ``t`` are ``gt_start[t]:gt_start[t+1]``.
        tracker_start: ``[F + 1]`` offsets of the tracker rows of each frame.
        start: ``[F + 1]`` offsets of each frame's block of pairs.
        frame: ``[P]`` frame index of each pair.
        gt_row: ``[P]`` gt row of each pair.
        tracker_row: ``[P]`` tracker row of each pair.
    """

    gt_start: np.ndarray
    tracker_start: np.ndarray
    start: np.ndarray
    frame: np.ndarray
    gt_row: np.ndarray
    tracker_row: np.ndarray

    @property
    def num_gt(self) -> np.ndarray:
        """Gt boxes per frame, ``[F]``."""
        return np.diff(self.gt_start)

    @property
    def num_tracker(self) -> np.ndarray:
        """Tracker boxes per frame, ``[F]``."""
        return np.diff(self.tracker_start)


def frame_offsets(frame_index: np.ndarray, num_frames: int) -> np.ndarray:
    """``[F + 1]`` offsets of each frame's rows in a table sorted by frame index."""
    counts = np.bincount(frame_index, minlength=num_frames)
    return np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)


def build_pairs(gt_frame: np.ndarray, tracker_frame: np.ndarray, num_frames: int) -> FramePairs:
    """Lays out every same-frame pair of two frame-sorted tables.

    Args:
        gt_frame: ``[num_gt_rows]`` 0-based frame index of each gt row, non-decreasing.
        tracker_frame: ``[num_tracker_rows]`` frame index of each tracker row, non-decreasing.
        num_frames: number of frames ``F``.

    Returns:
        The pairs, frame by frame, each frame's block in row-major (gt, tracker) order.
    """
    gt_start = frame_offsets(gt_frame, num_frames)
    tracker_start = frame_offsets(tracker_frame, num_frames)
    num_tracker = np.diff(tracker_start)
    per_gt_row = num_tracker[gt_frame]
    block_start = np.concatenate([[0], np.cumsum(per_gt_row)]).astype(np.int64)
    num_pairs = int(block_start[-1])
    gt_row = np.repeat(np.arange(gt_frame.shape[0], dtype=np.int64), per_gt_row)
    tracker_row = np.arange(num_pairs, dtype=np.int64) + np.repeat(
        tracker_start[gt_frame] - block_start[:-1], per_gt_row
    )
    per_frame = np.diff(gt_start) * num_tracker
    start = np.concatenate([[0], np.cumsum(per_frame)]).astype(np.int64)
    frame = np.repeat(np.arange(num_frames, dtype=np.int64), per_frame)
    return FramePairs(gt_start, tracker_start, start, frame, gt_row, tracker_row)


def select_pairs(pairs: FramePairs, keep_gt: np.ndarray, keep_tracker: np.ndarray):
    """Restricts the pairs to kept gt and tracker rows (block order is preserved).

    Args:
        pairs: pairs of the unfiltered tables.
        keep_gt: ``[num_gt_rows]`` boolean mask of gt rows to keep.
        keep_tracker: ``[num_tracker_rows]`` boolean mask of tracker rows to keep.

    Returns:
        ``(new_pairs, kept)``: pairs indexed into the filtered tables, and the ``[P]`` mask of
        the old pairs that survive (to carry per-pair values such as similarities over).
    """
    kept = keep_gt[pairs.gt_row] & keep_tracker[pairs.tracker_row]
    gt_new_index = np.cumsum(keep_gt) - 1
    tracker_new_index = np.cumsum(keep_tracker) - 1
    gt_start = _filtered_offsets(pairs.gt_start, keep_gt)
    tracker_start = _filtered_offsets(pairs.tracker_start, keep_tracker)
    per_frame = np.diff(gt_start) * np.diff(tracker_start)
    start = np.concatenate([[0], np.cumsum(per_frame)]).astype(np.int64)
    new_pairs = FramePairs(
        gt_start=gt_start,
        tracker_start=tracker_start,
        start=start,
        frame=pairs.frame[kept],
        gt_row=gt_new_index[pairs.gt_row[kept]],
        tracker_row=tracker_new_index[pairs.tracker_row[kept]],
    )
    return new_pairs, kept


def _filtered_offsets(offsets: np.ndarray, keep: np.ndarray) -> np.ndarray:
    kept_before = np.concatenate([[0], np.cumsum(keep)]).astype(np.int64)
    return kept_before[offsets]


def box_similarity(
    gt_boxes: np.ndarray,
    tracker_boxes: np.ndarray,
    centre_threshold: float | None = None,
) -> np.ndarray:
    """Similarity of paired boxes (row ``k`` of each input forms pair ``k``).

    Args:
        gt_boxes: ``[P, 4]`` ``(x, y, w, h)``.
        tracker_boxes: ``[P, 4]``.
        centre_threshold: None for IoU (computed as TrackEval does). Otherwise a distance
            ``tau`` in pixels: similarity ``max(0, 1 - d / (2 tau))`` with ``d`` the distance
            between box centres, so that similarity >= 0.5 exactly when ``d <= tau`` (the
            form of TrackEval's Euclidean similarity, with its zero distance set to ``2 tau``).

    Returns:
        ``[P]`` similarities in ``[0, 1]``.
    """
    if centre_threshold is None:
        return iou_matrix(gt_boxes[:, None, :], tracker_boxes[:, None, :])[:, 0, 0]
    distance = centre_distance(gt_boxes, tracker_boxes)
    return np.maximum(0.0, 1.0 - distance / (2.0 * centre_threshold))


def centre_distance(gt_boxes: np.ndarray, tracker_boxes: np.ndarray) -> np.ndarray:
    """Euclidean distance between the centres of paired boxes, ``[P]``."""
    offset = xywh_to_cxcywh(gt_boxes)[:, :2] - xywh_to_cxcywh(tracker_boxes)[:, :2]
    return np.sqrt(np.sum(offset * offset, axis=1))


def conflict_frames(pairs: FramePairs, candidate: np.ndarray, num_rows) -> np.ndarray:
    """Frames where some gt row or tracker row has two or more candidate pairs.

    Args:
        pairs: the pairs.
        candidate: ``[P]`` boolean, the pairs with a positive assignment score.
        num_rows: ``(num_gt_rows, num_tracker_rows)``.

    Returns:
        Sorted frame indices that need the Hungarian algorithm.
    """
    num_gt_rows, num_tracker_rows = num_rows
    gt_count = np.bincount(pairs.gt_row[candidate], minlength=num_gt_rows)
    tracker_count = np.bincount(pairs.tracker_row[candidate], minlength=num_tracker_rows)
    busy_gt = np.flatnonzero(gt_count > 1)
    busy_tracker = np.flatnonzero(tracker_count > 1)
    frames_of_gt = np.searchsorted(pairs.gt_start, busy_gt, side="right") - 1
    frames_of_tracker = np.searchsorted(pairs.tracker_start, busy_tracker, side="right") - 1
    return np.union1d(frames_of_gt, frames_of_tracker).astype(np.int64)


def solve_block(pairs: FramePairs, frame: int, score_block: np.ndarray) -> np.ndarray:
    """Maximum-score assignment of one frame's block.

    Args:
        pairs: the pairs.
        frame: the frame index.
        score_block: ``[num_gt[frame] * num_tracker[frame]]`` scores of the frame's pairs.

    Returns:
        Global pair indices chosen by ``linear_sum_assignment(-scores)`` (as TrackEval calls
        it), ``min(num_gt, num_tracker)`` of them, including zero-score pairs.
    """
    num_tracker = int(pairs.tracker_start[frame + 1] - pairs.tracker_start[frame])
    rows, cols = linear_sum_assignment(-score_block.reshape(-1, num_tracker))
    return pairs.start[frame] + rows * num_tracker + cols


def assign_frames(pairs: FramePairs, score: np.ndarray, candidate: np.ndarray, num_rows):
    """Per-frame maximum-score one-to-one assignment, restricted to candidate pairs.

    Equivalent to solving every frame's score matrix with the Hungarian algorithm and
    keeping the chosen pairs that are candidates, provided ``candidate`` marks exactly the
    pairs with a positive score.

    Args:
        pairs: the pairs.
        score: ``[P]`` scores (zero where not a candidate).
        candidate: ``[P]`` boolean.
        num_rows: ``(num_gt_rows, num_tracker_rows)``.

    Returns:
        ``[P]`` boolean mask of matched pairs.
    """
    matched = candidate.copy()
    for frame in conflict_frames(pairs, candidate, num_rows):
        lo, hi = pairs.start[frame], pairs.start[frame + 1]
        chosen = solve_block(pairs, frame, score[lo:hi])
        matched[lo:hi] = False
        matched[chosen] = candidate[chosen]
    return matched
