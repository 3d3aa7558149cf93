"""jaxtrack's metrics equal TrackEval 1.3.0's on many generated tracker outputs.

Tracker outputs are seeded corruptions of the 11 MOT15 ground-truth files (jitter, misses,
gaps, identity switches, splits, false tracks, empty output). Every shared score must agree
to 1e-9 and every count exactly, per sequence and for the combined row.
"""

from __future__ import annotations

import numpy as np
import pytest

from jaxtrack.io import MotTable, read_mot_file, read_seqinfo, write_mot_file, write_seqinfo
from jaxtrack.metrics import EvalConfig, combine_sequences, evaluate_sequence
from jaxtrack.metrics.synthetic import SCENARIOS, Corruption, corrupt
from tests.metrics.trackeval_oracle import COUNT_KEYS, FIELD_MAP, run_trackeval

FAST_SEQUENCES = ("KITTI-17", "TUD-Campus", "TUD-Stadtmitte")


def assert_same_as_trackeval(evaluations: dict, oracle: dict) -> None:
    """Per sequence and combined, every mapped score equal (counts exactly)."""
    ours = {name: evaluation.scores() for name, evaluation in evaluations.items()}
    ours["COMBINED_SEQ"] = combine_sequences(evaluations.values()).scores()
    assert set(ours) == set(oracle)
    for name, scores in ours.items():
        for key in FIELD_MAP:
            expected = oracle[name][key]
            if key in COUNT_KEYS:
                assert scores[key] == int(expected), (name, key)
                assert isinstance(scores[key], int), (name, key)
            else:
                assert abs(scores[key] - float(expected)) <= 1e-9, (
                    name,
                    key,
                    scores[key],
                    expected,
                )


def check_against_trackeval(gt_root, gts, results, tmp_path, config=None, **oracle_options):
    evaluations = {
        name: evaluate_sequence(gt, results[name], (1, seq_length), config)
        for name, (gt, seq_length) in gts.items()
    }
    oracle = run_trackeval(gt_root, results, tmp_path, **oracle_options)
    assert_same_as_trackeval(evaluations, oracle)
    return evaluations


@pytest.mark.parametrize("scenario", sorted(SCENARIOS))
def test_scenarios_on_three_sequences(mot15_root, mot15_gt, tmp_path, scenario):
    gts = {name: mot15_gt[name] for name in FAST_SEQUENCES}
    results = {
        name: corrupt(gt, SCENARIOS[scenario], seed=10 + i)
        for i, (name, (gt, _)) in enumerate(gts.items())
    }
    check_against_trackeval(mot15_root, gts, results, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["perturbed", "fragmented", "id_swapped", "noisy"])
def test_scenarios_on_all_sequences(mot15_root, mot15_gt, tmp_path, scenario):
    results = {
        name: corrupt(gt, SCENARIOS[scenario], seed=100 + i)
        for i, (name, (gt, _)) in enumerate(mot15_gt.items())
    }
    evaluations = check_against_trackeval(mot15_root, mot15_gt, results, tmp_path)
    assert sum(e.clear["IDSW"] for e in evaluations.values()) > 0


@pytest.mark.slow
def test_many_seeds_heavy_corruption(mot15_root, mot15_gt, tmp_path):
    """Crowded conflicts: large jitter and many false tracks make the per-frame
    assignments non-trivial (many frames solved by the Hungarian algorithm)."""
    heavy = Corruption(jitter=0.3, miss_rate=0.1, switch_rate=0.5, split_rate=0.2, false_tracks=60)
    names = ("ETH-Bahnhof", "KITTI-13", "PETS09-S2L1", "Venice-2")
    gts = {name: mot15_gt[name] for name in names}
    for seed in range(3):
        results = {
            name: corrupt(gt, heavy, seed=seed * 7 + i)
            for i, (name, (gt, _)) in enumerate(gts.items())
        }
        check_against_trackeval(mot15_root, gts, results, tmp_path / str(seed))


@pytest.mark.parametrize("threshold", [0.3, 0.75])
def test_iou_threshold(mot15_root, mot15_gt, tmp_path, threshold):
    gts = {name: mot15_gt[name] for name in FAST_SEQUENCES}
    results = {name: corrupt(gt, SCENARIOS["noisy"], seed=3) for name, (gt, _) in gts.items()}
    check_against_trackeval(
        mot15_root, gts, results, tmp_path, EvalConfig(iou_threshold=threshold), threshold=threshold
    )


def test_centre_distance_matching(mot15_root, mot15_gt, tmp_path):
    """Centre matching equals TrackEval's Euclidean similarity with zero distance 2 tau."""
    gts = {name: mot15_gt[name] for name in FAST_SEQUENCES}
    results = {name: corrupt(gt, SCENARIOS["noisy"], seed=4) for name, (gt, _) in gts.items()}
    config = EvalConfig(centre_threshold=25.0)
    check_against_trackeval(mot15_root, gts, results, tmp_path, config, centre_threshold=25.0)


def mot17_style_copy(gt: MotTable, rng) -> MotTable:
    """The gt with a MOT16/17 class per track (column 8), visibility, some zero-marked rows."""
    tracks = np.unique(gt.ids)
    track_class = rng.choice([1, 1, 1, 1, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13], tracks.size)
    track_class[:2] = (8, 3)  # at least one distractor and one non-pedestrian track
    classes = track_class[np.searchsorted(tracks, gt.ids)]
    confs = np.where(rng.random(len(gt)) < 0.1, 0.0, 1.0)
    extra = np.column_stack([classes, rng.random(len(gt))])
    return MotTable.from_arrays(gt.frames, gt.ids, gt.boxes, confs, extra)


def test_mot17_distractor_rules(mot15_root, mot15_gt, tmp_path):
    rng = np.random.default_rng(17)
    gt_root = tmp_path / "gt"
    gts, results = {}, {}
    for i, name in enumerate(("ADL-Rundle-6", "KITTI-17", "TUD-Stadtmitte", "PETS09-S2L1")):
        gt, seq_length = mot15_gt[name]
        write_mot_file(gt_root / name / "gt" / "gt.txt", mot17_style_copy(gt, rng))
        write_seqinfo(
            gt_root / name / "seqinfo.ini", read_seqinfo(mot15_root / name / "seqinfo.ini")
        )
        gt17 = read_mot_file(gt_root / name / "gt" / "gt.txt", "gt", seq_length)
        gts[name] = (gt17, seq_length)
        results[name] = corrupt(gt17, SCENARIOS["noisy"], seed=i)
    evaluations = check_against_trackeval(
        gt_root, gts, results, tmp_path / "run", EvalConfig(distractors=True), benchmark="MOT17"
    )
    for name, evaluation in evaluations.items():
        scored_boxes = evaluation.clear["TP"] + evaluation.clear["FP"]
        assert scored_boxes < len(results[name]), name  # boxes on distractors were removed


def test_empty_ground_truth_and_empty_frames(mot15_gt, tmp_path):
    """A sequence whose gt is empty (TrackEval reports MOTA 0) and one with empty spans."""
    gt, seq_length = mot15_gt["TUD-Campus"]
    empty_gt = gt.select(np.zeros(len(gt), dtype=bool))
    holes = gt.select((gt.frames < 20) | (gt.frames > 40))
    gt_root = tmp_path / "gt"
    gts = {"empty-gt": (empty_gt, seq_length), "holes": (holes, seq_length)}
    results = {
        "empty-gt": corrupt(gt, SCENARIOS["perturbed"], seed=1),
        "holes": corrupt(gt, SCENARIOS["perturbed"], seed=2).frame_span(1, 50),
    }
    for name, (table, _) in gts.items():
        (gt_root / name / "gt").mkdir(parents=True)
        write_mot_file(gt_root / name / "gt" / "gt.txt", table)
    lengths = {name: seq_length for name in gts}
    evaluations = {
        name: evaluate_sequence(table, results[name], (1, seq_length))
        for name, (table, _) in gts.items()
    }
    oracle = run_trackeval(gt_root, results, tmp_path / "run", seq_lengths=lengths)
    assert_same_as_trackeval(evaluations, oracle)
    assert evaluations["empty-gt"].summary()["MOTA"] == 0.0
