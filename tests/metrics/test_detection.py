"""The detections under their true identities (:func:`true_identity_rows`), on a hand-built
sequence whose answer is known."""

from __future__ import annotations

import numpy as np

from jaxtrack.metrics.detection import true_identity_rows
from jaxtrack.metrics.evaluate import evaluate_sequence
from jaxtrack.types import MotTable

FRAMES = np.arange(1, 11)


def _scene():
    """gt 7 walks right, gt 3 stands, gt 5 is marked ignored (conf 0). The detector finds
    7 on every frame (twice on frame 5: the exact box and a near copy), places 3 12 px off
    (IoU 0.25) on frames 4-6, finds the ignored 5, and fires once far from everyone."""
    gt_rows, det_rows = [], []
    for f in FRAMES:
        a = [10.0 + 2 * f, 10.0, 20.0, 40.0]
        b = [100.0, 10.0, 20.0, 40.0]
        gt_rows += [(f, 7, a, 1.0), (f, 3, b, 1.0), (f, 5, [200.0, 10.0, 20.0, 40.0], 0.0)]
        det_rows.append((f, a))
        det_rows.append((f, [112.0, 10.0, 20.0, 40.0] if 4 <= f <= 6 else b))
        det_rows.append((f, [200.0, 10.0, 20.0, 40.0]))
        if f == 5:
            det_rows.append((f, [a[0] + 2, 10.0, 20.0, 40.0]))
        if f == 2:
            det_rows.append((f, [400.0, 300.0, 20.0, 40.0]))
    gt = MotTable.from_arrays(
        [r[0] for r in gt_rows],
        [r[1] for r in gt_rows],
        [r[2] for r in gt_rows],
        confs=[r[3] for r in gt_rows],
    )
    det = MotTable.from_arrays(
        [r[0] for r in det_rows], np.full(len(det_rows), -1), [r[1] for r in det_rows]
    )
    return gt, det


def test_mapped_detections_take_the_true_identities():
    gt, det = _scene()
    rows = true_identity_rows(det, gt, (1, 10))
    expected = [(f, 7, 10.0 + 2 * f) for f in FRAMES]
    expected += [(f, 3, 100.0) for f in FRAMES if not 4 <= f <= 6]
    got = sorted(
        zip(rows.frames.tolist(), rows.ids.tolist(), rows.boxes[:, 0].tolist(), strict=True)
    )
    assert got == sorted(expected)
    assert np.all(np.diff(rows.frames) >= 0)  # the detections' row order
    assert np.all(rows.confs == 1.0)


def test_scores_count_only_the_detector_misses():
    gt, det = _scene()
    summary = evaluate_sequence(gt, true_identity_rows(det, gt, (1, 10)), frames=(1, 10)).summary()
    assert (summary["MT"], summary["PT"], summary["ML"]) == (1, 1, 0)  # 7: 10/10, 3: 7/10
    assert (summary["IDSW"], summary["FP"], summary["FN"], summary["Frag"]) == (0, 0, 3, 1)


def test_a_stricter_threshold_drops_the_near_copies():
    gt, det = _scene()
    loose = true_identity_rows(det, gt, (1, 10), iou_threshold=0.2)
    assert len(loose) == 20  # gt 3's offset boxes (IoU 0.25) now match
    strict = true_identity_rows(det, gt, (1, 10), iou_threshold=1.0)
    assert len(strict) == 17  # exact boxes only, as at 0.5
