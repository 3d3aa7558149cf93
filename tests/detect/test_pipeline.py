"""Detector quality on real video: PETS09-S2L1 (vtest.avi) against its ground truth."""

from __future__ import annotations

import numpy as np
import pytest

from jaxtrack.detect.pipeline import DetectorConfig, detect_video
from jaxtrack.errors import InputError
from jaxtrack.io import read_mot_file
from jaxtrack.metrics.detection import detection_precision_recall

#: The slice tested (the first 100 frames of the tracking span 401:795 of the experiment).
SLICE = (401, 500)
#: (precision, recall) floors on SLICE: the goal for the best detector (Horprasert here);
#: MOG2 measured 0.905 / 0.722 on this slice (0.822 / 0.841 on all 795 frames).
FLOORS = {"horprasert": (0.80, 0.75), "mog2": (0.85, 0.70)}


@pytest.mark.parametrize("method", ["horprasert", "mog2"])
def test_precision_recall_floor_on_pets_slice(data_root, method):
    video = data_root / "video" / "vtest.avi"
    gt = read_mot_file(data_root / "mot15" / "PETS09-S2L1" / "gt" / "gt.txt", "gt", 795)
    found = detect_video(video, SLICE, DetectorConfig(method=method))
    assert found.frames == SLICE and found.size == (768, 576)
    table = found.table
    assert table.frames.min() >= SLICE[0] and table.frames.max() <= SLICE[1]
    assert np.all(table.confs > 0) and np.all(table.confs <= 1)
    precision, recall = detection_precision_recall(table, gt.frame_span(*SLICE), SLICE)
    floor_precision, floor_recall = FLOORS[method]
    assert precision >= floor_precision, (method, precision, recall)
    assert recall >= floor_recall, (method, precision, recall)
    # the prior says people are taller further down the image (camera above the ground)
    assert found.prior.slope > 0.1


def test_unknown_method_and_bad_span(data_root):
    video = data_root / "video" / "vtest.avi"
    with pytest.raises(InputError, match="unknown method"):
        detect_video(video, (1, 10), DetectorConfig(method="hog"))
    with pytest.raises(InputError, match="frame span"):
        detect_video(video, (700, 900))
