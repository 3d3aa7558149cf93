"""The Hierarchical tracker's compiled step (jaxtrack.filters.hierarchical) on drawn scenes.

Oracles: scenes whose truth is known exactly (two-tone rectangles over a grey background,
detections = the true boxes, a stretch of frames without one target's detections: an
occlusion longer than the low level coasts), the managed low level alone (the full tracker's
boxes are its boxes), and hand-made per-frame outputs for the host-side identity merges and
event rows.
"""

from __future__ import annotations

import jax
import numpy as np
import pytest

from jaxtrack.filters.base import run
from jaxtrack.filters.hier_events import ENTERING, EXITING, GROUPED, GROUPING, SINGLE
from jaxtrack.filters.hierarchical_tracker import HierarchicalConfig, build_hierarchical
from jaxtrack.pipelines.events import (
    EventOutputs,
    event_rows,
    identity_merges,
    merge_identities,
)
from jaxtrack.pipelines.tracking import output_rows
from jaxtrack.types import MotTable, Tracks
from tests.filters.test_cmt import COLOURS, INFO, SIZE, frame_inputs, two_tone

#: Frames of the occlusion scene, and the frames in which target 0 is not detected.
NUM_FRAMES = 60
HIDDEN = range(18, 40)
BACKGROUND = np.full((SIZE[1], SIZE[0], 3), 128, np.uint8)


def occlusion_scene(reappearing_colours=None, num_slots=4, lower_y=72.0, hidden=HIDDEN):
    """Target 0 walks right and is not detected in the ``hidden`` frames (and not drawn);
    target 1 walks left below it (top edge at ``lower_y``). From the first frame after the
    gap target 0 wears ``reappearing_colours`` (default: its own)."""
    frames, kept = [], []
    for t in range(NUM_FRAMES):
        image = BACKGROUND.copy()
        truth = [(10.0 + 1.5 * t, 20.0, 16.0, 36.0), (130.0 - 1.5 * t, lower_y, 16.0, 36.0)]
        shown = [t not in hidden, True]
        colours = list(COLOURS)
        if reappearing_colours is not None and t > hidden[-1]:
            colours[0] = reappearing_colours
        for box, (top, bottom), visible in zip(truth, colours, shown, strict=True):
            if visible:
                two_tone(image, box, top, bottom)
        frames.append(image)
        kept.append([box for box, visible in zip(truth, shown, strict=True) if visible])
    return frame_inputs(frames, kept, num_slots=num_slots)


def tracked(variant, inputs, **settings):
    """The per-frame infos of a run, identities merged (as the pipelines do)."""
    config = HierarchicalConfig(variant=variant, max_tracks=8, max_trackers=8, **settings)
    filt, params = build_hierarchical(config, INFO, BACKGROUND)
    _, info = jax.jit(lambda k, p, i: run(filt, k, p, i))(jax.random.PRNGKey(0), params, inputs)
    info = jax.device_get(info)
    if variant == "full":
        info = merge_identities(info)
    return info, output_rows(info, config, 1)


def target_ids(rows: MotTable, row_y: float, hidden=HIDDEN) -> tuple[set, set]:
    """The identities of the boxes near ``row_y`` before and after the ``hidden`` frames."""
    near = np.abs(rows.boxes[:, 1] - row_y) < 8
    before = set(rows.ids[near & (rows.frames <= hidden[0])].tolist())
    after = set(rows.ids[near & (rows.frames > hidden[-1] + 1)].tolist())
    return before, after


def test_the_high_level_keeps_the_identity_through_an_occlusion():
    inputs = occlusion_scene()
    full, full_rows = tracked("full", inputs)
    managed, managed_rows = tracked("managed", inputs)
    before, after = target_ids(full_rows, 20.0)
    assert len(before) == 1 and after == before  # re-associated: one identity
    before, after = target_ids(managed_rows, 20.0)
    assert len(before) == 1 and len(after) == 1 and after != before  # the low level: a new one
    # the other target is one identity in both
    assert len(set.union(*target_ids(full_rows, 72.0))) == 1
    # the full tracker's boxes are the low level's (same detections, same Kalman bank)
    shown = full.tracks.mask
    np.testing.assert_allclose(full.tracks.boxes[shown], managed.tracks.boxes[shown], atol=1e-4)
    assert (full.merged >= 0).sum() == 1  # one re-association, recorded once


def test_a_differently_dressed_target_is_not_reassociated():
    inputs = occlusion_scene(reappearing_colours=((250, 250, 250), (10, 10, 10)))
    info, rows = tracked("full", inputs)
    before, after = target_ids(rows, 20.0)
    assert len(before) == 1 and len(after) == 1 and after != before
    assert (info.merged >= 0).sum() == 0


def resumption_scene(gap, reappearing_colours=None):
    """:func:`occlusion_scene` with target 0 undetected for ``gap`` frames from frame 18
    (fewer than the 12 its track coasts at 25 fps: the track resumes), then in
    ``reappearing_colours``: someone else stepping out where it went in."""
    hidden = range(18, 18 + gap)
    return occlusion_scene(reappearing_colours, hidden=hidden), hidden


def _upper_ids(rows, hidden):
    """Target 0's identities before and after its undetected frames."""
    return target_ids(rows, 20.0, hidden)


WHITE_BLACK = ((250, 250, 250), (10, 10, 10))


def test_a_track_resuming_on_someone_else_is_let_go():
    # 9 undetected frames (>= 8 = 0.32 s at 25 fps): the resumed measurement is checked
    inputs, hidden = resumption_scene(9, WHITE_BLACK)
    info, rows = tracked("full", inputs)
    before, after = _upper_ids(rows, hidden)
    assert len(before) == 1 and len(after) == 1 and after != before
    # the tracker that let the track go is lost from that frame (not re-associated to it)
    lost = np.asarray(info.high_lost)
    first = hidden[-1] + 1
    assert lost[first].sum() == 1 and lost[first - 1].sum() == 0
    assert (np.asarray(info.merged) >= 0).sum() == 0
    # the other target keeps its one identity
    near = np.abs(rows.boxes[:, 1] - 72.0) < 8
    assert len(set(rows.ids[near].tolist())) == 1
    # the paper's tracker (no check): the track, and its identity, go on with the newcomer
    _, plain = tracked("full", inputs, resume_seconds=0.0)
    before, after = _upper_ids(plain, hidden)
    assert len(before) == 1 and after == before


def test_a_track_resuming_on_its_own_target_keeps_its_identity():
    inputs, hidden = resumption_scene(9)
    info, rows = tracked("full", inputs)
    before, after = _upper_ids(rows, hidden)
    assert len(before) == 1 and after == before
    assert not np.asarray(info.high_lost).any()


def test_a_short_gap_is_not_checked():
    # 5 undetected frames (< 8): not checked, even in other colours
    inputs, hidden = resumption_scene(5, WHITE_BLACK)
    _, rows = tracked("full", inputs)
    before, after = _upper_ids(rows, hidden)
    assert len(before) == 1 and after == before
    # a threshold of 0.2 s (5 frames) checks it
    _, rows = tracked("full", inputs, resume_seconds=0.2)
    before, after = _upper_ids(rows, hidden)
    assert len(before) == 1 and len(after) == 1 and after != before


def test_lost_tracker_is_dropped_after_max_lost_frames():
    inputs = occlusion_scene()
    config = HierarchicalConfig(max_tracks=8, max_trackers=8, lost_seconds=0.2)  # 5 frames
    filt, params = build_hierarchical(config, INFO, BACKGROUND)
    _, info = run(filt, jax.random.PRNGKey(0), params, inputs)
    lost_frames = np.asarray(info.high_lost).sum(axis=0)
    assert lost_frames.max() == 5  # lost for 5 frames, then dropped
    assert (np.asarray(info.merged) >= 0).sum() == 0


def test_a_lost_trackers_extrapolated_box_makes_no_group():
    # target 1 walks at the height of target 0's path: while target 0 is hidden, its lost
    # tracker's extrapolated box overlaps target 1's from about frame 35 on.
    inputs = occlusion_scene(lower_y=40.0)
    info, _ = tracked("full", inputs)
    boxes, lost = np.asarray(info.high_boxes), np.asarray(info.high_lost)
    shown, events = np.asarray(info.tracks.mask), np.asarray(info.events)
    overlapping = 0
    for t in HIDDEN:
        low, high = boxes[t, :, :2], boxes[t, :, :2] + boxes[t, :, 2:]
        sides = np.minimum(high[:, None], high[None]) - np.maximum(low[:, None], low[None])
        touching = np.all(sides > 0, axis=-1) & lost[t][None, :] & shown[t][:, None]
        overlapping += int(touching.any())
        # the shown tracker is single, not grouping with a box no detection supports
        assert not np.isin(events[t][shown[t]], (GROUPING, GROUPED)).any(), t
    assert overlapping >= 3  # the case arises


def _outputs(ids, merged, events=None):
    ids = np.asarray(ids)
    boxes = np.zeros((*ids.shape, 4))
    boxes[..., 2:] = 1.0
    tracks = Tracks(boxes, ids, np.ones(ids.shape), ids >= 0)
    codes = np.zeros(ids.shape, np.int32) if events is None else np.asarray(events)
    return EventOutputs(tracks, tracks, codes, ids, np.asarray(merged))


def test_identity_merges_resolve_chains_and_drop_clashing_rows():
    # frame 0: ids 1, 5 (a tentative track); frame 1: tracker 1 takes track 5 (merged 5);
    # frame 2: tracker 7 takes tracker 1's identity (merged 1): 5 -> 1 -> 7
    mapping = identity_merges([[-1, -1], [5, -1], [-1, 1]], [[1, 5], [1, -1], [-1, 7]])
    assert mapping == {5: 7, 1: 7}
    outputs = merge_identities(_outputs([[1, 5], [1, -1], [7, -1]], [[-1, -1], [5, -1], [1, -1]]))
    # frame 0 had both 1 and 5, which both become 7: the merged row (5) is dropped
    assert outputs.tracks.ids.tolist() == [[7, -1], [7, -1], [7, -1]]
    assert outputs.tracks.mask.tolist() == [[True, False], [True, False], [True, False]]
    unmerged = _outputs([[1, 2]], [[-1, -1]])
    assert merge_identities(unmerged) is unmerged


def test_event_rows_follow_the_results_and_label_exits():
    # slots: identity 3 single then grouping; identity 4 entering, gone after frame 2
    outputs = _outputs(
        [[3, 4], [3, 4], [3, -1], [3, -1]],
        [[-1, -1]] * 4,
        [[SINGLE, ENTERING], [SINGLE, ENTERING], [GROUPING, SINGLE], [GROUPING, SINGLE]],
    )
    # identity 4 walks (1 box height a frame): an exit by its motion (moving_ends)
    boxes = np.zeros((7, 4))
    boxes[4:] = [[10.0, 0.0, 1.0, 1.0], [11.0, 0.0, 1.0, 1.0], [12.0, 0.0, 1.0, 1.0]]
    rows = MotTable.from_arrays(
        np.array([11, 12, 13, 14, 10, 11, 12]),
        np.array([3, 3, 3, 3, 4, 4, 4]),
        boxes,
        np.ones(7),
    )
    # at 1 frame/s half a second is under a frame: every group episode is kept
    events = event_rows(outputs, rows, first_frame=11, frame_rate=1.0)
    keys = zip(events.frames.tolist(), events.ids.tolist(), strict=True)
    got = dict(zip(keys, events.names, strict=True))
    assert got[(11, 3)] == "single" and got[(13, 3)] == "grouping"
    # at 25 frames/s (the default) identity 3's 2-frame group is shorter than half a
    # second: dropped (drop_short_groups), the rest unchanged
    default = event_rows(outputs, rows, first_frame=11)
    keys = zip(default.frames.tolist(), default.ids.tolist(), strict=True)
    dropped = dict(zip(keys, default.names, strict=True))
    assert dropped[(13, 3)] == dropped[(14, 3)] == "single"
    assert {k: v for k, v in dropped.items() if k[1] == 4} == {
        k: v for k, v in got.items() if k[1] == 4
    }
    # identity 4's row before its tracker existed takes its first state; its track ends on
    # frame 12 before the span's end (14): exiting
    assert got[(10, 4)] == "exiting" and got[(12, 4)] == "exiting"
    assert len(events.frames) == len(rows.frames)
    assert EXITING == 5
    # standing still at the same place, identity 4 does not leave: no exit
    still_boxes = np.where(np.arange(7)[:, None] >= 4, [[10.0, 0, 1, 1]], 0.0)
    still = MotTable.from_arrays(rows.frames, rows.ids, still_boxes, rows.confs)
    static = event_rows(outputs, still, first_frame=11, frame_rate=1.0)
    assert "exiting" not in static.names[static.ids == 4].tolist()


@pytest.mark.parametrize("variant", ["managed", "full", "kalman"])
def test_every_variant_runs_on_frame_inputs(variant):
    inputs = occlusion_scene()
    config = HierarchicalConfig(variant=variant, max_tracks=8, max_trackers=8)
    filt, params = build_hierarchical(config, INFO, BACKGROUND)
    _, info = run(filt, jax.random.PRNGKey(0), params, inputs)
    rows = output_rows(jax.device_get(info), config, 1)
    assert len(np.unique(rows.frames)) >= NUM_FRAMES - len(HIDDEN)
