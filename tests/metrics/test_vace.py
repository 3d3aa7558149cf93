"""MODA / MODP / VACE scores against hand-worked examples and a brute-force mapping."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from jaxtrack.io import MotTable
from jaxtrack.metrics import EvalConfig, evaluate_sequence


def table(rows) -> MotTable:
    """Rows ``(frame, id, x, y, w, h)``."""
    rows = np.asarray(rows, dtype=float).reshape(-1, 6)
    return MotTable.from_arrays(rows[:, 0], rows[:, 1], rows[:, 2:6])


def test_hand_worked_detection_scores():
    # Frame 1: gt A matched at IoU 0.8, gt B missed, one false positive.
    # Frame 2: gt A missed. Frame 3: no gt, one false positive.
    gt = table([(1, 1, 0, 0, 10, 10), (1, 2, 100, 0, 10, 10), (2, 1, 0, 0, 10, 10)])
    result = table([(1, 7, 0, 0, 10, 8), (1, 8, 50, 50, 10, 10), (3, 9, 0, 0, 10, 10)])
    scores = evaluate_sequence(gt, result, (1, 3)).summary()
    assert scores["MODA"] == pytest.approx(1 - 4 / 3)  # (2 misses + 2 false) / 3 gt boxes
    assert scores["MODP"] == pytest.approx(0.8)
    assert scores["VACE_MODA"] == pytest.approx(0.0)  # frames 1 and 2 have gt; both score 0
    assert scores["VACE_MODP"] == pytest.approx(0.8)  # only frame 1 maps anything


def swapping_sequence(num_objects: int) -> tuple[MotTable, MotTable]:
    """``num_objects`` static objects over 4 frames; from frame 3 on the tracker rotates all
    its ids, so every object switches identity in frame 3."""
    gt_rows, result_rows = [], []
    for frame in range(1, 5):
        for k in range(num_objects):
            gt_rows.append((frame, k + 1, 30 * k, 0, 20, 20))
            tracker_id = k + 1 if frame < 3 else (k + 1) % num_objects + 1
            result_rows.append((frame, tracker_id, 30 * k, 0, 20, 20))
    return table(gt_rows), table(result_rows)


@pytest.mark.parametrize("num_objects", [2, 3, 10])
def test_vace_mota_log10_switch_penalty(num_objects):
    gt, result = swapping_sequence(num_objects)
    scores = evaluate_sequence(gt, result, (1, 4)).summary()
    assert scores["IDSW"] == num_objects
    assert scores["MOTA"] == pytest.approx(1 - num_objects / (4 * num_objects))
    assert scores["VACE_MOTA"] == pytest.approx(1 - math.log10(num_objects) / (4 * num_objects))
    assert scores["MODA"] == 1.0


def test_single_switch_per_frame_costs_nothing_in_vace_mota():
    gt, result = swapping_sequence(2)
    # Only object 1 switches (frame 3 gets a fresh id for it): log10(1) = 0.
    result = table(
        [(f, 1 if f < 3 else 5, 0, 0, 20, 20) for f in range(1, 5)]
        + [(f, 2, 30, 0, 20, 20) for f in range(1, 5)]
    )
    scores = evaluate_sequence(gt, result, (1, 4)).summary()
    assert scores["IDSW"] == 1
    assert scores["VACE_MOTA"] == 1.0


def best_mapping(iou: np.ndarray, threshold: float) -> tuple[int, float]:
    """Brute force: the one-to-one mapping of valid pairs with the most pairs, then the
    largest summed IoU. Returns (pairs, summed IoU)."""
    n, m = iou.shape
    best = (0, 0.0)
    for size in range(1, min(n, m) + 1):
        for rows in itertools.combinations(range(n), size):
            for cols in itertools.permutations(range(m), size):
                values = iou[list(rows), list(cols)]
                if np.all(values >= threshold):
                    best = max(best, (size, float(values.sum())))
    return best


def pairwise_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.zeros((len(a), len(b)))
    for i, (ax, ay, aw, ah) in enumerate(a):
        for j, (bx, by, bw, bh) in enumerate(b):
            w = max(0.0, min(ax + aw, bx + bw) - max(ax, bx))
            h = max(0.0, min(ay + ah, by + bh) - max(ay, by))
            out[i, j] = w * h / (aw * ah + bw * bh - w * h)
    return out


@pytest.mark.parametrize("seed", range(6))
def test_detection_scores_against_brute_force(seed):
    rng = np.random.default_rng(seed)
    threshold = [0.3, 0.5][seed % 2]
    gt_rows, result_rows = [], []
    misses = false = mapped = num_gt = 0
    overlap = moda_sum = modp_sum = 0.0
    moda_frames = modp_frames = 0
    for frame in range(1, 41):
        n, m = rng.integers(0, 5, size=2)
        centres = rng.random((max(n, m), 2)) * 25
        gt_boxes = np.column_stack([centres[:n], rng.uniform(8, 12, (n, 2))])
        shift = rng.normal(0, 2.5, (m, 2))
        result_boxes = np.column_stack([centres[:m] + shift, rng.uniform(8, 12, (m, 2))])
        result_boxes = result_boxes[rng.permutation(m)]
        gt_rows += [(frame, k, *box) for k, box in enumerate(gt_boxes)]
        result_rows += [(frame, k, *box) for k, box in enumerate(result_boxes)]
        count, summed = best_mapping(pairwise_iou(gt_boxes, result_boxes), threshold)
        misses += n - count
        false += m - count
        mapped += count
        overlap += summed
        num_gt += n
        if n:
            moda_sum += 1 - (n - count + m - count) / n
            moda_frames += 1
        if count:
            modp_sum += summed / count
            modp_frames += 1
    scores = evaluate_sequence(
        table(gt_rows), table(result_rows), (1, 40), EvalConfig(iou_threshold=threshold)
    ).summary()
    assert scores["MODA"] == pytest.approx(1 - (misses + false) / num_gt, abs=1e-12)
    assert scores["MODP"] == pytest.approx(overlap / mapped, abs=1e-12)
    assert scores["VACE_MODA"] == pytest.approx(moda_sum / moda_frames, abs=1e-12)
    assert scores["VACE_MODP"] == pytest.approx(modp_sum / modp_frames, abs=1e-12)
    assert scores["MODA"] >= scores["MOTA"] - 1e-12  # identities can only cost more
