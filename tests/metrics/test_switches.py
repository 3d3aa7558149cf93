"""Identity-switch kinds on hand-built sequences whose story is known, and their total."""

from __future__ import annotations

import numpy as np
import pytest

from jaxtrack.io import MotTable
from jaxtrack.metrics import combine_sequences, evaluate_sequence, switch_table
from jaxtrack.metrics.switches import KINDS

# Two objects far apart: A at x = 0, B at x = 100 (10 x 10 boxes); ids 7 and 8 in the gt.
A, B = 0, 100


def table(rows) -> MotTable:
    """Rows ``(frame, id, x)``: a 10 x 10 box at ``(x, 0)``."""
    rows = np.asarray(rows, dtype=float).reshape(-1, 3)
    boxes = np.column_stack([rows[:, 2], np.zeros(len(rows)), np.full((len(rows), 2), 10.0)])
    return MotTable.from_arrays(rows[:, 0], rows[:, 1], boxes)


def one_object() -> MotTable:
    """Object A alone (gt id 7), frames 1-10."""
    return table([(f, 7, A) for f in range(1, 11)])


def both_objects(frames=range(1, 11)) -> MotTable:
    return table([(f, 7, A) for f in frames] + [(f, 8, B) for f in frames])


def rows_of(switches) -> list[tuple]:
    return sorted(
        (r["frame"], r["gt_id"], r["from_id"], r["to_id"], r["kind"]) for r in switches.rows()
    )


def test_exchange_two_tracks_trade_objects():
    # Track 1 on A and track 2 on B for frames 1-5, then the other way round.
    result = table(
        [(f, 1, A if f <= 5 else B) for f in range(1, 11)]
        + [(f, 2, B if f <= 5 else A) for f in range(1, 11)]
    )
    switches = switch_table(both_objects(), result, (1, 10))
    assert rows_of(switches) == [(6, 7, 1, 2, "exchange"), (6, 8, 2, 1, "exchange")]


def test_drift_old_track_leaves_for_an_untracked_object():
    # B is untracked until track 1 leaves A for it at frame 6; a new track 2 picks A up.
    result = table(
        [(f, 1, A if f <= 5 else B) for f in range(1, 11)] + [(f, 2, A) for f in range(6, 11)]
    )
    switches = switch_table(both_objects(), result, (1, 10))
    assert rows_of(switches) == [(6, 7, 1, 2, "drift")]


def test_takeover_new_track_comes_from_another_object():
    # Track 1 on A ends at frame 5; track 2 follows B and moves to A at frame 6.
    result = table(
        [(f, 1, A) for f in range(1, 6)] + [(f, 2, B if f <= 5 else A) for f in range(1, 11)]
    )
    switches = switch_table(both_objects(), result, (1, 10))
    assert rows_of(switches) == [(6, 7, 1, 2, "takeover")]


def test_lost_track_ends_and_a_new_one_starts():
    # A tracked by 1 for frames 1-4, nothing in 5-6, a new track 2 from frame 7.
    gt = one_object()
    result = table([(f, 1, A) for f in range(1, 5)] + [(f, 2, A) for f in range(7, 11)])
    switches = switch_table(gt, result, (1, 10))
    assert rows_of(switches) == [(7, 7, 1, 2, "lost")]
    assert switches.gap.tolist() == [3]  # last match at frame 4, next at frame 7


def test_replaced_old_track_stays_on_nothing():
    # Track 1 slides off A onto empty ground at frame 6 (IoU 0 with every object) and stays
    # there; a second track 2 takes A.
    gt = one_object()
    result = table(
        [(f, 1, A if f <= 5 else 50) for f in range(1, 11)] + [(f, 2, A) for f in range(6, 11)]
    )
    switches = switch_table(gt, result, (1, 10))
    assert rows_of(switches) == [(6, 7, 1, 2, "replaced")]


def test_ids_are_the_files_and_frames_are_one_based_in_a_span():
    gt = table([(f, 42, A) for f in range(11, 21)])
    result = table([(f, 5, A) for f in range(11, 15)] + [(f, 9, A) for f in range(15, 21)])
    switches = switch_table(gt, result, (11, 20))
    assert rows_of(switches) == [(15, 42, 5, 9, "lost")]


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_kinds_add_up_to_idsw_on_random_tracks(seed):
    # Random trackers over a handful of slowly moving objects: ids flip at random, tracks
    # stop and restart, boxes jitter across the IoU threshold. Every switch gets exactly one
    # kind, so the kinds add up to the CLEAR count.
    rng = np.random.default_rng(seed)
    num_frames, num_objects = 60, 5
    gt_rows, res_rows = [], []
    owner = np.arange(num_objects)
    next_id = num_objects
    for f in range(1, num_frames + 1):
        for k in range(num_objects):
            if rng.random() < 0.1:  # a new identity, or an exchange with a neighbour
                if rng.random() < 0.5:
                    owner[k], next_id = next_id, next_id + 1
                else:
                    j = (k + 1) % num_objects
                    owner[k], owner[j] = owner[j], owner[k]
        for k in range(num_objects):
            x = 30.0 * k + 0.3 * f
            gt_rows.append((f, 100 + k, x))
            if rng.random() < 0.85:
                res_rows.append((f, owner[k], x + rng.normal(0, 3)))
    gt, result = table(gt_rows), table(res_rows)
    switches = switch_table(gt, result, (1, num_frames))
    idsw = evaluate_sequence(gt, result, (1, num_frames)).scores()["IDSW"]
    assert idsw > 5
    assert len(switches.frame) == idsw == sum(switches.counts().values())
    assert set(switches.counts()) == set(KINDS)
    assert switches.counts()["exchange"] > 0 and switches.counts()["lost"] > 0
    assert np.all(switches.gap >= 1)


def test_evaluation_reports_the_counts_and_combines_them():
    exchange = table(
        [(f, 1, A if f <= 5 else B) for f in range(1, 11)]
        + [(f, 2, B if f <= 5 else A) for f in range(1, 11)]
    )
    lost = table([(f, 1, A) for f in range(1, 5)] + [(f, 2, A) for f in range(7, 11)])
    first = evaluate_sequence(both_objects(), exchange, (1, 10))
    second = evaluate_sequence(one_object(), lost, (1, 10))
    assert first.switches == {**dict.fromkeys(KINDS, 0), "exchange": 2}
    combined = combine_sequences([first, second]).scores()
    kinds = {key: value for key, value in combined.items() if key.startswith("IDSW_")}
    assert kinds == {f"IDSW_{kind}": {"exchange": 2, "lost": 1}.get(kind, 0) for kind in KINDS}
    assert sum(kinds.values()) == combined["IDSW"] == 3
