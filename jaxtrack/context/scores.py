"""The detector's score calibration ``p(target | s)``, learned on a training span.

A detector's confidence ``s`` is a probability only if the detector is calibrated. The PHD
tracker's evidence confirmation (:func:`~jaxtrack.association.labelling.confirm_by_evidence`)
adds up the log-odds ``logit p(target | s)`` of the detections a track holds, so it needs
that probability, and detectors differ: on the MOT15 training sequences (Faster R-CNN
boxes) a detection scoring 0.9 is a target about half the time (PETS09-S2L1 1:397: 0.48),
while the synthetic scenes' detector is under-confident (0.97-0.99 at 0.9). Reading raw
scores as probabilities confirms the MOT15 detector's recurring false positives within two
frames (combined MOTA over the second halves of the 11 sequences 49.3 -> 43.1), reading
them calibrated does not (49.3).

**Learning** (:func:`learn_score_calibration`): every detection of the span is labelled a
target when the per-frame one-to-one mapping to the ground truth at IoU 0.5 matches it
(:func:`~jaxtrack.context.samples.matched_detections`, the mapping that makes the clutter
events), else not; ``p(target | s)`` is the isotonic (non-decreasing) least-squares fit of
the labels on the scores (pool-adjacent-violators, ``scipy.optimize.isotonic_regression``,
equal scores pooled first), the non-parametric maximum-likelihood estimate of a monotone
calibration curve. It is stored at :data:`NUM_KNOTS` knots evenly spaced in ``logit(s)``
over ``[-8, 8]`` (linear interpolation between them, the end values beyond), clipped to
``[FLOOR, 1 - FLOOR]`` so that no single detection proves or disproves a target. With fewer
than :data:`MIN_DETECTIONS` detections, or without both targets and non-targets, nothing is
learned.

The identity calibration (:func:`identity_calibration`, ``p = s`` at the knots) is the
tracker's default: scores read as probabilities.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from jaxtyping import Array, Float
from scipy.optimize import isotonic_regression

#: Knots of a calibration curve, evenly spaced in ``logit(s)`` over ``[-KNOT_LOGIT, KNOT_LOGIT]``.
NUM_KNOTS = 33
KNOT_LOGIT = 8.0
#: Learned probabilities are clipped to ``[FLOOR, 1 - FLOOR]``.
FLOOR = 0.01
#: Fewest labelled detections a calibration is learned from.
MIN_DETECTIONS = 50


class ScoreCalibration(NamedTuple):
    """A monotone map from detector scores to ``p(target | s)``, piecewise linear.

    Attributes:
        scores: the knots, increasing, in ``(0, 1)``.
        probabilities: ``p(target | s)`` at the knots, non-decreasing, in ``[0, 1]``.
    """

    scores: Float[Array, " num_knots"]
    probabilities: Float[Array, " num_knots"]


def knot_scores() -> np.ndarray:
    """The :data:`NUM_KNOTS` knot scores ``sigmoid(t)``, ``t`` evenly spaced in
    ``[-KNOT_LOGIT, KNOT_LOGIT]`` (float32)."""
    logits = np.linspace(-KNOT_LOGIT, KNOT_LOGIT, NUM_KNOTS)
    return (1.0 / (1.0 + np.exp(-logits))).astype(np.float32)


def identity_calibration() -> ScoreCalibration:
    """Scores read as probabilities: ``p(target | s) = s`` at every knot."""
    knots = knot_scores()
    return ScoreCalibration(knots, knots.copy())


def learn_score_calibration(
    scores: np.ndarray, is_target: np.ndarray
) -> tuple[ScoreCalibration | None, dict]:
    """The isotonic fit of ``p(target | s)`` (module docstring).

    Args:
        scores: detection scores.
        is_target: True for the detections of targets.

    Returns:
        The calibration at the knots (None when too few or one-sided labels) and a
        JSON-serialisable summary: ``detections``, ``target_share``, ``learned`` and, when
        learned, ``p_at`` (the calibrated probability at scores 0.5, 0.7, 0.9, 0.97, 0.99).
    """
    scores = np.asarray(scores, np.float64)
    is_target = np.asarray(is_target, bool)
    if scores.shape != is_target.shape:
        raise ValueError(f"{scores.shape} scores but {is_target.shape} labels")
    summary = {
        "detections": int(scores.size),
        "target_share": float(is_target.mean()) if scores.size else None,
    }
    if scores.size < MIN_DETECTIONS or is_target.all() or not is_target.any():
        return None, {**summary, "learned": False}
    unique, inverse, counts = np.unique(scores, return_inverse=True, return_counts=True)
    shares = np.bincount(inverse, weights=is_target) / counts
    fitted = isotonic_regression(shares, weights=counts.astype(np.float64), increasing=True).x
    knots = knot_scores()
    probabilities = np.clip(np.interp(knots, unique, fitted), FLOOR, 1 - FLOOR)
    calibration = ScoreCalibration(knots, probabilities.astype(np.float32))
    probe = (0.5, 0.7, 0.9, 0.97, 0.99)
    values = np.interp(probe, knots, calibration.probabilities)
    p_at = {f"{s:g}": round(float(p), 3) for s, p in zip(probe, values, strict=True)}
    return calibration, {**summary, "learned": True, "p_at": p_at}


def calibration_from_metadata(metadata: dict) -> ScoreCalibration | None:
    """The calibration a context's metadata records (``score_calibration``), or None."""
    record = metadata.get("score_calibration") or {}
    if "probabilities" not in record:
        return None
    return ScoreCalibration(
        np.asarray(record["scores"], np.float32), np.asarray(record["probabilities"], np.float32)
    )


def invalid_calibration(record: object) -> str | None:
    """Why a context's ``score_calibration`` metadata cannot be used, or None when it can."""
    if not isinstance(record, dict):
        return "score_calibration must be a JSON object"
    if "probabilities" not in record and "scores" not in record:
        return None
    try:
        knots = np.asarray(record["scores"], np.float64)
        probabilities = np.asarray(record["probabilities"], np.float64)
    except (KeyError, TypeError, ValueError):
        return "score_calibration needs numeric 'scores' and 'probabilities' lists"
    if knots.ndim != 1 or knots.shape != probabilities.shape or knots.size < 2:
        return "score_calibration 'scores' and 'probabilities' must be lists of one length >= 2"
    if not (np.all(np.isfinite(knots)) and np.all(np.isfinite(probabilities))):
        return "score_calibration values must be finite"
    if np.any(np.diff(knots) <= 0) or knots[0] <= 0 or knots[-1] >= 1:
        return "score_calibration 'scores' must increase inside (0, 1)"
    if np.any(np.diff(probabilities) < 0) or probabilities[0] < 0 or probabilities[-1] > 1:
        return "score_calibration 'probabilities' must be non-decreasing inside [0, 1]"
    return None
