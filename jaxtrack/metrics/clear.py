"""CLEAR MOT metrics (Bernardin & Stiefelhagen 2008), exactly as TrackEval 1.3.0 computes them.

Matching, per frame: a gt box and a tracker box may match when their similarity is at least
the threshold (``sim >= threshold - eps``). Among the one-to-one assignments the Hungarian
algorithm maximises ``sum 1000 * continues + sim``, where ``continues`` marks a pair whose gt
object was matched to the same tracker id in the previous frame that had both gt and tracker
boxes: keeping existing correspondences comes first, then the summed similarity.

Scores (``N_G`` gt boxes, ``TP`` matches, ``FN = N_G - TP``, ``FP`` = unmatched tracker boxes):

* ``MOTA = 1 - (FN + FP + IDSW) / N_G`` (Bernardin & Stiefelhagen 2008).
* ``MOTP = sum of matched similarities / TP`` (mean IoU of matches).
* ``IDSW``: a match whose tracker id differs from the tracker id the same gt object was last
  matched to, any number of frames before.
* ``Frag``: per gt object, the number of times it becomes matched after being unmatched in the
  previous frame that had both gt and tracker boxes, minus one.
* ``MT / PT / ML``: gt objects matched in more than 80% / 20% to 80% / less than 20% of the
  frames they appear in.
* ``Recall = TP / N_G``, ``Precision = TP / (TP + FP)``; ratios use ``max(1, denominator)``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from jaxtrack.metrics.matching import EPS, conflict_frames, solve_block
from jaxtrack.metrics.preprocess import SequenceData

#: Score bonus for keeping the previous frame's correspondence (TrackEval's constant).
CONTINUITY_BONUS = 1000.0
#: Fields summed when sequences are combined.
ADDITIVE_FIELDS = ("TP", "FN", "FP", "IDSW", "Frag", "MT", "PT", "ML", "MOTP_sum", "GT_IDs")


class ClearMatching(NamedTuple):
    """Result of the CLEAR MOT frame-by-frame matching.

    Attributes:
        matched: ``[P]`` boolean mask of matched pairs.
        matches: ``[F]`` matches per frame.
        id_switches: ``[F]`` identity switches per frame.
    """

    matched: np.ndarray
    matches: np.ndarray
    id_switches: np.ndarray


def clear_matching(data: SequenceData, threshold: float = 0.5) -> ClearMatching:
    """Matches gt and tracker boxes frame by frame with identity continuity.

    Frames whose candidate pairs (``sim >= threshold - eps``) share no row or column are
    resolved without solving; the others are solved in frame order, each with the continuity
    bonus computed from the matches of the previous frame that had both gt and tracker boxes.

    Args:
        data: the scored boxes.
        threshold: minimum similarity of a match, in ``(0, 1]``.

    Returns:
        The matching.
    """
    pairs, similarity = data.pairs, data.similarity
    candidate = (similarity >= threshold - EPS) & (similarity > EPS)
    matched = candidate.copy()
    code = (
        data.gt_id[pairs.gt_row] * max(data.num_tracker_ids, 1) + data.tracker_id[pairs.tracker_row]
    )
    active = np.flatnonzero((pairs.num_gt > 0) & (pairs.num_tracker > 0))
    conflicts = conflict_frames(pairs, candidate, data.num_rows)
    position = np.searchsorted(active, conflicts)
    previous_active = np.where(position > 0, active[position - 1], -1)
    for frame, previous in zip(conflicts, previous_active, strict=True):
        lo, hi = pairs.start[frame], pairs.start[frame + 1]
        block_candidate = candidate[lo:hi]
        continues = np.zeros(hi - lo, dtype=bool)
        if previous >= 0:
            p_lo, p_hi = pairs.start[previous], pairs.start[previous + 1]
            continues = np.isin(code[lo:hi], code[p_lo:p_hi][matched[p_lo:p_hi]])
        score = np.where(continues, CONTINUITY_BONUS, 0.0) + similarity[lo:hi]
        score[~block_candidate] = 0.0
        chosen = solve_block(pairs, frame, score)
        matched[lo:hi] = False
        matched[chosen] = candidate[chosen]
    matches = np.bincount(pairs.frame[matched], minlength=data.num_frames)
    gt_id, tracker_id, frame = matches_by_object(data, matched)
    switch = (gt_id[1:] == gt_id[:-1]) & (tracker_id[1:] != tracker_id[:-1])
    id_switches = np.bincount(frame[1:][switch], minlength=data.num_frames)
    return ClearMatching(matched, matches, id_switches)


def clear_fields(data: SequenceData, matching: ClearMatching) -> dict:
    """CLEAR MOT counts of one sequence (the additive fields).

    Args:
        data: the scored boxes.
        matching: from :func:`clear_matching`.

    Returns:
        ``TP, FN, FP, IDSW, Frag, MT, PT, ML, GT_IDs`` (ints) and ``MOTP_sum`` (float).
    """
    pairs = data.pairs
    num_gt_rows, num_tracker_rows = data.num_rows
    tp = int(matching.matches.sum())
    gt_id, _, frame = matches_by_object(data, matching.matched)
    active = (pairs.num_gt > 0) & (pairs.num_tracker > 0)
    active_index = np.cumsum(active) - 1
    step = active_index[frame]
    run_start = np.ones(gt_id.shape[0], dtype=bool)
    run_start[1:] = (gt_id[1:] != gt_id[:-1]) | (step[1:] != step[:-1] + 1)
    tracked_objects = np.unique(gt_id).size
    appearances = np.bincount(data.gt_id, minlength=data.num_gt_ids)
    tracked_frames = np.bincount(gt_id, minlength=data.num_gt_ids)
    ratio = tracked_frames[appearances > 0] / appearances[appearances > 0]
    mostly = int(np.sum(ratio > 0.8))
    partly = int(np.sum(ratio >= 0.2)) - mostly
    return {
        "TP": tp,
        "FN": num_gt_rows - tp,
        "FP": num_tracker_rows - tp,
        "IDSW": int(matching.id_switches.sum()),
        "Frag": int(run_start.sum()) - tracked_objects,
        "MT": mostly,
        "PT": partly,
        "ML": data.num_gt_ids - mostly - partly,
        "GT_IDs": data.num_gt_ids,
        "MOTP_sum": float(np.sum(data.similarity[matching.matched])),
    }


def clear_scores(fields: dict, single_sequence: bool = True) -> dict:
    """CLEAR MOT scores from the additive fields (of one sequence or summed over several).

    Args:
        fields: from :func:`clear_fields` (or their sums).
        single_sequence: True for one sequence: TrackEval then reports MOTA 0 when the
            sequence has no gt boxes (instead of ``-FP``); combined rows use the formula.

    Returns:
        ``MOTA, MOTP, Recall, Precision`` plus the counts ``FP, FN, IDSW, Frag, MT, PT, ML,
        GT_IDs``.
    """
    tp, fn, fp = fields["TP"], fields["FN"], fields["FP"]
    num_gt = tp + fn
    mota = (tp - fp - fields["IDSW"]) / max(1.0, num_gt)
    if single_sequence and num_gt == 0:
        mota = 0.0
    scores = {
        "MOTA": mota,
        "MOTP": fields["MOTP_sum"] / max(1.0, tp),
        "Recall": tp / max(1.0, num_gt),
        "Precision": tp / max(1.0, tp + fp),
    }
    scores.update({key: int(fields[key]) for key in ("FP", "FN", "IDSW", "Frag", "MT", "PT", "ML")})
    scores["GT_IDs"] = int(fields["GT_IDs"])
    return scores


def matches_by_object(data: SequenceData, matched: np.ndarray):
    """``(gt_id, tracker_id, frame)`` of the matches, sorted by gt id then frame."""
    pairs = data.pairs
    gt_id = data.gt_id[pairs.gt_row[matched]]
    tracker_id = data.tracker_id[pairs.tracker_row[matched]]
    frame = pairs.frame[matched]
    order = np.lexsort((frame, gt_id))
    return gt_id[order], tracker_id[order], frame[order]
