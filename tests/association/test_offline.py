"""Result rows and offline finishing (back-filled confirmation, gap interpolation)."""

from __future__ import annotations

import numpy as np

from jaxtrack.association.offline import (
    chain_candidates,
    finalise_tracks,
    gap_breaks,
    track_rows,
)
from jaxtrack.types import PAD_BOX, MotTable, Tracks


def _tracks(rows, num_frames=8, capacity=3):
    """Tracks from ``(frame_index, slot, id, x)`` rows; boxes ``(x, 10, 20, 40)``."""
    boxes = np.tile(np.asarray(PAD_BOX), (num_frames, capacity, 1))
    ids = np.full((num_frames, capacity), -1)
    scores = np.zeros((num_frames, capacity))
    mask = np.zeros((num_frames, capacity), bool)
    for t, slot, identity, x in rows:
        boxes[t, slot] = (x, 10, 20, 40)
        ids[t, slot] = identity
        scores[t, slot] = 0.5 + 0.01 * t
        mask[t, slot] = True
    return Tracks(boxes=boxes, ids=ids, scores=scores, mask=mask)


def test_track_rows_lists_the_masked_slots():
    rows = track_rows(_tracks([(0, 1, 4, 10.0), (2, 0, 4, 30.0), (2, 2, 5, 90.0)]), first_frame=5)
    np.testing.assert_array_equal(rows.frames, [5, 7, 7])
    np.testing.assert_array_equal(rows.ids, [4, 4, 5])
    np.testing.assert_array_equal(rows.boxes[:, 0], [10, 30, 90])


def test_finalise_backfills_confirmed_tracks_and_interpolates_short_gaps():
    # id 1: tentative at frames 0-1, confirmed from 2, missing at 4-5, back at 6-7.
    # id 2: tentative only (never confirmed). id 3: confirmed, gap of 3 frames (too long).
    candidates = [(t, 0, 1, 10.0 * t) for t in (0, 1, 2, 3, 6, 7)]
    candidates += [(t, 1, 2, 200.0) for t in (0, 1, 2)]
    candidates += [(t, 2, 3, 300.0 + t) for t in (0, 4)]
    online = [(t, 0, 1, 10.0 * t) for t in (2, 3, 6, 7)] + [(0, 2, 3, 300.0), (4, 2, 3, 304.0)]
    rows = finalise_tracks(_tracks(online), _tracks(candidates), max_gap=2)
    id1 = rows.ids == 1
    np.testing.assert_array_equal(rows.frames[id1], np.arange(1, 9))
    np.testing.assert_allclose(rows.boxes[id1, 0], 10.0 * np.arange(8))
    np.testing.assert_allclose(rows.confs[id1][4:6], 0.53)
    assert not np.any(rows.ids == 2)
    np.testing.assert_array_equal(rows.frames[rows.ids == 3], [1, 5])
    assert np.all(np.diff(rows.frames) >= 0)
    no_gap = finalise_tracks(_tracks(online), _tracks(candidates))
    assert np.sum(no_gap.ids == 1) == 6


def test_a_break_leaves_the_last_gap_before_it_unfilled():
    """Identity 1 has rows on frames 1, 4, 5, 8, 9 (gaps 2-3 and 6-7, both short enough):
    a break at frame 8 (the re-association's frame, as :func:`gap_breaks` gives it) or 7
    (inside the gap: the gap ending at or before it is 2-3) leaves one gap unfilled; a break
    on identity 2 or at frame 1 (no gap before it) changes nothing."""
    frames = (0, 3, 4, 7, 8)
    tracks = _tracks([(t, 0, 1, 10.0 * t) for t in frames], num_frames=9)
    filled = finalise_tracks(tracks, tracks, max_gap=2)
    assert filled.frames[filled.ids == 1].tolist() == list(range(1, 10))
    for breaks, expected in (
        ({1: [8]}, [1, 2, 3, 4, 5, 8, 9]),
        ({1: [9]}, [1, 2, 3, 4, 5, 8, 9]),
        ({1: [7]}, [1, 4, 5, 6, 7, 8, 9]),
        ({1: [5, 8]}, [1, 4, 5, 8, 9]),
        ({2: [8]}, list(range(1, 10))),
        ({1: [1]}, list(range(1, 10))),
    ):
        rows = finalise_tracks(tracks, tracks, max_gap=2, breaks=breaks)
        assert rows.frames[rows.ids == 1].tolist() == expected, breaks


def test_gap_breaks_reads_the_flagged_slots_identities():
    flags = np.zeros((4, 3), bool)
    flags[1, 2] = flags[3, 0] = flags[3, 2] = True
    ids = np.array([[5, -1, 7], [5, -1, 7], [5, 6, 7], [9, 6, 7]])
    assert gap_breaks(flags, ids, first_frame=10) == {7: [11, 13], 9: [13]}
    assert gap_breaks(np.zeros((2, 2), bool), np.zeros((2, 2), int)) == {}


def _table(rows):
    """A table from ``(frame, id, x)`` rows, boxes ``(x, 10, 20, 40)``, scores 1."""
    frames, ids, xs = (np.asarray(column) for column in zip(*rows, strict=True))
    boxes = np.stack(
        [xs, np.full(xs.shape, 10.0), np.full(xs.shape, 20.0), np.full(xs.shape, 40.0)], 1
    )
    return MotTable.from_arrays(frames, ids, boxes)


def test_chain_candidates_walks_back_through_dropped_hypotheses():
    # Confirmed id 9 starts at frame 20 at x = 100, moving +2 px a frame (rows 20-25).
    # Hypothesis 3 (frames 12-17, x = 84 .. 94) ends 3 frames before it, where 9 walked back
    # lies (x = 94 at frame 17). Hypothesis 2 (frames 5-9, x = 76 .. 84) ends 3 frames before
    # 3 began, near 3 walked back at its own velocity (x = 78: IoU 14 / 26). Hypothesis 4
    # ends at frame 19 far away
    # (x = 400); hypothesis 5 ends at frame 1, 11 frames before 2 began.
    confirmed = [(f, 9, 100.0 + 2 * (f - 20)) for f in range(20, 26)]
    three = [(f, 3, 94.0 - 2 * (17 - f)) for f in range(12, 18)]
    two = [(f, 2, 84.0 - 2 * (9 - f)) for f in range(5, 10)]
    four = [(19, 4, 400.0)]
    five = [(1, 5, 70.0)]
    rows = _table(confirmed + three + two + four + five)
    chained = chain_candidates(rows, np.array([9]), max_gap=2, min_iou=0.3)
    np.testing.assert_array_equal(chained.frames, rows.frames)
    np.testing.assert_array_equal(chained.boxes, rows.boxes)
    assert np.all(chained.ids[rows.ids == 3] == 9) and np.all(chained.ids[rows.ids == 2] == 9)
    assert np.all(chained.ids[rows.ids == 4] == 4) and np.all(chained.ids[rows.ids == 5] == 5)
    assert np.all(chained.ids[rows.ids == 9] == 9)
    # A gap longer than max_gap + 1 stops the walk before hypothesis 3.
    short = chain_candidates(rows, np.array([9]), max_gap=1, min_iou=0.3)
    assert np.all(short.ids[rows.ids == 3] == 3)
    # An overlap below min_iou too: 3's last box 10 px off the walked box (IoU 10 / 30).
    off = _table(confirmed + [(f, 3, 104.0) for f in range(12, 18)])
    np.testing.assert_array_equal(chain_candidates(off, np.array([9]), 2, 0.34).ids, off.ids)
    np.testing.assert_array_equal(chain_candidates(off, np.array([9]), 2, 0.33).ids, [9] * 12)


def test_chain_candidates_gives_each_hypothesis_to_one_target_and_feeds_the_gaps():
    # Two confirmed identities on one path (7 from frame 10, 8 from frame 11): the earlier
    # takes hypothesis 1 (frames 5-8); 8 finds nothing left.
    rows = _table(
        [(f, 7, 50.0) for f in range(10, 13)]
        + [(f, 8, 50.0) for f in range(11, 13)]
        + [(f, 1, 50.0) for f in range(5, 9)]
    )
    chained = chain_candidates(rows, np.array([7, 8]), max_gap=3, min_iou=0.3)
    assert np.all(chained.ids[rows.ids == 1] == 7)
    # In finalise_tracks (frame indices; rows numbered from 1): hypothesis 2 (indices 0-2)
    # dropped, target 6's hypothesis from index 4, confirmed at 5; chained, 6's rows start at
    # frame 1 and the gap (frame 4) is interpolated; without chaining they start at frame 5.
    candidates = [(t, 1, 2, 20.0) for t in (0, 1, 2)] + [(t, 0, 6, 20.0) for t in (4, 5, 6, 7)]
    online = [(t, 0, 6, 20.0) for t in (5, 6, 7)]
    plain = finalise_tracks(_tracks(online), _tracks(candidates), max_gap=2)
    linked = finalise_tracks(_tracks(online), _tracks(candidates), max_gap=2, chain_iou=0.3)
    np.testing.assert_array_equal(plain.frames, [5, 6, 7, 8])
    np.testing.assert_array_equal(linked.frames, np.arange(1, 9))
    assert set(linked.ids.tolist()) == {6}


def test_the_fusion_configuration_chains_at_its_support_gate():
    from jaxtrack.filters.fusion_tracker import GATE, FusionConfig

    assert FusionConfig().chain_iou == GATE
    assert FusionConfig(hypothesis_rows="voted").chain_iou == 0.0
    assert FusionConfig(output="online").output == "online"  # the default is no error there
