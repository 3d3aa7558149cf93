"""Result rows and offline finishing (back-filled confirmation, gap interpolation)."""

from __future__ import annotations

import numpy as np

from jaxtrack.association.offline import finalise_tracks, track_rows
from jaxtrack.types import PAD_BOX, Tracks


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
