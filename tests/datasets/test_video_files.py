"""The written video scene: a loadable MOTChallenge folder, a decodable video, its truth."""

from __future__ import annotations

import json

import numpy as np
import pytest

from jaxtrack.datasets import build_canvas, render_frame, write_video_scene
from jaxtrack.datasets.video_files import TRUTH_FILE
from jaxtrack.detect import DetectorConfig, detect_video
from jaxtrack.io import load_sequence
from jaxtrack.io.video import VideoReader, find_frame_source
from jaxtrack.metrics.detection import detection_precision_recall

#: mp4v is lossy and the pixel noise does not survive it: mean absolute error per channel
#: (measured 5.0 at 320x240 with noise_std 4) and its 99th percentile (measured 19-23).
MP4_MEAN_ERROR = 7.0
MP4_P99_ERROR = 32.0


@pytest.fixture(scope="module")
def written(small_video_scene, tmp_path_factory):
    """The 320x240 scene written once (about 0.6 s)."""
    return write_video_scene(small_video_scene, tmp_path_factory.mktemp("video") / "v3")


def test_folder_loads_with_the_scene_tables(written, small_video_scene):
    scene = small_video_scene
    sequence = load_sequence(written)
    assert sequence.info == scene.info
    np.testing.assert_array_equal(sequence.gt_table.boxes, scene.gt_table.boxes)
    np.testing.assert_array_equal(sequence.gt_table.extra, scene.gt_table.extra)  # visibility
    np.testing.assert_array_equal(sequence.det_table.boxes, scene.det_table.boxes)
    np.testing.assert_array_equal(sequence.det_table.confs, scene.det_table.confs)
    assert find_frame_source(written, scene.info.name) == written / "video-3.mp4"


def test_truth_file_holds_zones_appearance_and_events(written, small_video_scene):
    scene = small_video_scene
    truth = json.loads((written / TRUTH_FILE).read_text())
    assert truth["seed"] == 3 and truth["video"] == "video-3.mp4"
    assert truth["image_size"] == [320, 240]
    zones = [[zone[key] for key in "xywh"] for zone in truth["zones"]]
    np.testing.assert_allclose(zones, scene.zones)
    assert [zone["name"] for zone in truth["zones"]] == ["west", "east", "south", "door"]
    assert [truth["occluder"][key] for key in "xywh"] == scene.occluder.tolist()
    people = truth["people"]
    assert [person["id"] for person in people] == list(range(1, scene.num_people + 1))
    np.testing.assert_array_equal([p["top"] for p in people], scene.appearance.top)
    np.testing.assert_array_equal([p["bottom"] for p in people], scene.appearance.bottom)
    assert [p["role"] for p in people] == list(scene.roles)
    events = [(e["type"], tuple(e["ids"]), tuple(e["frames"]), e["zone"]) for e in truth["events"]]
    assert events == [(e.kind, e.ids, e.frames, e.zone) for e in scene.events]
    gust = np.zeros(scene.config.num_frames, bool)
    for first, last in truth["gusts"]:
        gust[first - 1 : last] = True
    np.testing.assert_array_equal(gust, scene.gust)


def test_video_decodes_close_to_the_rendered_frames(written, small_video_scene):
    scene = small_video_scene
    canvas = build_canvas(scene)
    with VideoReader(written / "video-3.mp4") as reader:
        assert (reader.num_frames, reader.width, reader.height) == (500, 320, 240)
        assert reader.fps == 25.0
        for frame in (1, 250, 500):
            error = np.abs(reader.read(frame).astype(float) - render_frame(scene, canvas, frame))
            assert error.mean() < MP4_MEAN_ERROR
            assert np.percentile(error, 99) < MP4_P99_ERROR


def test_background_subtraction_finds_the_people_and_the_gusts(written, small_video_scene):
    # Horprasert over the whole 320x240 video at full resolution (people are 20-60 pixels
    # tall; about 3 s). Measured: 7.8 detections per frame for 8.3 people at least half
    # visible, precision 0.75 and recall 0.71 at IoU >= 0.5; 250 detections in the foliage,
    # 89 % of them in gust frames (18 % of the frames).
    scene = small_video_scene
    found = detect_video(written / "video-3.mp4", None, DetectorConfig(scale=1.0, min_area=60))
    seen = scene.gt_table.select(scene.visibility >= 0.5)
    assert len(found.table) == pytest.approx(len(seen), rel=0.2)
    precision, recall = detection_precision_recall(found.table, seen, (1, 500), 0.5)
    assert precision >= 0.65 and recall >= 0.6
    boxes = found.table.boxes
    x, y, _, h = scene.vegetation  # the foliage reaches the right edge
    foliage = (boxes[:, 0] + boxes[:, 2] / 2 >= x) & (boxes[:, 1] + boxes[:, 3] / 2 <= y + h)
    assert foliage.sum() >= 50
    assert scene.gust[found.table.frames[foliage] - 1].mean() >= 0.8 > scene.gust.mean()
