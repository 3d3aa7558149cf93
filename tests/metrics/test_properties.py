"""Properties every evaluation must have: perfect scores, invariances, empty inputs."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from jaxtrack.errors import InputError
from jaxtrack.io import MotTable
from jaxtrack.metrics import SUMMARY_KEYS, EvalConfig, combine_sequences, evaluate_sequence
from jaxtrack.metrics.synthetic import SCENARIOS, corrupt

PERFECT = {
    "MOTA": 1.0, "MOTP": 1.0, "MODA": 1.0, "MODP": 1.0, "IDF1": 1.0, "IDP": 1.0, "IDR": 1.0,
    "HOTA": 1.0, "DetA": 1.0, "AssA": 1.0, "LocA": 1.0, "FP": 0, "FN": 0, "IDSW": 0,
    "PT": 0, "ML": 0, "Recall": 1.0, "Precision": 1.0, "VACE_MOTA": 1.0, "VACE_MODA": 1.0,
    "VACE_MODP": 1.0, "OSPA": 0.0, "GOSPA": 0.0,
}  # fmt: skip


def empty_table() -> MotTable:
    return MotTable.from_arrays([], [], np.zeros((0, 4)))


def kept_gt(gt: MotTable) -> MotTable:
    return gt.select(~gt.ignored)


@pytest.mark.parametrize("name", ["ETH-Bahnhof", "KITTI-13", "TUD-Campus", "Venice-2"])
def test_ground_truth_as_result_scores_perfectly(mot15_gt, name):
    gt, seq_length = mot15_gt[name]
    result = kept_gt(gt)
    scores = evaluate_sequence(gt, result, (1, seq_length)).summary()
    for key, value in PERFECT.items():
        assert scores[key] == pytest.approx(value, abs=1e-12), key
    assert scores["MT"] == scores["GT_IDs"] == np.unique(result.ids).size
    assert scores["Frag"] == annotation_gaps(result)


def annotation_gaps(gt: MotTable) -> int:
    """Fragmentations of a perfect tracker: TrackEval counts a gt object's re-appearance after
    frames (with other boxes) where it is not annotated."""
    frames = np.unique(gt.frames)
    gaps = 0
    for track in np.unique(gt.ids):
        steps = np.searchsorted(frames, np.sort(gt.frames[gt.ids == track]))
        gaps += int(np.sum(np.diff(steps) > 1))
    return gaps


def test_ignored_gt_rows_are_false_positives(mot15_gt):
    gt, seq_length = mot15_gt["ETH-Bahnhof"]
    scores = evaluate_sequence(gt, gt, (1, seq_length)).summary()
    assert scores["FP"] == int(gt.ignored.sum()) > 0
    assert scores["FN"] == 0


def relabel(table: MotTable, rng) -> MotTable:
    labels = np.unique(table.ids)
    new = rng.permutation(np.arange(10_000, 10_000 + 5 * labels.size))[: labels.size]
    return dataclasses.replace(table, ids=new[np.searchsorted(labels, table.ids)])


@pytest.mark.parametrize("name", ["ADL-Rundle-6", "PETS09-S2L1", "TUD-Stadtmitte"])
def test_invariant_to_id_relabelling_and_row_order(mot15_gt, name):
    rng = np.random.default_rng(0)
    gt, seq_length = mot15_gt[name]
    result = corrupt(gt, SCENARIOS["noisy"], seed=5)
    reference = evaluate_sequence(gt, result, (1, seq_length)).scores()
    shuffled_gt = relabel(gt, rng).select(rng.permutation(len(gt)))
    shuffled_result = relabel(result, rng).select(rng.permutation(len(result)))
    scores = evaluate_sequence(shuffled_gt, shuffled_result, (1, seq_length)).scores()
    for key, value in reference.items():
        assert scores[key] == pytest.approx(value, abs=1e-12), key


def test_empty_result_and_empty_frames(mot15_gt):
    gt, seq_length = mot15_gt["TUD-Campus"]
    kept = kept_gt(gt)
    empty = evaluate_sequence(gt, empty_table(), (1, seq_length)).summary()
    assert empty["FN"] == len(kept) and empty["FP"] == 0 and empty["ML"] == empty["GT_IDs"]
    for key in ("MOTA", "MOTP", "MODA", "IDF1", "HOTA", "DetA", "AssA", "Recall", "VACE_MOTA"):
        assert empty[key] == 0.0, key
    assert empty["OSPA"] == 1.0  # every frame has gt and no output: distance c

    # Output only on frames 1-30: the other frames' gt are misses, nothing else changes there.
    partial = evaluate_sequence(gt, kept.frame_span(1, 30), (1, seq_length)).summary()
    assert partial["FP"] == 0
    assert partial["FN"] == int(np.sum(kept.frames > 30))
    assert partial["IDSW"] == 0 and partial["Precision"] == 1.0

    nothing = evaluate_sequence(empty_table(), empty_table(), (1, 10)).summary()
    assert set(nothing) == set(SUMMARY_KEYS)
    assert nothing["OSPA"] == 0.0 and nothing["GOSPA"] == 0.0 and nothing["FP"] == 0


def test_rows_outside_the_span_are_an_error(mot15_gt):
    gt, _ = mot15_gt["TUD-Campus"]
    with pytest.raises(InputError, match="outside the scored span 1:50"):
        evaluate_sequence(gt, gt.frame_span(1, 50), (1, 50))


def test_frame_span_only_changes_frame_averages_and_exits(mot15_gt):
    gt, seq_length = mot15_gt["TUD-Campus"]
    result = corrupt(gt, SCENARIOS["perturbed"], seed=2)
    whole = evaluate_sequence(gt, result, (1, seq_length)).scores()
    longer = evaluate_sequence(gt, result, (1, 2 * seq_length)).scores()
    assert longer["DE_exiting"] == whole["GT_IDs"]  # the span's end decides who exits
    for key in whole:
        if key.startswith(("OSPA", "GOSPA")) or key in ("OE", "SE"):
            assert longer[key] == pytest.approx(whole[key] / 2, abs=1e-12), key
        elif key in ("DE", "DE_late_releases", "DE_exiting"):
            continue
        else:
            assert longer[key] == pytest.approx(whole[key], abs=1e-12), key


def test_combining_one_sequence_changes_nothing(mot15_gt):
    gt, seq_length = mot15_gt["KITTI-17"]
    evaluation = evaluate_sequence(gt, corrupt(gt, SCENARIOS["noisy"], seed=9), (1, seq_length))
    combined = combine_sequences([evaluation]).scores()
    for key, value in evaluation.scores().items():
        assert combined[key] == pytest.approx(value, abs=1e-12), key


def test_combined_frame_averages_weight_frames(mot15_gt):
    evaluations, frames, ospa_sum = [], 0, 0.0
    for seed, name in enumerate(("KITTI-17", "TUD-Campus")):
        gt, seq_length = mot15_gt[name]
        evaluation = evaluate_sequence(gt, corrupt(gt, SCENARIOS["noisy"], seed), (1, seq_length))
        evaluations.append(evaluation)
        frames += seq_length
        ospa_sum += evaluation.summary()["OSPA"] * seq_length
    assert combine_sequences(evaluations).summary()["OSPA"] == pytest.approx(ospa_sum / frames)


@pytest.mark.parametrize(
    "settings",
    [
        {"iou_threshold": 0.0},
        {"iou_threshold": 1.5},
        {"centre_threshold": -1.0},
        {"ospa_cutoff": 0.0},
        {"ospa_order": 0.5},
        {"ospa_distance": "mahalanobis"},
    ],
)
def test_invalid_settings(settings):
    with pytest.raises(InputError):
        EvalConfig(**settings)
