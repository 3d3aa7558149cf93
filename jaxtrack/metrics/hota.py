"""HOTA with DetA, AssA, LocA (Luiten et al. 2021, IJCV), as TrackEval 1.3.0 computes them.

1. Global alignment: ``A(g, k) = S(g, k) / (n_g + n_k - S(g, k))`` where ``n_g``, ``n_k`` count
   the boxes of gt object ``g`` and tracker object ``k`` and ``S(g, k)`` sums, over frames,
   the pair's similarity normalised within its frame, ``sim / (rowsum + colsum - sim)``.
2. Per frame, the Hungarian algorithm maximises ``sum A(g, k) * sim(g, k)`` (one assignment
   for all thresholds).
3. For each ``alpha`` in ``0.05, 0.10, ..., 0.95``, assigned pairs with ``sim >= alpha``
   are true positives: ``DetA = TP / (TP + FN + FP)``,
   ``AssA = (1 / TP) sum over TP of TPA / (TPA + FNA + FPA)`` (``TPA(g, k)`` = TPs of the
   pair, ``FNA = n_g - TPA``, ``FPA = n_k - TPA``), ``HOTA = sqrt(DetA * AssA)``,
   ``LocA`` = mean similarity of the TPs (Luiten et al. 2021).
4. Reported scores are the means over the 19 thresholds.
"""

from __future__ import annotations

import numpy as np

from jaxtrack.metrics.matching import EPS, assign_frames
from jaxtrack.metrics.preprocess import SequenceData

#: Localisation thresholds alpha (the same float values as TrackEval's).
ALPHAS = np.arange(0.05, 0.99, 0.05)
#: Reported HOTA scores (means over ALPHAS).
SCORES = ("HOTA", "DetA", "AssA", "LocA", "DetRe", "DetPr", "AssRe", "AssPr")


def hota_fields(data: SequenceData) -> dict:
    """HOTA per-threshold arrays of one sequence.

    Args:
        data: the scored boxes.

    Returns:
        ``[19]`` arrays: ``HOTA_TP, HOTA_FN, HOTA_FP`` (counts, as floats), ``AssA, AssRe,
        AssPr, LocA`` (per-sequence values, combined weighted by ``HOTA_TP`` as TrackEval
        does).
    """
    pairs, similarity = data.pairs, data.similarity
    num_gt_rows, num_tracker_rows = data.num_rows
    gt_count = np.bincount(data.gt_id, minlength=data.num_gt_ids).astype(float)
    tracker_count = np.bincount(data.tracker_id, minlength=data.num_tracker_ids).astype(float)
    gt_id = data.gt_id[pairs.gt_row]
    tracker_id = data.tracker_id[pairs.tracker_row]

    row_sum = np.bincount(pairs.gt_row, weights=similarity, minlength=num_gt_rows)
    col_sum = np.bincount(pairs.tracker_row, weights=similarity, minlength=num_tracker_rows)
    denominator = col_sum[pairs.tracker_row] + row_sum[pairs.gt_row] - similarity
    normalised = np.zeros_like(similarity)
    positive = denominator > EPS
    normalised[positive] = similarity[positive] / denominator[positive]
    codes, pair_object = np.unique(
        gt_id * max(data.num_tracker_ids, 1) + tracker_id, return_inverse=True
    )
    overlap = np.bincount(pair_object, weights=normalised, minlength=codes.size)
    code_gt, code_tracker = np.divmod(codes, max(data.num_tracker_ids, 1))
    alignment = overlap / (gt_count[code_gt] + tracker_count[code_tracker] - overlap)

    score = alignment[pair_object] * similarity
    matched = assign_frames(pairs, score, score > 0, data.num_rows)
    matched_similarity = similarity[matched]
    is_tp = matched_similarity[:, None] >= ALPHAS[None, :] - EPS
    tp = is_tp.sum(axis=0).astype(float)
    loc_sum = np.sum(np.where(is_tp, matched_similarity[:, None], 0.0), axis=0)

    objects, matched_object = np.unique(pair_object[matched], return_inverse=True)
    num_alphas = ALPHAS.size
    tp_per_object = np.bincount(
        (matched_object[:, None] * num_alphas + np.arange(num_alphas))[is_tp],
        minlength=objects.size * num_alphas,
    ).reshape(objects.size, num_alphas)
    object_gt = gt_count[code_gt[objects]][:, None]
    object_tracker = tracker_count[code_tracker[objects]][:, None]
    ass_a = tp_per_object / np.maximum(1, object_gt + object_tracker - tp_per_object)
    ass_re = tp_per_object / np.maximum(1, object_gt)
    ass_pr = tp_per_object / np.maximum(1, object_tracker)
    safe_tp = np.maximum(1, tp)
    return {
        "HOTA_TP": tp,
        "HOTA_FN": num_gt_rows - tp,
        "HOTA_FP": num_tracker_rows - tp,
        "AssA": np.sum(tp_per_object * ass_a, axis=0) / safe_tp,
        "AssRe": np.sum(tp_per_object * ass_re, axis=0) / safe_tp,
        "AssPr": np.sum(tp_per_object * ass_pr, axis=0) / safe_tp,
        "LocA": np.maximum(1e-10, loc_sum) / np.maximum(1e-10, tp),
    }


def combine_hota(all_fields: list[dict]) -> dict:
    """Combines per-sequence HOTA arrays (TrackEval's ``combine_sequences``).

    Counts are summed; ``AssA, AssRe, AssPr`` and ``LocA`` are averaged weighted by
    ``HOTA_TP``.
    """
    combined = {
        key: sum(fields[key] for fields in all_fields) for key in ("HOTA_TP", "HOTA_FN", "HOTA_FP")
    }
    tp = combined["HOTA_TP"]
    for key in ("AssA", "AssRe", "AssPr"):
        combined[key] = sum(f[key] * f["HOTA_TP"] for f in all_fields) / np.maximum(1.0, tp)
    loc_sum = sum(f["LocA"] * f["HOTA_TP"] for f in all_fields)
    combined["LocA"] = np.maximum(1e-10, loc_sum) / np.maximum(1e-10, tp)
    return combined


def hota_arrays(fields: dict) -> dict:
    """Per-threshold ``[19]`` arrays of every HOTA score."""
    tp, fn, fp = fields["HOTA_TP"], fields["HOTA_FN"], fields["HOTA_FP"]
    det_a = tp / np.maximum(1, tp + fn + fp)
    return {
        "HOTA": np.sqrt(det_a * fields["AssA"]),
        "DetA": det_a,
        "AssA": fields["AssA"],
        "LocA": fields["LocA"],
        "DetRe": tp / np.maximum(1, tp + fn),
        "DetPr": tp / np.maximum(1, tp + fp),
        "AssRe": fields["AssRe"],
        "AssPr": fields["AssPr"],
    }


def hota_scores(fields: dict) -> dict:
    """HOTA scores averaged over the 19 thresholds (what TrackEval's summary reports)."""
    return {key: float(np.mean(values)) for key, values in hota_arrays(fields).items()}
