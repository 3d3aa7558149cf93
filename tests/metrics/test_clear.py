"""CLEAR MOT conventions on hand-worked sequences (TrackEval's, including its quirks)."""

from __future__ import annotations

import numpy as np
import pytest

from jaxtrack.io import MotTable
from jaxtrack.metrics import evaluate_sequence


def table(rows) -> MotTable:
    """Rows ``(frame, id, x, y, w, h)``."""
    rows = np.asarray(rows, dtype=float).reshape(-1, 6)
    return MotTable.from_arrays(rows[:, 0], rows[:, 1], rows[:, 2:6])


def test_continuity_beats_higher_overlap():
    # Two gt objects side by side; in frame 2 tracker 1 overlaps B better than A, but both
    # pairs stay above 0.5, so the frame-1 correspondences are kept: no identity switch.
    gt = table(
        [(1, 1, 0, 0, 10, 10), (1, 2, 4, 0, 10, 10), (2, 1, 0, 0, 10, 10), (2, 2, 4, 0, 10, 10)]
    )
    result = table(
        [(1, 1, 0, 0, 10, 10), (1, 2, 4, 0, 10, 10), (2, 1, 3, 0, 10, 10), (2, 2, 1, 0, 10, 10)]
    )
    scores = evaluate_sequence(gt, result, (1, 2)).scores()
    assert scores["IDSW"] == 0 and scores["TP"] == 4
    # IoUs kept in frame 2: A-1 = 7/13, B-2 = 7/13 (the swap would give 9/11 and 9/11).
    assert scores["MOTP"] == pytest.approx((1 + 1 + 7 / 13 + 7 / 13) / 4)
    # The detection mapping (MODP) ignores identities and takes the larger overlaps.
    assert scores["MODP"] == pytest.approx((1 + 1 + 9 / 11 + 9 / 11) / 4)


def test_id_switch_counts_against_last_match_any_frames_before():
    # Object matched to 1 in frame 1, missed in frames 2-3, matched to 2 in frame 4.
    gt = table([(f, 1, 0, 0, 10, 10) for f in range(1, 5)])
    result = table([(1, 1, 0, 0, 10, 10), (4, 2, 0, 0, 10, 10)])
    scores = evaluate_sequence(gt, result, (1, 4)).scores()
    assert scores["IDSW"] == 1 and scores["FN"] == 2


def test_fragmentation_counts_only_frames_with_tracker_output():
    gt = table([(f, 1, 0, 0, 10, 10) for f in range(1, 6)])
    tracked = [(f, 1, 0, 0, 10, 10) for f in (1, 2, 4, 5)]
    # Frame 3 without any tracker box: TrackEval does not see the interruption.
    quiet = evaluate_sequence(gt, table(tracked), (1, 5)).scores()
    assert quiet["Frag"] == 0 and quiet["FN"] == 1
    # Frame 3 with a tracker box elsewhere: the track is interrupted, one fragmentation.
    busy = evaluate_sequence(gt, table([*tracked, (3, 9, 50, 50, 10, 10)]), (1, 5)).scores()
    assert busy["Frag"] == 1 and busy["FN"] == 1 and busy["FP"] == 1


@pytest.mark.parametrize(("tracked", "category"), [(9, "MT"), (8, "PT"), (2, "PT"), (1, "ML")])
def test_mostly_partly_lost_boundaries(tracked, category):
    gt = table([(f, 1, 0, 0, 10, 10) for f in range(1, 11)])
    result = table([(f, 1, 0, 0, 10, 10) for f in range(1, tracked + 1)])
    scores = evaluate_sequence(gt, result, (1, 10)).scores()
    assert {key: scores[key] for key in ("MT", "PT", "ML")} == {
        key: int(key == category) for key in ("MT", "PT", "ML")
    }
