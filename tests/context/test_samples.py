"""Training samples for context learning, against hand-made tables with exact answers."""

from __future__ import annotations

import numpy as np
import pytest

from jaxtrack.context.clutter_labels import ClutterLabels, load_clutter_labels, save_clutter_labels
from jaxtrack.context.samples import (
    EventSamples,
    birth_samples,
    birth_samples_from_gt,
    birth_samples_from_tracks,
    chance_overlap,
    clutter_samples_from_gt,
    clutter_samples_from_labels,
    clutter_samples_from_tracks,
    first_states,
    occupancy_samples,
    occupancy_samples_from,
)
from jaxtrack.datasets.scene_bank import generate_family_scene
from jaxtrack.io import MotTable


def _track(first_frame, box, velocity, length, gap_after=None):
    """Rows of a constant-velocity box ``(x, y, w, h)``; optionally one frame skipped."""
    frames = np.arange(first_frame, first_frame + length + (gap_after is not None))
    if gap_after is not None:
        frames = np.delete(frames, gap_after + 1)
    steps = (frames - first_frame)[:, None]
    boxes = np.asarray(box, float) + steps * np.array([velocity[0], velocity[1], 0.0, 0.0])
    return frames, boxes


def test_first_states_exact_for_constant_velocity_with_gaps():
    frames_a, boxes_a = _track(3, (10.0, 20.0, 4.0, 8.0), (2.0, -1.0), 6)
    frames_b, boxes_b = _track(7, (100.0, 50.0, 10.0, 20.0), (-0.5, 3.0), 4, gap_after=1)
    frames = np.concatenate([frames_b, frames_a])
    ids = np.concatenate([np.full(frames_b.size, 9), np.full(frames_a.size, 4)])
    boxes = np.concatenate([boxes_b, boxes_a])
    states, first, track_ids = first_states(frames, ids, boxes)
    np.testing.assert_array_equal(first, [3, 7])
    np.testing.assert_array_equal(track_ids, [4, 9])
    # centre = top-left + size / 2; the skipped frame does not change the fitted speed
    np.testing.assert_allclose(states[0], [12.0, 2.0, 24.0, -1.0, 4.0, 8.0], atol=1e-12)
    np.testing.assert_allclose(states[1], [105.0, -0.5, 60.0, 3.0, 10.0, 20.0], atol=1e-12)


def test_first_states_uses_only_the_first_velocity_frames():
    # moves +1 px/frame for 3 frames, then +10 px/frame
    frames = np.arange(1, 8)
    x = np.array([0.0, 1.0, 2.0, 12.0, 22.0, 32.0, 42.0])
    boxes = np.stack([x, np.zeros(7), np.full(7, 2.0), np.full(7, 2.0)], axis=-1)
    ids = np.zeros(7, int)
    states, _, _ = first_states(frames, ids, boxes, velocity_frames=3)
    assert states[0, 1] == pytest.approx(1.0)
    states, _, _ = first_states(frames, ids, boxes, velocity_frames=2)
    assert states[0, 1] == pytest.approx(1.0)
    states, _, _ = first_states(frames, ids, boxes, velocity_frames=4)
    # least-squares slope of (0, 1, 2, 12) over frames (1, 2, 3, 4)
    assert states[0, 1] == pytest.approx(3.7)


def test_first_states_min_length():
    frames = np.array([5, 5, 6])
    ids = np.array([1, 2, 2])
    boxes = np.array([[0.0, 0.0, 2.0, 4.0], [10.0, 10.0, 2.0, 2.0], [11.0, 10.0, 2.0, 2.0]])
    _, _, track_ids = first_states(frames, ids, boxes)
    np.testing.assert_array_equal(track_ids, [2])
    states, _, track_ids = first_states(frames, ids, boxes, min_length=1)
    np.testing.assert_array_equal(track_ids, [1, 2])
    np.testing.assert_allclose(states[0], [1.0, 0.0, 2.0, 0.0, 2.0, 4.0])
    with pytest.raises(ValueError):
        first_states(frames, ids, boxes, velocity_frames=1)


def test_birth_samples_skip_the_warmup_and_count_frames_after_it():
    frames_a, boxes_a = _track(1, (0.0, 0.0, 2.0, 2.0), (1.0, 0.0), 5)  # in view at the start
    frames_b, boxes_b = _track(4, (50.0, 0.0, 2.0, 2.0), (0.0, 1.0), 5)  # inside the warm-up
    frames_c, boxes_c = _track(6, (80.0, 0.0, 2.0, 2.0), (0.0, 2.0), 5)  # a birth
    frames = np.concatenate([frames_a, frames_b, frames_c])
    ids = np.repeat([1, 2, 3], 5)
    boxes = np.concatenate([boxes_a, boxes_b, boxes_c])
    events = birth_samples(frames, ids, boxes, (1, 20), "test", warmup_frames=5)
    assert events.count == 1 and events.num_frames == 15 and events.source == "test"
    np.testing.assert_allclose(events.values, [[81.0, 0.0, 1.0, 2.0, 2.0, 2.0]])
    np.testing.assert_array_equal(events.frames, [6])
    assert events.magnitude == pytest.approx(1 / 15)
    events = birth_samples(frames, ids, boxes, (1, 20), "test", warmup_frames=0)
    assert events.count == 3 and events.num_frames == 20


def test_birth_samples_from_gt_ignore_zero_confidence_rows():
    frames, boxes = _track(10, (0.0, 0.0, 4.0, 4.0), (3.0, 0.0), 4)
    confs = np.array([0.0, 1.0, 1.0, 1.0])  # the first row is marked "ignore"
    table = MotTable.from_arrays(frames, np.full(4, 7), boxes, confs)
    events = birth_samples_from_gt(table, (1, 30))
    assert events.source == "gt" and events.num_frames == 25
    np.testing.assert_array_equal(events.frames, [11])
    np.testing.assert_allclose(events.values, [[5.0, 3.0, 2.0, 0.0, 4.0, 4.0]])


def test_birth_samples_from_tracks():
    frames, boxes = _track(8, (20.0, 30.0, 6.0, 12.0), (-1.0, 0.5), 3)
    rows = MotTable.from_arrays(frames, np.full(3, 2), boxes, np.ones(3))
    events = birth_samples_from_tracks(rows, (1, 10), warmup_frames=2)
    assert events.source == "tracks" and events.num_frames == 8
    np.testing.assert_allclose(events.values, [[23.0, -1.0, 36.0, 0.5, 6.0, 12.0]])


def test_occupancy_samples_every_stride_th_box_with_its_local_velocity():
    # a: 7 boxes, constant velocity; b: starts at frame 5, a frame skipped after its 2nd box
    frames_a, boxes_a = _track(1, (10.0, 20.0, 4.0, 8.0), (2.0, -1.0), 7)
    frames_b, boxes_b = _track(5, (100.0, 50.0, 10.0, 20.0), (-0.5, 3.0), 4, gap_after=1)
    frames = np.concatenate([frames_b, frames_a])
    ids = np.concatenate([np.full(frames_b.size, 9), np.full(frames_a.size, 4)])
    boxes = np.concatenate([boxes_b, boxes_a])
    events = occupancy_samples(frames, ids, boxes, (1, 20), "test", stride=3, velocity_frames=3)
    # a's boxes 1, 4, 7 (frames 1, 4, 7); b's boxes 1, 4 (frames 5, 9: the gap moves it)
    np.testing.assert_array_equal(events.frames, [1, 4, 5, 7, 9])
    expected_a = [[12.0 + 2 * k, 2.0, 24.0 - k, -1.0, 4.0, 8.0] for k in (0, 3, 6)]
    expected_b = [[105.0 - 0.5 * k, -0.5, 60.0 + 3 * k, 3.0, 10.0, 20.0] for k in (0, 4)]
    np.testing.assert_allclose(
        events.values,
        [expected_a[0], expected_a[1], expected_b[0], expected_a[2], expected_b[1]],
    )
    # every box counts towards the magnitude: 11 boxes of targets in view over 20 frames
    assert events.count == 5 and events.num_frames == 20 and events.source == "test"
    assert events.coverage == pytest.approx(5 / 11)
    assert events.magnitude == pytest.approx(11 / 20)


def test_occupancy_samples_velocity_window_and_short_trajectories():
    # a curved track: the velocity is the slope of the boxes around each event only
    frames = np.arange(1, 9)
    x = np.array([0.0, 1.0, 2.0, 3.0, 10.0, 20.0, 30.0, 40.0])
    boxes = np.stack([x, np.zeros(8), np.full(8, 2.0), np.full(8, 2.0)], axis=1)
    events = occupancy_samples(frames, np.ones(8), boxes, (1, 8), "t", stride=7, velocity_frames=3)
    # box 1: window boxes 1-3 (cut at the start), box 8: boxes 6-8 (cut at the end)
    np.testing.assert_allclose(events.values[:, 1], [1.0, 10.0])
    # one box: velocity 0
    single = occupancy_samples([4], [3], [[5.0, 5.0, 2.0, 4.0]], (1, 10), "t")
    np.testing.assert_allclose(single.values, [[6.0, 0.0, 7.0, 0.0, 2.0, 4.0]])
    assert single.magnitude == pytest.approx(0.1)
    for bad in ({"stride": 0}, {"velocity_frames": 1}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            occupancy_samples(frames, np.ones(8), boxes, (1, 8), "t", **bad)


def test_occupancy_samples_from_gt_and_tracks():
    frames, boxes = _track(10, (0.0, 0.0, 4.0, 4.0), (3.0, 0.0), 4)
    confs = np.array([0.0, 1.0, 1.0, 1.0])  # the first row is marked "ignore"
    table = MotTable.from_arrays(frames, np.full(4, 7), boxes, confs)
    events = occupancy_samples_from(table, (1, 30), "gt", stride=2)
    assert events.source == "gt" and events.num_frames == 30
    np.testing.assert_array_equal(events.frames, [11, 13])
    assert events.magnitude == pytest.approx(3 / 30)
    rows = MotTable.from_arrays(frames, np.full(4, 7), boxes, np.ones(4))
    events = occupancy_samples_from(rows, (1, 30), "tracks", stride=2)
    assert events.source == "tracks" and events.magnitude == pytest.approx(4 / 30)
    np.testing.assert_array_equal(events.frames, [10, 12])
    np.testing.assert_allclose(events.values[:, 1], [3.0, 3.0])


def _clutter_scene():
    """Detections and ground truth over frames 1-4 with known clutter.

    Frame 1: one gt box; a detection on it and one far away (clutter).
    Frame 2: one gt box, two detections on it (IoU 0.9 and 0.6): one-to-one, so the weaker
    one is clutter.
    Frame 3: an ignored (conf 0) gt box with a detection on it (not clutter).
    Frame 4: no gt; its detection is clutter.
    """
    gt = MotTable.from_arrays(
        [1, 2, 3],
        [1, 1, 2],
        [[0, 0, 10, 10], [0, 0, 10, 10], [50, 50, 10, 10]],
        confs=[1.0, 1.0, 0.0],
    )
    det_boxes = [
        [300, 200, 20, 40],
        [1, 0, 10, 10],
        [0, 0, 10, 9],
        [0, 0, 10, 6],
        [50, 51, 10, 10],
        [5, 5, 4, 8],
    ]
    det = MotTable.from_arrays([1, 1, 2, 2, 3, 4], np.full(6, -1), det_boxes)
    return det, gt


def test_clutter_samples_from_gt_one_to_one_at_iou_half():
    det, gt = _clutter_scene()
    events = clutter_samples_from_gt(det, gt, (1, 5), object_overlap=None)
    assert events.source == "gt" and events.num_frames == 5
    np.testing.assert_array_equal(events.frames, [1, 2, 4])
    np.testing.assert_allclose(
        events.values, [[310.0, 220.0, 20.0, 40.0], [5.0, 3.0, 10.0, 6.0], [7.0, 9.0, 4.0, 8.0]]
    )
    assert events.magnitude == pytest.approx(3 / 5)
    # at IoU 0.95 no detection matches (best IoUs 0.82, 0.9, 0.82): all are clutter
    strict = clutter_samples_from_gt(det, gt, (1, 5), iou_threshold=0.95, object_overlap=None)
    np.testing.assert_array_equal(strict.frames, [1, 1, 2, 2, 3, 4])


def test_clutter_samples_from_gt_leave_out_badly_placed_detections_of_objects():
    det, gt = _clutter_scene()
    # frame 2's second box on the object (IoU 0.6 with it, unmatched one-to-one) is the
    # object's detection, not clutter; the far box of frame 1 and frame 4's box are clutter
    events = clutter_samples_from_gt(det, gt, (1, 5))
    np.testing.assert_array_equal(events.frames, [1, 4])
    np.testing.assert_allclose(events.values, [[310.0, 220.0, 20.0, 40.0], [7.0, 9.0, 4.0, 8.0]])
    assert events.object_overlaps == 1
    # the kept boxes overlap no object in other frames either: nothing to count back
    assert events.coverage == 1.0 and events.magnitude == pytest.approx(2 / 5)
    # at IoU 0.95 nothing matches; the ignored object's box (frame 3) and every box on an
    # object are left out, whatever the one-to-one mapping did
    strict = clutter_samples_from_gt(det, gt, (1, 5), iou_threshold=0.95)
    np.testing.assert_array_equal(strict.frames, [1, 4])
    assert strict.object_overlaps == 4
    # the overlap threshold is inclusive: 0.6 is the weaker box's IoU with the object
    assert clutter_samples_from_gt(det, gt, (1, 5), object_overlap=0.6).object_overlaps == 1
    assert clutter_samples_from_gt(det, gt, (1, 5), object_overlap=0.61).object_overlaps == 0


def test_clutter_samples_from_tracks_by_best_iou():
    det, _ = _clutter_scene()
    # track boxes: frame 1 on the gt object, frame 2 on the weaker detection; none later
    rows = MotTable.from_arrays(
        np.array([1, 2]),
        np.array([1, 1]),
        np.array([[0.0, 0.0, 10.0, 10.0], [0.0, 0.0, 10.0, 6.0]]),
        np.ones(2),
    )
    events = clutter_samples_from_tracks(det, rows, (1, 4))
    assert events.source == "tracks" and events.num_frames == 4
    # frame 2: both detections overlap the track box by >= 0.5 (IoU 6/9 and 1), none is clutter
    np.testing.assert_array_equal(events.frames, [1, 3, 4])
    np.testing.assert_allclose(events.values[0], [310.0, 220.0, 20.0, 40.0])
    assert events.object_overlaps == 0


def test_clutter_samples_from_tracks_leave_out_badly_placed_detections_of_tracks():
    # frame 1: a track box and a detection of half its height on it (IoU 0.5 * 0.8 = 0.4),
    # a detection at IoU 0.1 (a corner) and a far one
    rows = MotTable.from_arrays([1], [1], [[0.0, 0.0, 10.0, 20.0]], [1.0])
    det = MotTable.from_arrays(
        [1, 1, 1],
        np.full(3, -1),
        [[0.0, 0.0, 10.0, 8.0], [0.0, 0.0, 10.0, 20.0 / 11 * 2], [100.0, 100.0, 10.0, 20.0]],
    )
    ious = np.array([0.4, 2 / 11])
    events = clutter_samples_from_tracks(det, rows, (1, 1))
    # the first overlaps the track by IoU 0.4 >= 0.2: the track's detection; the second by
    # 2/11 < 0.2 and the far one are clutter
    assert ious[0] >= 0.2 > ious[1]
    np.testing.assert_allclose(events.values[:, 1], [20.0 / 11, 110.0])
    assert events.object_overlaps == 1
    every = clutter_samples_from_tracks(det, rows, (1, 1), object_overlap=None)
    assert every.count == 3 and every.object_overlaps == 0


def test_clutter_samples_from_labels_file(tmp_path):
    labels = ClutterLabels(
        sequence="toy",
        image_size=(640, 480),
        labelled_frames=[3, 8, 20, 50],
        frames=[8, 8, 20, 50],
        boxes=[[10, 20, 30, 40], [0, 0, 2, 2], [100, 100, 10, 10], [1, 1, 1, 1]],
    )
    path = tmp_path / "labels.json"
    save_clutter_labels(path, labels)
    events = clutter_samples_from_labels(load_clutter_labels(path), (1, 30), str(path))
    # frame 50 is outside the span; frames 3, 8, 20 were looked at (3 without clutter)
    assert events.num_frames == 3 and events.count == 3 and events.source == str(path)
    np.testing.assert_array_equal(events.frames, [8, 8, 20])
    np.testing.assert_allclose(
        events.values, [[25.0, 40.0, 30.0, 40.0], [1.0, 1.0, 2.0, 2.0], [105.0, 105.0, 10.0, 10.0]]
    )
    assert events.magnitude == pytest.approx(1.0)


def test_event_samples_magnitude_without_frames_is_zero():
    empty = EventSamples(np.zeros((0, 4)), np.zeros(0, int), 0, "gt")
    assert empty.count == 0 and empty.magnitude == 0.0


@pytest.mark.parametrize("seed", [0, 1])
def test_clutter_samples_are_the_scene_clutter_under_a_detector_that_misplaces_boxes(seed):
    # the scene bank's "misplaced" family: the simulator knows which detections are clutter
    scene = generate_family_scene("misplaced", seed)
    keep = scene.det_table.frames <= 300
    det = scene.det_table.select(keep)
    gt = scene.gt_table.select(scene.gt_table.frames <= 300)
    truth = scene.is_clutter[keep]
    true_set = {tuple(np.round(row, 3)) for row in np.c_[det.frames[truth], det.boxes[truth]]}

    def precision_recall(events):
        centres = events.values
        boxes = np.c_[centres[:, :2] - centres[:, 2:] / 2, centres[:, 2:]]
        found = np.array([tuple(np.round(r, 3)) in true_set for r in np.c_[events.frames, boxes]])
        return found.mean(), found.sum() / len(true_set)

    every = clutter_samples_from_gt(det, gt, (1, 300), object_overlap=None)
    events = clutter_samples_from_gt(det, gt, (1, 300))
    # every unmatched detection: mostly people's badly placed boxes (precision 0.26-0.36)
    assert precision_recall(every)[0] < 0.4
    # without the ones overlapping a person: the scene's clutter, at the cost of the clutter
    # that happens to overlap a person (recall 0.90-0.95)
    precision, recall = precision_recall(events)
    assert precision > 0.9 and recall > 0.85
    assert events.count + events.object_overlaps == every.count


def test_chance_overlap_counts_clutter_landing_on_objects_of_other_frames():
    # one object, always at the same place in frames 1..10; clutter boxes at frames 1..10,
    # the first four on the object's place (they would have been left out in a frame where
    # the object is present) and six elsewhere
    objects = MotTable.from_arrays(
        np.arange(1, 11), np.ones(10, int), np.tile([[0.0, 0.0, 10.0, 20.0]], (10, 1))
    )
    boxes = np.array([[1.0, 1.0, 10.0, 20.0]] * 4 + [[100.0, 100.0, 10.0, 20.0]] * 6)
    assert chance_overlap(boxes, np.arange(1, 11), objects, (1, 10), 0.2) == pytest.approx(0.4)
    # the object present only in frames 1..5: every shift lands half the boxes on empty
    # frames; hits only where a box on the place meets a frame with the object
    half = objects.select(objects.frames <= 5)
    shifted = [1 + (f - 1 + s) % 10 for s in (2, 4, 6, 8) for f in range(1, 5)]
    expected = np.sum(np.array(shifted) <= 5) / 40
    assert chance_overlap(boxes, np.arange(1, 11), half, (1, 10), 0.2) == pytest.approx(expected)
    assert chance_overlap(boxes[:0], np.arange(0), objects, (1, 10), 0.2) == 0.0
