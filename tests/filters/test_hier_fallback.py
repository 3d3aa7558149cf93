"""The fallback appearance (``HierarchicalConfig.fallback_appearance``): a tracker that has
never been single learns while colliding, and that model re-associates it when lost.

Oracle: a drawn scene whose truth is known exactly. Target 0 walks with a companion whose box
overlaps a quarter of its own (a collision at the event module's 10 %) from its first frame,
so under the paper's rule (learn only while single) it never learns an appearance; it is then
hidden longer than its track coasts and comes back beside the companion.
"""

from __future__ import annotations

import functools

import jax
import numpy as np
import pytest

from jaxtrack.filters.base import run
from jaxtrack.filters.hierarchical_tracker import HierarchicalConfig, build_hierarchical
from jaxtrack.pipelines.tracking import output_rows
from tests.filters.test_cmt import INFO, scene
from tests.filters.test_hierarchical import BACKGROUND, NUM_FRAMES, tracked

#: Frames in which target 0 is neither detected nor drawn (longer than the 12 frames a
#: low-level track coasts at 25 fps).
HIDDEN = range(20, 36)
#: Target 0, its companion (overlapping a quarter of its width) and a third target.
WALKER_COLOURS = [
    ((200, 30, 30), (30, 30, 200)),
    ((30, 200, 30), (200, 200, 30)),
    ((230, 230, 230), (20, 20, 20)),
]


#: The configuration of :func:`~tests.filters.test_hierarchical.tracked` (its output settings).
CONFIG = HierarchicalConfig(variant="full", max_tracks=8, max_trackers=8, fallback_appearance=1)


#: Frames before target 0 first shows (its companions' trackers exist by then).
LATE = 6


def _scene(companions, target, shown, colours):
    """:func:`~tests.filters.test_cmt.scene` of the ``companions[t]`` boxes, then target 0's
    ``target[t]`` on top on the frames where ``shown(t)``; ``colours``: the companions', then
    target 0's."""
    return scene(
        [[*companions[t], *([target[t]] if shown(t) else [])] for t in range(NUM_FRAMES)],
        colours,
    )


def group_scene():
    """Target 0 walks right between two companions, 12 px behind one and ahead of the other
    (each overlapping a quarter of its box). It shows from frame :data:`LATE`, so its tracker
    is born colliding with two existing trackers: a group tracker (Sec. 5.1). It is hidden in
    :data:`HIDDEN`."""
    x = [22.0 + 1.5 * t for t in range(NUM_FRAMES)]
    return _scene(
        [
            [(x[t] + 12.0, 20.0, 16.0, 36.0), (x[t] - 12.0, 20.0, 16.0, 36.0)]
            for t in range(NUM_FRAMES)
        ],
        [(x[t], 20.0, 16.0, 36.0) for t in range(NUM_FRAMES)],
        lambda t: t >= LATE and t not in HIDDEN,
        [WALKER_COLOURS[1], ((240, 140, 20), (120, 20, 160)), WALKER_COLOURS[0]],
    )


def walk_scene(apart_from=None):
    """Target 0 and its companion walk right side by side (boxes 16 wide, 12 px apart); target
    0 is hidden in :data:`HIDDEN`. A third target walks left on a lower row. From frame
    ``apart_from`` on (None: never) the companion walks twice as fast: their boxes part (no
    collision once 15 px apart, 2 frames later)."""
    x = [10.0 + 1.5 * t for t in range(NUM_FRAMES)]
    ahead = [
        12.0 + (1.5 * max(t - apart_from, 0) if apart_from is not None else 0.0)
        for t in range(NUM_FRAMES)
    ]
    return _scene(
        [
            [(x[t] + ahead[t], 20.0, 16.0, 36.0), (130.0 - 1.5 * t, 76.0, 16.0, 36.0)]
            for t in range(NUM_FRAMES)
        ],
        [(x[t], 20.0, 16.0, 36.0) for t in range(NUM_FRAMES)],
        lambda t: t not in HIDDEN,
        [WALKER_COLOURS[1], WALKER_COLOURS[2], WALKER_COLOURS[0]],
    )


def identities_of_target_0(rows):
    """The identities of the boxes at target 0's place before and after it is hidden."""
    expected_x = 10.0 + 1.5 * rows.frames
    on_target = (np.abs(rows.boxes[:, 0] - expected_x) < 5) & (np.abs(rows.boxes[:, 1] - 20) < 5)
    before = set(rows.ids[on_target & (rows.frames <= HIDDEN[0])].tolist())
    after = set(rows.ids[on_target & (rows.frames > HIDDEN[-1] + 8)].tolist())
    return before, after


@pytest.mark.parametrize(("fallback", "kept"), [(1, True), (0, False)])
def test_a_tracker_never_single_is_reassociated_by_its_fallback_model(fallback, kept):
    """With the fallback, target 0 keeps its identity across the occlusion; under the paper's
    rule its tracker has no model and the target comes back under a new identity."""
    info, rows = tracked("full", walk_scene(), fallback_appearance=fallback)
    before, after = identities_of_target_0(rows)
    assert len(before) == 1 and len(after) == 1
    assert (after == before) is kept
    assert bool((info.merged >= 0).sum() == 1) is kept


@pytest.mark.parametrize(("fallback", "kept"), [(2, True), (1, False)])
def test_group_trackers_learn_a_fallback_model_at_level_2(fallback, kept):
    """Three people walk side by side; the middle one's tracker is born after the others',
    colliding with both: a group tracker. With ``fallback_appearance=2`` it has a fallback
    model and keeps its identity across the occlusion; at 1 (group trackers learn nothing)
    the person comes back under a new identity."""
    info, rows = tracked("full", group_scene(), fallback_appearance=fallback)
    assert np.all(np.asarray(info.tracks.mask).sum(axis=1)[LATE + 6 : HIDDEN[0]] == 3)
    expected_x = 22.0 + 1.5 * rows.frames
    on_target = np.abs(rows.boxes[:, 0] - expected_x) < 4
    before = set(rows.ids[on_target & (rows.frames <= HIDDEN[0])].tolist())
    after = set(rows.ids[on_target & (rows.frames > HIDDEN[-1] + 8)].tolist())
    assert len(before) == 1 and len(after) == 1
    assert (after == before) is kept


def test_no_gap_is_filled_across_a_fallback_reassociation():
    """The offline output interpolates an identity's short gaps (``max_gap``), but not the
    one a fallback model's re-association joined: target 0's identity has no row inside the
    occlusion, though the gap is shorter than ``max_gap`` (25 frames). The frame of the join
    is flagged once in the info."""
    info, rows = tracked("full", walk_scene(), fallback_appearance=1)
    assert int(np.sum(info.unfilled)) == 1
    (identity,) = identities_of_target_0(rows)[0]
    inside = (rows.ids == identity) & (rows.frames > HIDDEN[0] + 2) & (rows.frames < HIDDEN[-1])
    assert not np.any(inside)
    # the same outputs without the flag: the gap is filled
    filled = output_rows(info._replace(unfilled=np.zeros_like(info.unfilled)), CONFIG, 1)
    inside = (filled.ids == identity) & (filled.frames > HIDDEN[0] + 2)
    assert np.sum(inside & (filled.frames < HIDDEN[-1])) == HIDDEN[-1] - HIDDEN[0] - 3


def test_the_first_single_frame_restarts_the_model():
    """The fallback model is dropped on the tracker's first single frame: from then on its
    model counts only single frames (target 0 is single from frame 12; with the fallback it
    learned on the frames before too, yet its count equals the run without)."""
    counts = {}
    for fallback in (0, 1):
        config = HierarchicalConfig(
            variant="full", max_tracks=8, max_trackers=8, fallback_appearance=fallback
        )
        filt, params = build_hierarchical(config, INFO, BACKGROUND)
        inputs = walk_scene(apart_from=10)
        inputs = jax.tree.map(lambda leaf: leaf[: HIDDEN[0]], inputs)  # before the occlusion
        state, info = jax.jit(functools.partial(run, filt))(jax.random.PRNGKey(0), params, inputs)
        first_ids = np.asarray(info.event_ids)[-1]
        boxes = np.asarray(state.high.boxes)
        slot = int(np.argmin(np.where(first_ids >= 0, np.abs(boxes[:, 0] - (10 + 1.5 * 19)), 1e9)))
        counts[fallback] = np.asarray(state.appearance.models.count)[slot].max()
        assert bool(np.asarray(state.high.single_model)[slot])
    assert counts[0] == counts[1] > 0


def test_the_fallback_is_on_by_default():
    """On since session 62, by a rule written before a held-out run (README, "A fallback
    appearance for trackers never single")."""
    assert HierarchicalConfig().fallback_appearance == 1
