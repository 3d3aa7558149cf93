"""CMT's OE, DE, SE: hand-built cases, a loop-based reference, pooling and the eval CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest

from jaxtrack.cli import main
from jaxtrack.errors import InputError
from jaxtrack.io import MotTable, write_mot_file
from jaxtrack.metrics import EvalConfig, combine_sequences, evaluate_sequence
from jaxtrack.metrics.clear import clear_matching
from jaxtrack.metrics.cmt import (
    DEFAULT_TOLERANCE,
    cmt_fields,
    crossing_swap_fields,
    crossing_swap_rate,
)
from jaxtrack.metrics.preprocess import prepare_sequence
from jaxtrack.metrics.synthetic import SCENARIOS, corrupt

SIZE = 10.0


def table(rows) -> MotTable:
    """Rows ``(frame, id, x, y)`` of 10x10 boxes."""
    rows = np.asarray(rows, dtype=float).reshape(-1, 4)
    boxes = np.c_[rows[:, 2:4], np.full((len(rows), 2), SIZE)]
    return MotTable.from_arrays(rows[:, 0], rows[:, 1], boxes)


def walker(identity: int, frames, y: float = 0.0, step: float = 2.0) -> list:
    """A target walking right by ``step`` pixels a frame on row ``y``."""
    return [(f, identity, step * f, y) for f in frames]


def cmt(gt, result, span, tolerance=DEFAULT_TOLERANCE) -> dict:
    scores = evaluate_sequence(gt, result, span, EvalConfig(delay_tolerance=tolerance)).scores()
    return {key: value for key, value in scores.items() if key[:2] in ("OE", "DE", "SE")}


def test_perfect_tracker_scores_zero_and_counts_entries_and_exits():
    # 1 is there from frame 1 to the end, 2 enters at 5, 3 exits at 12, 4 enters and exits.
    rows = [
        *walker(1, range(1, 21)),
        *walker(2, range(5, 21), y=50),
        *walker(3, range(1, 13), y=100),
        *walker(4, range(8, 16), y=150),
    ]
    scores = cmt(table(rows), table(rows), (1, 20))
    assert scores["OE"] == scores["DE"] == scores["SE"] == 0.0
    assert (scores["DE_entering"], scores["DE_exiting"]) == (2, 2)


@pytest.mark.parametrize("k", [2, 7, 10])
def test_one_swap_is_one_swap_frame(k):
    # Two parallel walkers; from frame k the tracker's ids are exchanged.
    gt = table([*walker(1, range(1, 11)), *walker(2, range(1, 11), y=50)])
    result = table(
        [(f, 1 if f < k else 2, 2.0 * f, 0.0) for f in range(1, 11)]
        + [(f, 2 if f < k else 1, 2.0 * f, 50.0) for f in range(1, 11)]
    )
    scores = cmt(gt, result, (1, 10))
    assert scores["SE"] == pytest.approx(1 / 10) and scores["SE_frames"] == 1
    # the swap frame is the only falsely tracked one: the new correspondences hold after it
    assert scores["OE"] == pytest.approx(1 / 10) and scores["DE"] == 0.0


def test_a_miss_or_a_false_track_makes_a_false_frame():
    gt = table(walker(1, range(1, 11)))
    missed = table([row for row in walker(1, range(1, 11)) if row[0] != 4])
    ghost = table([*walker(1, range(1, 11)), (6, 9, 300.0, 300.0), (7, 9, 300.0, 300.0)])
    assert cmt(gt, missed, (1, 10))["OE_frames"] == 1
    scores = cmt(gt, ghost, (1, 10))
    assert scores["OE"] == pytest.approx(2 / 10) and scores["SE"] == 0.0


@pytest.mark.parametrize(("delay", "late"), [(0, 0), (3, 0), (4, 1)])
def test_pick_up_within_the_tolerance(delay, late):
    # Target enters at frame 5; the tracker first follows it at frame 5 + delay.
    gt = table(walker(1, range(5, 21)))
    result = table(walker(7, range(5 + delay, 21)))
    scores = cmt(gt, result, (1, 20), tolerance=3)
    assert scores["DE_late_pickups"] == late and scores["DE_entering"] == 1
    assert scores["DE_exiting"] == 0 and scores["DE"] == late


def test_a_target_never_picked_up_is_late_and_one_there_from_the_start_is_not_entering():
    gt = table([*walker(1, range(1, 21)), *walker(2, range(6, 21), y=50)])
    scores = cmt(gt, table(walker(7, range(1, 21))), (1, 20))
    assert (scores["DE_entering"], scores["DE_late_pickups"]) == (1, 1)
    assert scores["DE"] == 1.0


@pytest.mark.parametrize(("ghost_frames", "late"), [(0, 0), (3, 0), (4, 1), (6, 1)])
def test_release_within_the_tolerance(ghost_frames, late):
    # Target exits after frame 10; its track stays where it was for ghost_frames frames.
    gt = table(walker(1, range(1, 11)))
    tail = [(11 + i, 7, 20.0, 0.0 + 30.0) for i in range(ghost_frames)]
    result = table([*walker(7, range(1, 11)), *tail])
    scores = cmt(gt, result, (1, 30), tolerance=3)
    assert scores["DE_exiting"] == 1 and scores["DE_late_releases"] == late
    assert scores["DE"] == late


def test_a_track_taken_over_by_another_target_is_released():
    # Track 7 follows target 1 until frame 10, then (switch) target 2 from frame 11 on.
    gt = table([*walker(1, range(1, 11)), *walker(2, range(1, 21), y=50)])
    result = table(
        [*walker(7, range(1, 11)), *walker(8, range(1, 11), y=50), *walker(7, range(11, 21), y=50)]
    )
    scores = cmt(gt, result, (1, 20), tolerance=2)
    assert scores["DE_late_releases"] == 0 and scores["DE_exiting"] == 1
    assert scores["SE_frames"] == 1  # target 2 switches from track 8 to track 7


def test_a_release_window_past_the_span_is_not_late():
    gt = table(walker(1, range(1, 11)))
    result = table([*walker(7, range(1, 11)), *[(f, 7, 20.0, 30.0) for f in (11, 12)]])
    assert cmt(gt, result, (1, 12), tolerance=3)["DE_late_releases"] == 0
    assert cmt(gt, result, (1, 12), tolerance=1)["DE_late_releases"] == 1


def reference(gt: MotTable, result: MotTable, span, tolerance: int) -> dict:
    """Frame-by-frame loops over the CLEAR matches: an independent count of every field."""
    data = prepare_sequence(gt, result, span)
    matched = clear_matching(data).matched
    pairs = data.pairs
    frames = range(data.num_frames)
    gt_at = {f: set(data.gt_id[data.gt_frame == f].tolist()) for f in frames}
    tracks_at = {f: set(data.tracker_id[data.tracker_frame == f].tolist()) for f in frames}
    match_at = {f: {} for f in frames}  # frame -> {gt id: track id}
    for p in np.flatnonzero(matched):
        frame = int(pairs.frame[p])
        gt_id = int(data.gt_id[pairs.gt_row[p]])
        match_at[frame][gt_id] = int(data.tracker_id[pairs.tracker_row[p]])
    last_track, false_frames, swap_frames = {}, 0, 0
    for f in frames:
        switched = False
        for gt_id, track in match_at[f].items():
            switched |= gt_id in last_track and last_track[gt_id] != track
            last_track[gt_id] = track
        missed = gt_at[f] - set(match_at[f])
        unmatched = tracks_at[f] - set(match_at[f].values())
        false_frames += bool(missed or unmatched or switched)
        swap_frames += switched
    late_pickups = late_releases = entering = exiting = 0
    for gt_id in range(data.num_gt_ids):
        present = [f for f in frames if gt_id in gt_at[f]]
        first, last = present[0], present[-1]
        followed = [f for f in frames if gt_id in match_at[f]]
        if first > 0:
            entering += 1
            late_pickups += not any(first <= f <= first + tolerance for f in followed)
        if last < data.num_frames - 1:
            exiting += 1
            if followed:
                track = match_at[followed[-1]][gt_id]
                window = range(last + 1, last + tolerance + 2)
                late_releases += all(
                    f < data.num_frames
                    and track in tracks_at[f]
                    and track not in match_at[f].values()
                    for f in window
                )
    return {
        "OE_frames": false_frames,
        "SE_frames": swap_frames,
        "num_frames": data.num_frames,
        "DE_late_pickups": late_pickups,
        "DE_late_releases": late_releases,
        "DE_entering": entering,
        "DE_exiting": exiting,
    }


def with_delays(result: MotTable, seed: int) -> MotTable:
    """Each track starts 0-8 frames late and goes on for 0-8 frames after its end as a box
    far from everything (late pick-ups and releases around the tolerances tested)."""
    rng = np.random.default_rng(seed)
    keep = np.ones(len(result), bool)
    extra = []
    for identity in np.unique(result.ids):
        rows = np.flatnonzero(result.ids == identity)
        rows = rows[np.argsort(result.frames[rows])]
        keep[rows[: rng.integers(0, 9)]] = False
        box = result.boxes[rows[-1]] + [2000.0, 2000.0, 0.0, 0.0]
        last = result.frames[rows[-1]]
        extra += [(last + k, identity, *box) for k in range(1, rng.integers(0, 9) + 1)]
    extra = np.asarray(extra, float).reshape(-1, 6)
    return MotTable.from_arrays(
        np.r_[result.frames[keep], extra[:, 0]],
        np.r_[result.ids[keep], extra[:, 1]],
        np.r_[result.boxes[keep], extra[:, 2:]],
    )


@pytest.mark.parametrize("sequence", ["TUD-Campus", "PETS09-S2L1"])
@pytest.mark.parametrize("scenario", ["perturbed", "fragmented", "id_swapped", "noisy"])
def test_matches_the_loop_reference(mot15_gt, sequence, scenario):
    gt, seq_length = mot15_gt[sequence]
    result = with_delays(corrupt(gt, SCENARIOS[scenario], seed=5), seed=6)
    result = result.frame_span(1, seq_length)
    data = prepare_sequence(gt, result, (1, seq_length))
    late = []
    for tolerance in (0, 4, 8):
        fields = cmt_fields(data, clear_matching(data), tolerance)
        assert fields == reference(gt, result, (1, seq_length), tolerance)
        late.append((fields["DE_late_pickups"], fields["DE_late_releases"]))
    late = np.asarray(late)
    assert np.all(late[0] > 0)  # both kinds of delay error occur
    assert np.all(np.diff(late, axis=0) <= 0)  # and no more with a larger tolerance


def test_combined_rates_pool_frames_and_events(mot15_gt):
    evaluations = []
    for seed, name in enumerate(("TUD-Campus", "KITTI-17")):
        gt, seq_length = mot15_gt[name]
        result = corrupt(gt, SCENARIOS["noisy"], seed)
        config = EvalConfig(delay_tolerance=0)
        evaluations.append(evaluate_sequence(gt, result, (1, seq_length), config))
    fields = [evaluation.cmt for evaluation in evaluations]
    combined = combine_sequences(evaluations).scores()
    frames = sum(f["num_frames"] for f in fields)
    events = sum(f["DE_entering"] + f["DE_exiting"] for f in fields)
    late = sum(f["DE_late_pickups"] + f["DE_late_releases"] for f in fields)
    assert combined["OE"] == pytest.approx(sum(f["OE_frames"] for f in fields) / frames)
    assert combined["SE"] == pytest.approx(sum(f["SE_frames"] for f in fields) / frames)
    assert combined["DE"] == pytest.approx(late / events) and 0 < combined["DE"] < 1


def test_empty_output_misses_every_frame_with_a_target():
    gt = table([*walker(1, range(3, 8)), *walker(2, range(5, 11), y=50)])
    scores = cmt(gt, table([]), (1, 12))
    assert scores["OE"] == pytest.approx(8 / 12) and scores["SE"] == 0.0
    assert scores["DE"] == pytest.approx(2 / 4) and scores["DE_late_releases"] == 0


@pytest.mark.parametrize("tolerance", [-1, 2.5, True])
def test_bad_tolerance_is_refused(tolerance):
    with pytest.raises(InputError, match="delay tolerance"):
        EvalConfig(delay_tolerance=tolerance)


def test_eval_cli_prints_the_rates_and_takes_the_tolerance(tmp_path, capsys):
    gt_path, res_path = tmp_path / "gt.txt", tmp_path / "res.txt"
    write_mot_file(gt_path, table(walker(1, range(5, 21))))
    write_mot_file(res_path, table(walker(7, range(9, 21))))
    argv = ["eval", "--gt", str(gt_path), "--res", str(res_path), "--frames", "1:20", "--json"]
    assert main([*argv, "--delay-tolerance", "4"]) == 0
    assert json.loads(capsys.readouterr().out)["DE"] == 0.0
    assert main([*argv, "--delay-tolerance", "3"]) == 0
    scores = json.loads(capsys.readouterr().out)
    assert scores["DE"] == 1.0 and scores["OE"] == pytest.approx(4 / 20)
    assert main([*argv, "--delay-tolerance", "-1"]) == 2
    assert "--delay-tolerance" in capsys.readouterr().err


def test_crossing_swaps_count_window_frames_once_and_only_the_crossing_people():
    # crossings of people (1, 2) on frames 10-14 and (3, 4) on frames 18-20, tolerance 3:
    # windows 10-17 and 18-23 (14 frames); switches of 1 at 16 (in), of 2 at 16 (the same
    # frame), of 3 at 12 (before its window), of 5 at 19 (not a crossing person), of 4 at 24
    # (after its window): 1 frame with a swap
    fields = crossing_swap_fields(
        np.array([16, 16, 12, 19, 24]),
        np.array([1, 2, 3, 5, 4]),
        [((1, 2), (10, 14)), ((3, 4), (18, 20))],
        (1, 100),
        tolerance=3,
    )
    assert fields == {"crossing_frames": 14, "crossing_swap_frames": 1}
    assert crossing_swap_rate(fields) == 1 / 14
    # overlapping windows (10-17, 12-22 cut by the span) count their frames once: 13; 3 at 13
    # and 4 at 21 are in their crossing's window, 1 at 21 is not (its window ends at 17)
    fields = crossing_swap_fields(
        np.array([13, 21, 21]),
        np.array([3, 4, 1]),
        [((1, 2), (10, 14)), ((3, 4), (12, 20))],
        (1, 22),
        3,
    )
    assert fields == {"crossing_frames": 13, "crossing_swap_frames": 2}
    only_one = crossing_swap_fields(
        np.array([21]), np.array([1]), [((1, 2), (10, 14)), ((3, 4), (12, 20))], (1, 22), 3
    )
    assert only_one["crossing_swap_frames"] == 0
    assert crossing_swap_rate({"crossing_frames": 0, "crossing_swap_frames": 0}) == 0.0
    with pytest.raises(ValueError, match="tolerance"):
        crossing_swap_fields(np.array([]), np.array([]), [], (1, 10), -1)
