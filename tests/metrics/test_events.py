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
    matched_identities,
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


def test_scripted_onsets_by_hand():
    events = [
        ScriptedEvent("entry", (1,), (5, 5), "west"),
        ScriptedEvent("entry", (2,), (5, 5), "west"),
        ScriptedEvent("entry", (3,), (5, 5), "east"),
        ScriptedEvent("group", (1, 2), (5, 40)),
        ScriptedEvent("crossing", (3, 4), (20, 30)),
        ScriptedEvent("occlusion", (4,), (50, 60)),
        ScriptedEvent("exit", (3,), (70, 70), "south"),
    ]
    onsets = scripted_onsets(events)
    np.testing.assert_array_equal(onsets["group"], [[5, 1], [5, 2], [20, 3], [20, 4]])
    np.testing.assert_array_equal(onsets["split"], [[40, 1], [40, 2], [30, 3], [30, 4]])
    np.testing.assert_array_equal(onsets["entry"], [[5, 3]])  # 1, 2 enter as a group
    np.testing.assert_array_equal(onsets["exit"], [[70, 3]])


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
    # tracker 11 splits 3 frames late, tracker 5 splits 6 frames late.
    names = {11: ["single"] * 60, 5: ["single"] * 60}
    names[11][21:33] = ["grouping"] * 12
    names[5][19:22] = ["grouping"] * 3
    names[5][25:36] = ["grouped"] * 11
    rows = rows_of([(f, i, names[i][f - 1]) for f in range(1, 61) for i in (11, 5)])
    scores = score_events(rows, results, gt, scripted, tolerance=5)
    assert scores["group"] == {
        "predicted": 3,
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
    assert scores["entry"]["scripted"] == sum(e.kind == "entry" for e in scene.events) - 3
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
    # person 1 (a lone walker, frames 17-187) "groups" on frames 100-102: one spurious group
    # onset (100) and one spurious split onset (103).
    names = rows.names.copy()
    names[(rows.ids == 1) & (rows.frames >= 100) & (rows.frames <= 102)] = "grouping"
    scores = score_events(rows._replace(names=names), gt, gt, scene.events)
    assert scores["group"]["precision"] == 5 / 6 and scores["split"]["precision"] == 5 / 6
    total = clean["overall"]["predicted"]
    assert scores["overall"]["precision"] == total / (total + 2)
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
