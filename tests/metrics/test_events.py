"""Event precision / recall against scripted events: hand-made onsets and a synthetic video
scene's events with perfect, shifted and spurious predictions."""

from __future__ import annotations

import numpy as np
import pytest

from jaxtrack.datasets.video_scene import ScriptedEvent, generate_video_scene
from jaxtrack.errors import InputError
from jaxtrack.filters.hier_events import EVENT_NAMES
from jaxtrack.metrics.events import (
    DEFAULT_TOLERANCE,
    GROUP_STATES,
    KINDS,
    EventRows,
    gt_collisions,
    matched_identities,
    onset_summary,
    pool_scores,
    predicted_onsets,
    score_events,
    scripted_onsets,
)
from jaxtrack.types import MotTable


def rows_of(triples) -> EventRows:
    frames, ids, names = zip(*triples, strict=True)
    return EventRows(np.array(frames), np.array(ids), np.array(names))


def test_names_are_event_names():
    assert set(GROUP_STATES) | {"entering", "exiting"} <= set(EVENT_NAMES)


def test_predicted_onsets_by_hand():
    names = ["entering", "entering", "single", "grouping", "grouped", "splitting", "single"]
    names += ["grouping", "single", "exiting", "exiting"]
    rows = rows_of([(f, 7, n) for f, n in enumerate(names, start=10)])
    # a second identity starting grouped and ending in a group (no split, no exit)
    rows = EventRows(
        np.concatenate([[3, 4], rows.frames]),
        np.concatenate([[2, 2], rows.ids]),
        np.concatenate([["grouped", "grouping"], rows.names]),
    )
    onsets = predicted_onsets(rows)
    np.testing.assert_array_equal(onsets["group"], [[3, 2], [13, 7], [17, 7]])
    np.testing.assert_array_equal(onsets["split"], [[15, 7], [18, 7]])
    np.testing.assert_array_equal(onsets["entry"], [[10, 7]])
    np.testing.assert_array_equal(onsets["exit"], [[20, 7]])
    assert onset_summary(rows) == "onsets: 3 group, 2 split, 1 entry, 1 exit"


def collisions_loop(gt: MotTable) -> np.ndarray:
    """Slow oracle of gt_collisions."""
    out = np.zeros(len(gt), bool)
    by_frame = {}
    for row, frame in enumerate(gt.frames.tolist()):
        by_frame.setdefault(frame, []).append(row)
    for rows in by_frame.values():
        for a in rows:
            for b in rows:
                (xa, ya, wa, ha), (xb, yb, wb, hb) = gt.boxes[a], gt.boxes[b]
                w = min(xa + wa, xb + wb) - max(xa, xb)
                h = min(ya + ha, yb + hb) - max(ya, yb)
                out[a] |= a != b and w > 0 and h > 0
    return out


def test_gt_collisions_match_loop():
    rng = np.random.default_rng(1)
    frames = rng.integers(1, 6, 40)
    boxes = np.concatenate([rng.uniform(0, 50, (40, 2)), rng.uniform(3, 15, (40, 2))], 1)
    boxes[0] = boxes[1] + [boxes[1, 2], 0, 0, 0]  # touching (no area): not a collision
    frames[0] = frames[1]
    gt = MotTable.from_arrays(frames, np.arange(40), boxes)
    expected = collisions_loop(gt)
    assert 5 < expected.sum() < 35
    np.testing.assert_array_equal(gt_collisions(gt), expected)


def hand_scene() -> MotTable:
    """People 1 and 2 enter together on frame 5 and overlap until 40; 3 enters alone on 5,
    crosses 4 on frames 20-30 and leaves on 70; 4 stays from 10 to the end (80)."""
    rows = []
    for f in range(5, 46):
        rows += [(f, 1, 0), (f, 2, 5 if f <= 40 else 50)]
    for f in range(5, 71):
        rows.append((f, 3, 300 if 20 <= f <= 30 else 200))
    for f in range(10, 81):
        rows.append((f, 4, 305))
    frames, ids, x = map(np.array, zip(*rows, strict=True))
    boxes = np.stack([x, np.zeros_like(x), np.full_like(x, 10), np.full_like(x, 20)], 1)
    return MotTable.from_arrays(frames, ids, boxes.astype(float))


def test_scripted_onsets_by_hand():
    events = [
        ScriptedEvent("entry", (1,), (5, 5), "west"),
        ScriptedEvent("entry", (2,), (5, 5), "west"),
        ScriptedEvent("entry", (3,), (5, 5), "east"),
        ScriptedEvent("group", (1, 2), (5, 40)),
        ScriptedEvent("entry", (4,), (10, 10), "east"),
        ScriptedEvent("crossing", (3, 4), (20, 30)),
        ScriptedEvent("occlusion", (4,), (50, 60)),
        ScriptedEvent("exit", (3,), (70, 70), "south"),
    ]
    scored, unscored = scripted_onsets(events, hand_scene())
    np.testing.assert_array_equal(scored["group"], [[5, 1], [5, 2], [20, 3], [20, 4]])
    np.testing.assert_array_equal(scored["split"], [[40, 1], [40, 2], [30, 3], [30, 4]])
    np.testing.assert_array_equal(scored["entry"], [[5, 3], [10, 4]])  # 1, 2 enter together
    np.testing.assert_array_equal(scored["exit"], [[70, 3]])
    # every start and end of an overlap run, and the entries of 1 and 2, are unscored truths
    np.testing.assert_array_equal(unscored["group"], [[5, 1], [5, 2], [20, 3], [20, 4]])
    np.testing.assert_array_equal(unscored["split"], [[41, 1], [41, 2], [31, 3], [31, 4]])
    np.testing.assert_array_equal(unscored["entry"], [[5, 1], [5, 2]])
    assert unscored["exit"].shape == (0, 2)


def two_people(tracker_ids=(1, 2)) -> tuple[MotTable, MotTable]:
    """Gt ids 1, 2 on frames 1..60, far apart; results follow them with other ids."""
    frames = np.repeat(np.arange(1, 61), 2)
    gt_ids = np.tile([1, 2], 60)
    boxes = np.where(gt_ids[:, None] == 1, [[0, 0, 10, 20]], [[100, 0, 10, 20]]).astype(float)
    gt = MotTable.from_arrays(frames, gt_ids, boxes)
    results = MotTable.from_arrays(frames, np.array(tracker_ids)[gt_ids - 1], boxes + 0.5)
    return gt, results


def test_matched_identities_maps_tracker_to_gt_ids():
    gt, results = two_people((11, 5))
    matches = matched_identities(results, gt)
    assert len(matches) == 120
    np.testing.assert_array_equal(np.unique(matches[:, 1:], axis=0), [[1, 11], [2, 5]])
    np.testing.assert_array_equal(matches[matches[:, 1] == 2, 0], np.arange(1, 61))


def test_identity_tolerance_and_one_to_one():
    gt, results = two_people((11, 5))
    scripted = [ScriptedEvent("crossing", (1, 2), (20, 30))]
    # tracker 11 (gt 1) groups at 22, tracker 5 (gt 2) at 20 and again at 26 (a duplicate);
    # tracker 11 splits 4 frames late, tracker 5 splits 7 frames early and 7 late.
    names = {11: ["single"] * 60, 5: ["single"] * 60}
    names[11][21:33] = ["grouping"] * 12
    names[5][19:22] = ["grouping"] * 3
    names[5][25:36] = ["grouped"] * 11
    rows = rows_of([(f, i, names[i][f - 1]) for f in range(1, 61) for i in (11, 5)])
    scores = score_events(rows, results, gt, scripted, tolerance=5)
    assert scores["group"] == {
        "predicted": 3,
        "ignored": 0,
        "scripted": 2,
        "matched": 2,
        "precision": 2 / 3,
        "recall": 1.0,
    }
    # splits: tracker 11 at 34 (4 late) and tracker 5 at 23 and 37 (7 off: beyond 5).
    assert (scores["split"]["predicted"], scores["split"]["matched"]) == (3, 1)
    assert scores["overall"]["matched"] == 3 and scores["overall"]["predicted"] == 6
    assert scores["overall"]["precision"] == 0.5 and scores["overall"]["recall"] == 3 / 4
    # an onset counts only for the person its tracker follows: tracker 11 (at 22) follows
    # gt 1 in `results`, gt 2 in `crossed`; a scripted event of gt 1 alone.
    alone = [ScriptedEvent("group", (1,), (20, 30))]
    lone_rows = rows._replace(names=np.where(rows.ids == 11, rows.names, "single"))
    crossed = MotTable.from_arrays(gt.frames, np.tile([5, 11], 60), results.boxes)
    assert score_events(lone_rows, results, gt, alone, 5)["group"]["matched"] == 1
    assert score_events(lone_rows, crossed, gt, alone, 5)["group"]["matched"] == 0
    with pytest.raises(InputError, match="tolerance"):
        score_events(rows, results, gt, scripted, tolerance=-1)


def test_onsets_of_unscripted_overlaps_are_ignored():
    gt, results = two_people((11, 5))
    # gt 2 moves onto gt 1 on frames 40-44: an overlap the script does not name.
    moved = (gt.ids == 2) & (gt.frames >= 40) & (gt.frames <= 44)
    boxes = np.where(moved[:, None], gt.boxes - [95, 0, 0, 0], gt.boxes)
    gt = MotTable.from_arrays(gt.frames, gt.ids, boxes)
    results = MotTable.from_arrays(results.frames, results.ids, boxes + 0.5)
    # tracker 11 groups on 41-44 (the overlap: ignored) and on 10-12 (spurious).
    names = np.full(len(results), "single", "<U9")
    frames = results.frames
    span = ((frames >= 41) & (frames <= 44)) | ((frames >= 10) & (frames <= 12))
    names[(results.ids == 11) & span] = "grouping"
    rows = EventRows(results.frames, results.ids, names)
    scores = score_events(rows, results, gt, [ScriptedEvent("exit", (2,), (60, 60))], 5)
    for kind in ("group", "split"):
        assert (scores[kind]["predicted"], scores[kind]["ignored"]) == (2, 1)
        assert scores[kind]["precision"] == 0.0  # 0 matched of 2 - 1
    assert scores["overall"]["ignored"] == 2 and scores["overall"]["recall"] == 0.0


@pytest.fixture(scope="module")
def scene():
    return generate_video_scene(0)


def perfect_rows(scene) -> EventRows:
    """Events whose onsets fall exactly on the scripted frames, with the ground-truth ids:
    grouping over the scripted group and crossing spans ``first <= f < last``, entering on
    each person's first frame, exiting on the last frame of each person who exits."""
    gt = scene.gt_table
    names = np.full(len(gt), "single", dtype="<U9")
    for event in scene.events:
        person = np.isin(gt.ids, event.ids)
        first, last = event.frames
        if event.kind == "entry":
            names[person & (gt.frames == first)] = "entering"
        if event.kind == "exit":
            names[person & (gt.frames == last)] = "exiting"
    for event in scene.events:
        first, last = event.frames
        if event.kind in ("crossing", "group"):  # split onsets exactly on `last`
            names[np.isin(gt.ids, event.ids) & (gt.frames >= first) & (gt.frames < last)] = (
                "grouping"
            )
    return EventRows(gt.frames.copy(), gt.ids.copy(), names)


def test_perfect_predictions_score_one(scene):
    rows = perfect_rows(scene)
    scores = score_events(rows, scene.gt_table, scene.gt_table, scene.events)
    for kind in (*KINDS, "overall"):
        assert scores[kind]["precision"] == scores[kind]["recall"] == 1.0, kind
    assert scores["group"]["scripted"] == 5  # a group of 3 and a crossing of 2
    gt = scene.gt_table
    colliding = collisions_loop(gt)
    touching = set(zip(gt.frames[colliding].tolist(), gt.ids[colliding].tolist(), strict=True))
    entries = [e for e in scene.events if e.kind == "entry"]
    alone = [e for e in entries if (e.frames[0], e.ids[0]) not in touching]
    assert 0 < len(alone) < len(entries)
    assert scores["entry"]["scripted"] == len(alone)
    assert scores["tolerance"] == DEFAULT_TOLERANCE


def test_shifted_predictions(scene):
    rows = perfect_rows(scene)
    gt = scene.gt_table
    for shift, expected in ((DEFAULT_TOLERANCE, 1.0), (DEFAULT_TOLERANCE + 1, 0.0)):
        moved = rows._replace(frames=rows.frames + shift)
        scores = score_events(moved, gt, gt, scene.events)
        for kind in (*KINDS, "overall"):
            assert scores[kind]["precision"] == scores[kind]["recall"] == expected, (shift, kind)


def test_spurious_onset_lowers_precision_only(scene):
    rows = perfect_rows(scene)
    gt = scene.gt_table
    clean = score_events(rows, gt, gt, scene.events)
    # a person who overlaps nobody on frames f - 30 .. f + 33 "groups" on frames f .. f + 2:
    # one spurious group onset (f) and one spurious split onset (f + 3), neither ignored.
    colliding = collisions_loop(gt)
    pid, f = next(
        (pid, f)
        for pid in range(1, scene.num_people + 1)
        for f in range(50, 450, 10)
        if np.sum((gt.ids == pid) & (abs(gt.frames - f - 1) <= 32)) == 65
        and not colliding[(gt.ids == pid) & (abs(gt.frames - f - 1) <= 32)].any()
    )
    names = rows.names.copy()
    names[(rows.ids == pid) & (rows.frames >= f) & (rows.frames <= f + 2)] = "grouping"
    scores = score_events(rows._replace(names=names), gt, gt, scene.events)
    assert scores["group"]["precision"] == 5 / 6 and scores["split"]["precision"] == 5 / 6
    matched = clean["overall"]["matched"]  # all predicted onsets not ignored (precision 1)
    assert clean["overall"]["precision"] == 1.0 and matched > 30
    assert scores["overall"]["precision"] == matched / (matched + 2)
    for kind in (*KINDS, "overall"):
        assert scores[kind]["recall"] == 1.0


def test_no_output_scores_zero(scene):
    gt = scene.gt_table
    nothing = MotTable.from_arrays([], [], np.zeros((0, 4)))
    rows = EventRows(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, "<U9"))
    scores = score_events(rows, nothing, gt, scene.events)
    assert scores["overall"]["predicted"] == scores["overall"]["matched"] == 0
    assert scores["overall"]["scripted"] > 0
    assert scores["overall"]["precision"] == scores["overall"]["recall"] == 0.0


def counts(predicted, ignored, scripted, matched) -> dict:
    return {"predicted": predicted, "ignored": ignored, "scripted": scripted, "matched": matched}


def test_pooled_scores_sum_the_counts_and_keep_ignored_onsets_out():
    # run A: 10 onsets, 4 of them ignored, 5 matched of 8 scripted; run B: 4 onsets, 4 matched
    # of 4. Pooled: 9 matched of 14 - 4 scored onsets, of 12 scripted (not 9 / 14).
    a = {kind: counts(0, 0, 0, 0) for kind in KINDS} | {"tolerance": 5}
    b = {kind: counts(0, 0, 0, 0) for kind in KINDS} | {"tolerance": 5}
    a["group"], a["overall"] = counts(10, 4, 8, 5), counts(10, 4, 8, 5)
    b["exit"], b["overall"] = counts(4, 0, 4, 4), counts(4, 0, 4, 4)
    pooled = pool_scores([a, b])
    assert pooled["tolerance"] == 5
    assert pooled["overall"] == {**counts(14, 4, 12, 9), "precision": 0.9, "recall": 0.75}
    assert pooled["group"]["precision"] == 5 / 6 and pooled["exit"]["recall"] == 1.0
    assert pooled["split"] == {**counts(0, 0, 0, 0), "precision": 0.0, "recall": 0.0}


def test_pooled_scores_of_one_run_are_that_run_s(scene):
    scores = score_events(perfect_rows(scene), scene.gt_table, scene.gt_table, scene.events)
    assert pool_scores([scores]) == scores
    with pytest.raises(InputError, match="tolerances"):
        pool_scores([scores, {**scores, "tolerance": 3}])
    with pytest.raises(InputError, match="no event scores"):
        pool_scores([])
