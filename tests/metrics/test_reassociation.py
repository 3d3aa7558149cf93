"""Identity kept across scripted events (jaxtrack.metrics.reassociation), on hand-made tables."""

from __future__ import annotations

import numpy as np

from jaxtrack.datasets.video_scene import ScriptedEvent
from jaxtrack.metrics.reassociation import count_cases, identity_cases, identity_kept
from jaxtrack.types import MotTable


def table(rows) -> MotTable:
    """``(frame, id, x)`` rows as boxes ``(x, 10, 20, 40)``, confidence 1."""
    rows = np.asarray(rows, float)
    boxes = np.stack([rows[:, 2], np.full(len(rows), 10.0), np.full(len(rows), 20.0),
                      np.full(len(rows), 40.0)], 1)  # fmt: skip
    return MotTable.from_arrays(rows[:, 0].astype(int), rows[:, 1].astype(int), boxes,
                                np.ones(len(rows)))  # fmt: skip


def walk(identity, frames, x0=0.0):
    return [(f, identity, x0 + 2 * f) for f in frames]


def test_kept_switched_and_unscored_cases():
    # person 1 hidden on frames 10-20, seen before and after; person 2 likewise, 100 px away
    gt = table(
        walk(1, [*range(1, 10), *range(21, 31)]) + walk(2, [*range(1, 10), *range(21, 31)], 100)
    )
    results = table(
        walk(7, range(1, 10))  # person 1: tracker 7 before ...
        + walk(7, range(21, 31))  # ... and after: kept
        + walk(8, range(1, 10), 100)  # person 2: tracker 8 before ...
        + walk(9, range(21, 31), 100)  # ... and 9 after: switched
    )
    events = [ScriptedEvent("occlusion", (1,), (10, 20)), ScriptedEvent("crossing", (2,), (10, 20))]
    kept = identity_kept(results, gt, events, window=5)
    assert kept["occlusion"] == {"cases": 1, "kept": 1, "lost": 0, "unscored": 0, "rate": 1.0}
    assert kept["crossing"] == {"cases": 1, "kept": 0, "lost": 0, "unscored": 0, "rate": 0.0}
    assert kept["overall"]["cases"] == 2 and kept["overall"]["rate"] == 0.5
    assert kept["group"]["rate"] is None
    # in view after the event but picked up again only beyond the window: lost, a failure
    late = table(walk(7, range(1, 10)) + walk(7, range(27, 31)))
    scored = identity_kept(late, gt, events[:1], window=5)
    assert scored["occlusion"] == {"cases": 1, "kept": 0, "lost": 1, "unscored": 0, "rate": 0.0}
    # gone from the ground truth after the event, or never matched before it: unscored
    gone = table(walk(1, range(1, 10)))
    for results in (late, table(walk(7, range(21, 31)))):
        scored = identity_kept(results, gone if results is late else gt, events[:1], window=5)
        assert scored["occlusion"] == {
            "cases": 0, "kept": 0, "lost": 0, "unscored": 1, "rate": None
        }  # fmt: skip


def test_group_compares_the_walk_with_after_the_split():
    gt = table(walk(3, range(1, 31)))
    results = table(walk(4, range(1, 21)) + walk(5, range(21, 31)))
    events = [ScriptedEvent("group", (3,), (5, 20)), ScriptedEvent("entry", (3,), (1, 1), "a")]
    kept = identity_kept(results, gt, events, window=5)
    assert kept["group"] == {"cases": 1, "kept": 0, "lost": 0, "unscored": 0, "rate": 0.0}
    assert kept["overall"]["cases"] == 1  # the entry is not an identity case


def test_group_identity_swapped_during_the_walk_is_not_kept():
    # the walk is frames 1-20; tracker 4 picks the person up, 5 takes over at frame 12 and
    # keeps them after the split: the identity after (5) is not the walk's first (4)
    gt = table(walk(3, range(1, 31)))
    results = table(walk(4, range(1, 12)) + walk(5, range(12, 31)))
    kept = identity_kept(results, gt, [ScriptedEvent("group", (3,), (1, 20))], window=5)
    assert kept["group"] == {"cases": 1, "kept": 0, "lost": 0, "unscored": 0, "rate": 0.0}
    same = table(walk(4, range(3, 31)))  # picked up on frame 3, the same identity throughout
    kept = identity_kept(same, gt, [ScriptedEvent("group", (3,), (1, 20))], window=5)
    assert kept["group"] == {"cases": 1, "kept": 1, "lost": 0, "unscored": 0, "rate": 1.0}


def test_cases_name_each_person_identities_and_outcome():
    gt = table(
        walk(1, [*range(1, 10), *range(21, 31)]) + walk(2, [*range(1, 10), *range(21, 31)], 100)
    )
    results = table(
        walk(7, range(1, 10)) + walk(7, range(21, 31)) + walk(8, range(1, 10), 100)
        + walk(9, range(21, 31), 100)
    )  # fmt: skip
    events = [
        ScriptedEvent("entry", (1,), (1, 1), "a"),
        ScriptedEvent("occlusion", (1,), (10, 20)),
        ScriptedEvent("crossing", (2,), (10, 20)),
    ]
    cases = identity_cases(results, gt, events, window=5)
    assert cases == [
        {"kind": "occlusion", "person": 1, "frames": [10, 20], "before": 7, "after": 7,
         "outcome": "kept"},
        {"kind": "crossing", "person": 2, "frames": [10, 20], "before": 8, "after": 9,
         "outcome": "switched"},
    ]  # fmt: skip
    assert count_cases(cases, 5) == identity_kept(results, gt, events, window=5)
    late = table(walk(7, range(1, 10)) + walk(7, range(27, 31)))
    (lost,) = identity_cases(late, gt, events[1:2], window=5)
    assert (lost["before"], lost["after"], lost["outcome"]) == (7, None, "lost")
    (unmatched,) = identity_cases(table(walk(7, range(21, 31))), gt, events[1:2], window=5)
    assert (unmatched["before"], unmatched["after"], unmatched["outcome"]) == (None, 7, "unscored")
