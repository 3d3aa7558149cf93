"""Retrodiction: tracks extended backwards onto the detections before their first box."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from jaxtrack.association.retrodiction import detection_rows, retrodict
from jaxtrack.errors import InputError
from jaxtrack.filters.phd_tracker import PHDConfig
from jaxtrack.pipelines.tracking import track_sequences
from jaxtrack.types import PAD_BOX, Detections, MotTable

W, H = 20.0, 40.0


def _table(rows):
    """A table from ``(frame, id, x, y)`` rows, boxes ``W x H``, scores ``0.1 * frame``."""
    frames, ids, xs, ys = (np.asarray(column) for column in zip(*rows, strict=True))
    boxes = np.stack([xs, ys, np.full(xs.shape, W), np.full(xs.shape, H)], axis=1)
    return MotTable.from_arrays(frames, ids, boxes, 0.1 * frames)


def _rows_set(table):
    return sorted(
        (int(f), int(i), *np.round(b, 6).tolist())
        for f, i, b in zip(table.frames, table.ids, table.boxes, strict=True)
    )


def test_walks_back_with_the_tracks_velocity_onto_free_detections_only():
    # Track 7 starts at frame 6 at x = 100, moving +10 px per frame (rows 6-11). Its
    # earlier detections lie on the constant-velocity path (x = 90, 80, 70 at frames 5-3,
    # with 1 px of noise); frame 2 has only a far detection, so the walk stops there even
    # though frame 1 has one on the path. Track 8 (x = 300, still) starts at frame 4; at
    # frame 3 the only detection near it is covered by track 9's row, so track 8 gets none.
    rows = _table(
        [(f, 7, 100.0 + 10 * (f - 6), 50.0) for f in range(6, 12)]
        + [(f, 8, 300.0, 50.0) for f in range(4, 9)]
        + [(3, 9, 302.0, 50.0)]
    )
    detections = _table(
        [
            (5, -1, 91.0, 50.0),
            (4, -1, 79.0, 51.0),
            (3, -1, 70.0, 50.0),
            (2, -1, 400.0, 50.0),
            (1, -1, 50.0, 50.0),
            (5, -1, 500.0, 90.0),
            (3, -1, 301.0, 50.0),
        ]
    )
    extended = retrodict(rows, detections, first_frame=1, max_frames=10)
    added = sorted(set(_rows_set(extended)) - set(_rows_set(rows)))
    # The hand-worked answer: track 7 takes frames 5, 4, 3 (the detections' own boxes).
    assert added == [
        (3, 7, 70.0, 50.0, W, H),
        (4, 7, 79.0, 51.0, W, H),
        (5, 7, 91.0, 50.0, W, H),
    ]
    # Every original row is kept, unchanged; the result is sorted by frame and identity.
    assert set(_rows_set(rows)) <= set(_rows_set(extended))
    order = np.lexsort((extended.ids, extended.frames))
    np.testing.assert_array_equal(order, np.arange(len(extended)))
    # Added rows carry the detection's score.
    taken = (extended.ids == 7) & (extended.frames < 6)
    np.testing.assert_allclose(extended.confs[taken], [0.3, 0.4, 0.5])


def test_limits_max_frames_first_frame_and_one_detection_per_frame():
    rows = _table([(f, 1, 100.0, 50.0) for f in range(10, 14)])
    detections = _table([(f, -1, 100.0, 50.0) for f in range(1, 10)])
    assert len(retrodict(rows, detections, 1, 0)) == len(rows)
    three = retrodict(rows, detections, 1, 3)
    assert sorted(three.frames[three.frames < 10].tolist()) == [7, 8, 9]
    bounded = retrodict(rows, detections, 6, 100)
    assert sorted(bounded.frames[bounded.frames < 10].tolist()) == [6, 7, 8, 9]
    # Two tracks on one path: the one that starts first takes the detection; the other
    # finds it covered and stops.
    two = _table([(f, 1, 100.0, 50.0) for f in range(10, 14)] + [(11, 2, 100.0, 50.0)])
    extended = retrodict(two, detections, 1, 3)
    assert not np.any((extended.ids == 2) & (extended.frames < 11))
    assert np.sum(extended.frames == 9) == 1
    # A second detection that the taken one overlaps (IoU 0.82) is covered too: track 2,
    # on it, finds no free detection at frame 9.
    crowded = _table([(9, -1, 100.0, 50.0), (9, -1, 102.0, 50.0)])
    two = _table([(f, 1, 100.0, 50.0) for f in range(10, 14)] + [(10, 2, 102.0, 50.0)])
    extended = retrodict(two, crowded, 1, 3)
    assert sorted(extended.ids[extended.frames == 9].tolist()) == [1]


def test_detection_rows_lists_the_masked_slots():
    boxes = np.tile(np.asarray(PAD_BOX, np.float32), (3, 2, 1))
    boxes[0, 1] = (1, 2, 3, 4)
    boxes[2, 0] = (5, 6, 7, 8)
    scores = np.array([[0, 0.9], [0, 0], [0.4, 0]], np.float32)
    mask = np.array([[False, True], [False, False], [True, False]])
    table = detection_rows(Detections(boxes, scores, mask), first_frame=11)
    np.testing.assert_array_equal(table.frames, [11, 13])
    np.testing.assert_array_equal(table.boxes, [[1, 2, 3, 4], [5, 6, 7, 8]])
    np.testing.assert_allclose(table.confs, [0.9, 0.4])


def test_online_output_with_retrodiction_is_refused():
    with pytest.raises(InputError, match="offline"):
        PHDConfig(output="online", retrodiction=5)
    config = PHDConfig(retrodiction=25)
    assert PHDConfig.from_dict(config.to_dict()) == config


def test_fusion_retrodiction_walks_at_its_support_gate():
    """The Fusion tracker's retrodiction takes a detection that overlaps the walked box by
    IoU 12/28 = 0.43 (its support gate is 0.3); the PHD tracker's (IoU 0.5) does not."""
    from types import SimpleNamespace

    from jaxtrack.filters.fusion_tracker import FusionConfig
    from jaxtrack.pipelines.tracking import output_rows
    from jaxtrack.types import Tracks

    # one slot, identity 1, still at x = 100 on frames 4-6 (score 1); frames 1-3 empty
    present = np.arange(6)[:, None] >= 3
    boxes = np.where(present[..., None], np.array([100.0, 50.0, W, H]), np.array(PAD_BOX))
    tracks = Tracks(boxes, np.where(present, 1, -1), present.astype(float), present)
    info = SimpleNamespace(tracks=tracks, candidates=tracks)
    # a detection on frame 3 shifted by 8 px (IoU (20 - 8) / (20 + 8) with the track's box)
    det_boxes = np.tile(np.asarray(PAD_BOX, np.float32), (6, 1, 1))
    det_boxes[2, 0] = (108.0, 50.0, W, H)
    mask = np.zeros((6, 1), bool)
    mask[2, 0] = True
    detections = Detections(det_boxes, mask.astype(np.float32), mask)
    fusion = output_rows(
        info, FusionConfig(retrodiction=5, max_gap=0, smoothing="none"), 1, detections
    )
    phd = output_rows(info, PHDConfig(retrodiction=5, max_gap=0), 1, detections)
    assert sorted(fusion.frames.tolist()) == [3, 4, 5, 6]
    np.testing.assert_allclose(fusion.boxes[fusion.frames == 3], [[108.0, 50.0, W, H]])
    assert sorted(phd.frames.tolist()) == [4, 5, 6]
    with pytest.raises(InputError, match="offline"):
        FusionConfig(output="online", retrodiction=5)


def test_tracker_with_retrodiction_adds_rows_on_detections_and_fewer_misses(mot15_root):
    """TUD-Campus 1:40 (its own detections and ground truth): the retrodicted output is the
    plain output plus rows that are detections of the run, each before its track's first
    plain row; it misses fewer ground-truth boxes and keeps every identity."""
    from jaxtrack.experiments.common import evaluate_rows
    from jaxtrack.io import load_sequence

    seq = load_sequence(mot15_root / "TUD-Campus", frames=(1, 40))
    config = PHDConfig(num_particles=512)
    (plain,) = track_sequences([seq], config, 0)
    (extended,) = track_sequences([seq], dataclasses.replace(config, retrodiction=25), 0)
    old, new = set(_rows_set(plain)), set(_rows_set(extended))
    assert old < new
    first = {int(i): int(plain.frames[plain.ids == i].min()) for i in np.unique(plain.ids)}
    table = seq.det_table
    for frame, identity, *box in new - old:
        # The padded detections are float32: the row is a detection to 1e-3 px.
        gap = np.abs(table.boxes[table.frames == frame] - np.asarray(box)).max(axis=1)
        assert gap.min() < 1e-3
        assert frame < first[identity]
    assert set(np.unique(extended.ids)) == set(np.unique(plain.ids))
    before, after = evaluate_rows(seq, plain), evaluate_rows(seq, extended)
    assert after.summary()["FN"] < before.summary()["FN"]


def test_birth_run_of_learn_context_ignores_retrodiction(mot15_root):
    from jaxtrack.io import load_sequence
    from jaxtrack.pipelines.context import uniform_tracker_rows

    seq = load_sequence(mot15_root / "TUD-Campus", frames=(1, 40))
    config = PHDConfig(num_particles=512)
    plain = uniform_tracker_rows(seq, 0, config)
    retro = uniform_tracker_rows(seq, 0, config.replace(retrodiction=25))
    assert _rows_set(plain) == _rows_set(retro)
    # ... although retrodiction would add rows to that run's tracks.
    detections = detection_rows(seq.detections, seq.first_frame)
    assert len(retrodict(plain, detections, seq.first_frame, 25)) > len(plain)
