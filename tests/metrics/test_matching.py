"""The batched pair layout and the conflict-only assignment against plain per-frame loops."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment
from trackeval.datasets._base_dataset import _BaseDataset

from jaxtrack.boxes import iou_matrix
from jaxtrack.metrics.matching import assign_frames, build_pairs, conflict_frames


def random_boxes(rng, n):
    boxes = np.column_stack([rng.uniform(0, 50, (n, 2)), rng.uniform(1, 20, (n, 2))])
    boxes[: n // 4] = np.round(boxes[: n // 4])  # integer boxes: exact ties in IoU values
    boxes[n // 4 : n // 3, 2:] = 1e-9  # near-degenerate boxes
    return boxes


def test_iou_is_bitwise_trackeval():
    rng = np.random.default_rng(0)
    a, b = random_boxes(rng, 60), random_boxes(rng, 70)
    ours = iou_matrix(a, b)
    theirs = _BaseDataset._calculate_box_ious(a, b, box_format="xywh")
    np.testing.assert_array_equal(ours, theirs)


def random_frames(rng, num_frames, max_rows):
    counts = rng.integers(0, max_rows + 1, num_frames)
    return np.repeat(np.arange(num_frames), counts)


def test_pair_layout_matches_a_loop():
    rng = np.random.default_rng(1)
    gt_frame, tracker_frame = random_frames(rng, 30, 4), random_frames(rng, 30, 5)
    pairs = build_pairs(gt_frame, tracker_frame, 30)
    expected = [
        (t, i, j)
        for t in range(30)
        for i in np.flatnonzero(gt_frame == t)
        for j in np.flatnonzero(tracker_frame == t)
    ]
    assert list(zip(pairs.frame, pairs.gt_row, pairs.tracker_row, strict=True)) == expected
    for t in range(30):
        block = slice(pairs.start[t], pairs.start[t + 1])
        assert np.all(pairs.frame[block] == t)
        assert pairs.num_gt[t] == np.sum(gt_frame == t)


@pytest.mark.parametrize("seed", range(5))
def test_assignment_equals_hungarian_on_every_frame(seed):
    rng = np.random.default_rng(seed)
    num_frames = 50
    gt_frame, tracker_frame = random_frames(rng, num_frames, 6), random_frames(rng, num_frames, 6)
    pairs = build_pairs(gt_frame, tracker_frame, num_frames)
    score = rng.random(pairs.frame.size)
    score[rng.random(score.size) < 0.7] = 0.0  # sparse candidates: most frames conflict-free
    candidate = score > 0
    matched = assign_frames(pairs, score, candidate, (gt_frame.size, tracker_frame.size))
    expected = np.zeros_like(matched)
    for t in range(num_frames):
        lo, hi = pairs.start[t], pairs.start[t + 1]
        if lo == hi:
            continue
        block = score[lo:hi].reshape(pairs.num_gt[t], pairs.num_tracker[t])
        rows, cols = linear_sum_assignment(-block)
        chosen = lo + rows * pairs.num_tracker[t] + cols
        expected[chosen] = candidate[chosen]
    np.testing.assert_array_equal(matched, expected)
    conflicts = conflict_frames(pairs, candidate, (gt_frame.size, tracker_frame.size))
    assert 0 < conflicts.size < num_frames
