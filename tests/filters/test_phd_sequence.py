"""End to end on a real MOT15 sequence: finite, labelled, and close to the ground truth."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from jaxtrack.boxes import iou_matrix
from jaxtrack.filters.base import run
from jaxtrack.filters.phd import phd_filter
from jaxtrack.filters.phd_defaults import default_phd_params
from jaxtrack.io import load_sequence


@pytest.mark.parametrize("extraction", ["partition", "gmm"])
def test_default_tracker_on_tud_campus(mot15_root, extraction):
    sequence = load_sequence(mot15_root / "TUD-Campus")
    info = sequence.info
    params = default_phd_params(info.im_width, info.im_height, info.frame_rate)
    filt = phd_filter(256, extraction=extraction, max_clusters=16)
    _, out = jax.jit(lambda k: run(filt, k, params, sequence.detections))(jax.random.key(0))
    assert np.all(np.isfinite(out.mass)) and np.all(np.isfinite(out.log_likelihood))
    assert not np.any(out.track_overflow)
    tracks = jax.tree.map(np.asarray, out.tracks)
    assert np.all(tracks.ids[~tracks.mask] == -1) and np.all(tracks.ids[tracks.mask] >= 1)

    gt = sequence.gt_table
    matched = total = 0
    for t in range(sequence.num_frames):
        truth = gt.boxes[gt.frames == sequence.first_frame + t]
        total += len(truth)
        boxes = tracks.boxes[t][tracks.mask[t]]
        if len(truth) and len(boxes):
            matched += np.sum(iou_matrix(truth, boxes).max(1) >= 0.5)
    # TUD-Campus: 359 ground-truth boxes, 264 of them found by the detector at IoU >= 0.5.
    assert matched / total > 0.6
    num_ids = len(np.unique(tracks.ids[tracks.mask]))
    assert 6 <= num_ids <= 20  # 8 people in the ground truth
