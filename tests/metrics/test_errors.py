"""Kinds of misses and false positives (:mod:`jaxtrack.metrics.errors`): a hand-built frame
with one case of every kind, and properties on PETS09-S2L1 whose answers follow from the
definitions."""

from __future__ import annotations

import numpy as np
import pytest

from jaxtrack.errors import InputError
from jaxtrack.io import read_mot_file
from jaxtrack.metrics.detection import true_identity_rows
from jaxtrack.metrics.errors import FN_KINDS, FP_KINDS, classify_errors
from jaxtrack.metrics.evaluate import evaluate_sequence
from jaxtrack.types import MotTable

SIZE = [10.0, 10.0]


def _table(rows, ids=None, confs=None):
    frames = [r[0] for r in rows]
    ids = np.arange(len(rows)) + 1 if ids is None else ids
    return MotTable.from_arrays(frames, ids, [[r[1], r[2], *SIZE] for r in rows], confs=confs)


def _scene():
    """Frame 1 holds objects A-E 100 px apart (10 x 10 boxes) and F, marked ignored.
    Shifting a box by 4 px gives IoU 6/14 = 0.43: overlapping, not matching."""
    gt = _table(
        [(1, 0, 0), (1, 100, 0), (1, 200, 0), (1, 300, 0), (1, 400, 0), (1, 700, 0)],
        ids=[11, 12, 13, 14, 15, 16],
        confs=[1, 1, 1, 1, 1, 0],
    )
    det = _table(
        [
            (1, 0, 0),  # A, exact
            (1, 204, 0),  # C, misplaced
            (1, 300, 0),  # D, exact
            (1, 400, 0),  # E, exact
            (1, 500, 0),  # a false alarm
            (1, 700, 0),  # on the ignored F
        ]
    )
    out = _table(
        [
            (1, 0, 0),  # A matched
            (1, 2, 0),  # a second box on A (IoU 0.67, but A is taken)
            (1, 304, 0),  # D, misplaced
            (1, 500, 0),  # follows the false alarm
            (1, 700, 0),  # follows the detection of the ignored F
            (1, 600, 0),  # on nothing
        ],
        ids=[1, 2, 4, 5, 6, 7],
    )
    return gt, det, out


def test_each_kind_on_a_hand_built_frame():
    gt, det, out = _scene()
    table = classify_errors(gt, out, det, (1, 1))
    fn = dict(zip(table.fn_gt_id.tolist(), (FN_KINDS[k] for k in table.fn_kind), strict=True))
    assert fn == {
        12: "not_detected",
        13: "detection_misplaced",
        14: "output_misplaced",
        15: "dropped",
    }
    fp = dict(zip(table.fp_track_id.tolist(), (FP_KINDS[k] for k in table.fp_kind), strict=True))
    assert fp == {2: "duplicate", 4: "misplaced", 5: "clutter", 6: "clutter", 7: "phantom"}
    assert set(table.fn_frame.tolist()) == set(table.fp_frame.tolist()) == {1}
    summary = evaluate_sequence(gt, out, (1, 1)).summary()
    assert (summary["FN"], summary["FP"]) == (4, 5)


def test_near_moves_the_overlap_line():
    gt, det, out = _scene()
    # at 0.5 a 4 px shift no longer overlaps: C undetected, D's box dropped, its box phantom
    counts = classify_errors(gt, out, det, (1, 1), near=0.5).counts()
    assert counts["FN"] == {
        "not_detected": 2,
        "detection_misplaced": 0,
        "output_misplaced": 0,
        "dropped": 2,
    }
    assert counts["FP"] == {"misplaced": 0, "duplicate": 1, "clutter": 2, "phantom": 2}
    with pytest.raises(InputError, match="near"):
        classify_errors(gt, out, det, (1, 1), near=0.6)


def _pets(mot15_root, span):
    sequence = mot15_root / "PETS09-S2L1"
    gt = read_mot_file(sequence / "gt" / "gt.txt", "gt").frame_span(*span)
    det = read_mot_file(sequence / "det" / "det.txt", "det").frame_span(*span)
    return gt, det


def test_perfectly_associated_detections_miss_only_what_the_detector_missed(mot15_root):
    """One output box per well-detected object, on it: on this span every box is matched, so
    the misses are the detector's alone."""
    span = (1, 200)
    gt, det = _pets(mot15_root, span)
    rows = true_identity_rows(det, gt, span)
    counts = classify_errors(gt, rows, det, span).counts()
    summary = evaluate_sequence(gt, rows, span).summary()
    assert summary["FP"] == 0 and sum(counts["FP"].values()) == 0
    assert counts["FN"]["output_misplaced"] == counts["FN"]["dropped"] == 0
    assert counts["FN"]["not_detected"] > 0 and counts["FN"]["detection_misplaced"] > 0
    assert sum(counts["FN"].values()) == summary["FN"]


def test_detections_as_output_leave_no_phantom_and_add_up(mot15_root):
    """Every detection output as a one-frame track: an unmatched one overlaps itself (a
    detection), so it is misplaced, a duplicate or clutter, never a phantom; and the kinds add
    up to FN and FP."""
    span = (1, 200)
    gt, det = _pets(mot15_root, span)
    out = MotTable.from_arrays(det.frames, np.arange(len(det)), det.boxes)
    counts = classify_errors(gt, out, det, span).counts()
    summary = evaluate_sequence(gt, out, span).summary()
    assert counts["FP"]["phantom"] == 0
    assert sum(counts["FP"].values()) == summary["FP"] > 0
    assert sum(counts["FN"].values()) == summary["FN"] > 0
