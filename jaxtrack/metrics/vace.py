"""VACE / CLEAR-2007 detection and tracking scores: MODA, MODP and their per-frame forms.

The PHD-context paper (Maggio & Cavallaro, Sec. V-A, eqs. 22-25) evaluates with the VACE
protocol of CLEAR 2007 (Kasturi et al., "Framework for performance evaluation of face, text,
and vehicle detection and tracking in video", PAMI 2009). Definitions used here, with unit
costs ``c_m = c_f = 1``:

**Detection mapping** (identities ignored), per frame ``t``: a one-to-one mapping between gt
boxes and tracker boxes using only pairs with ``sim >= threshold``; among such mappings the
one with the most pairs, ties broken by the largest summed similarity (so that misses plus
false positives are minimal). ``N_m(t)`` mapped pairs with summed overlap ``O(t)``, ``N_G(t)``
gt boxes, ``m(t) = N_G(t) - N_m(t)`` misses, ``fp(t)`` unmapped tracker boxes.

* ``MODP(t) = O(t) / N_m(t)`` (eq. 22) and ``MODA(t) = 1 - (m(t) + fp(t)) / N_G(t)`` (eq. 23).
* ``MODA = 1 - sum_t (m(t) + fp(t)) / sum_t N_G(t)`` and ``MODP = sum_t O(t) / sum_t N_m(t)``
  (pooled over frames: Kasturi et al.'s N-MODA, and the mean overlap of all mapped pairs).
* ``VACE_MODA``: ``MODA(t)`` averaged over the frames where it is defined (``N_G(t) > 0``);
  false positives in frames without gt are thus not seen by it (they are by MODA).
* ``VACE_MODP``: ``MODP(t)`` averaged over the frames where it is defined (``N_m(t) > 0``).
  (The paper averages "over the number of frames of the evaluation segment"; frames where the
  per-frame ratio is 0/0 are left out.)

**Tracking accuracy**, from the CLEAR MOT matching (identity continuity, see
:mod:`jaxtrack.metrics.clear`) with per-frame misses ``fn(t)``, false positives ``fp(t)`` and
identity switches ``idsw(t)``:

* ``VACE_MOTA = 1 - sum_t (fn(t) + fp(t) + log10(idsw(t))) / sum_t N_G(t)`` (eq. 25), the log
  term only for frames with ``idsw(t) > 0``. SPEC.md §1 specifies base 10, the default here;
  eq. 25 of the PHD-context paper prints the natural log (``log_base=math.e`` gives that
  form). A single switch in a frame costs nothing (``log 1 = 0``).

Ratios with a zero denominator are 0 (as TrackEval's ``max(1, .)``); a sequence without gt
boxes has MODA and VACE_MOTA 0 (like TrackEval's MOTA).
"""

from __future__ import annotations

import numpy as np

from jaxtrack.metrics.clear import ClearMatching
from jaxtrack.metrics.matching import EPS, assign_frames
from jaxtrack.metrics.preprocess import SequenceData

#: Fields summed when sequences are combined.
ADDITIVE_FIELDS = (
    "num_gt",
    "misses",
    "false_positives",
    "mapped",
    "overlap_sum",
    "moda_frame_sum",
    "moda_frames",
    "modp_frame_sum",
    "modp_frames",
    "mota_penalty",
)


def detection_mapping(data: SequenceData, threshold: float = 0.5) -> np.ndarray:
    """Per-frame detection mapping (no identities): most pairs, then largest summed overlap.

    Args:
        data: the scored boxes.
        threshold: minimum similarity of a mapped pair, in ``(0, 1]``.

    Returns:
        ``[P]`` boolean mask of mapped pairs.
    """
    pairs, similarity = data.pairs, data.similarity
    candidate = (similarity >= threshold - EPS) & (similarity > EPS)
    size = np.minimum(pairs.num_gt, pairs.num_tracker)[pairs.frame]
    score = np.where(candidate, 1.0 + similarity / (1.0 + size), 0.0)
    return assign_frames(pairs, score, candidate, data.num_rows)


def vace_fields(
    data: SequenceData,
    mapped: np.ndarray,
    clear: ClearMatching,
    log_base: float = 10.0,
) -> dict:
    """Additive VACE fields of one sequence.

    Args:
        data: the scored boxes.
        mapped: from :func:`detection_mapping`.
        clear: the CLEAR MOT matching (for VACE_MOTA).
        log_base: base of the identity-switch logarithm in VACE_MOTA.

    Returns:
        Sums and frame counts listed in ``ADDITIVE_FIELDS``.
    """
    pairs = data.pairs
    num_gt, num_tracker = pairs.num_gt, pairs.num_tracker
    mapped_t = np.bincount(pairs.frame[mapped], minlength=data.num_frames)
    overlap_t = np.bincount(
        pairs.frame[mapped], weights=data.similarity[mapped], minlength=data.num_frames
    )
    errors_t = (num_gt - mapped_t) + (num_tracker - mapped_t)
    with_gt = num_gt > 0
    with_map = mapped_t > 0
    switches = clear.id_switches
    log_switches = np.log(np.where(switches > 0, switches, 1)) / np.log(log_base)
    tracking_errors = (num_gt - clear.matches) + (num_tracker - clear.matches)
    return {
        "num_gt": int(num_gt.sum()),
        "misses": int((num_gt - mapped_t).sum()),
        "false_positives": int((num_tracker - mapped_t).sum()),
        "mapped": int(mapped_t.sum()),
        "overlap_sum": float(overlap_t.sum()),
        "moda_frame_sum": float(np.sum(1.0 - errors_t[with_gt] / num_gt[with_gt])),
        "moda_frames": int(with_gt.sum()),
        "modp_frame_sum": float(np.sum(overlap_t[with_map] / mapped_t[with_map])),
        "modp_frames": int(with_map.sum()),
        "mota_penalty": float(tracking_errors.sum() + log_switches.sum()),
    }


def vace_scores(fields: dict, single_sequence: bool = True) -> dict:
    """``MODA, MODP, VACE_MODA, VACE_MODP, VACE_MOTA`` from (summed) fields.

    Args:
        fields: from :func:`vace_fields` or their sums over sequences.
        single_sequence: True for one sequence: MODA and VACE_MOTA are 0 without gt boxes.
    """
    num_gt = fields["num_gt"]
    no_gt = single_sequence and num_gt == 0
    errors = fields["misses"] + fields["false_positives"]
    return {
        "MODA": 0.0 if no_gt else 1.0 - errors / max(1.0, num_gt),
        "MODP": fields["overlap_sum"] / max(1.0, fields["mapped"]),
        "VACE_MODA": fields["moda_frame_sum"] / max(1.0, fields["moda_frames"]),
        "VACE_MODP": fields["modp_frame_sum"] / max(1.0, fields["modp_frames"]),
        "VACE_MOTA": 0.0 if no_gt else 1.0 - fields["mota_penalty"] / max(1.0, num_gt),
    }
