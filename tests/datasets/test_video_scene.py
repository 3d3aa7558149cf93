"""The scripted video scene: its events happen, its truth is consistent, its seed decides."""

from __future__ import annotations

import numpy as np
import pytest

from jaxtrack.datasets import VideoSceneConfig, generate_video_scene
from jaxtrack.datasets.video_paths import nominal_height
from jaxtrack.datasets.video_script import CLOTHING, FIRST_ENTRY, SIMILAR_JITTER
from jaxtrack.errors import InputError


def feet_of(scene, person_id):
    """Frames and foot points (bottom centre of the gt box) of one person."""
    rows = scene.person_rows(person_id)
    boxes = scene.gt_table.boxes[rows]
    return scene.gt_table.frames[rows], boxes[:, :2] + boxes[:, 2:] * [0.5, 1.0]


def event(scene, kind):
    (found,) = [e for e in scene.events if e.kind == kind]
    return found


def inside(point, box, tol=1e-3):
    x, y, w, h = box
    return x - tol <= point[0] <= x + w + tol and y - tol <= point[1] <= y + h + tol


def test_same_seed_same_scene_other_seed_other_scene(video_scene):
    again = generate_video_scene(3)
    np.testing.assert_array_equal(again.gt_table.boxes, video_scene.gt_table.boxes)
    np.testing.assert_array_equal(again.det_table.boxes, video_scene.det_table.boxes)
    np.testing.assert_array_equal(again.appearance.top, video_scene.appearance.top)
    np.testing.assert_array_equal(again.noise_offsets, video_scene.noise_offsets)
    assert again.events == video_scene.events
    other = generate_video_scene(4)
    assert other.events != video_scene.events
    assert not np.array_equal(other.appearance.top, video_scene.appearance.top)


def test_everybody_enters_and_leaves_through_a_zone(video_scene):
    scene = video_scene
    for index in range(scene.num_people):
        frames, feet = feet_of(scene, index + 1)
        assert frames[0] >= FIRST_ENTRY and np.all(np.diff(frames) == 1)
        assert inside(feet[0], scene.zones[scene.entry_zones[index]])
        exit_zone = scene.exit_zones[index]
        if exit_zone >= 0:
            assert inside(feet[-1], scene.zones[exit_zone])
            assert exit_zone != scene.entry_zones[index]
        else:
            assert frames[-1] == scene.config.num_frames
    entries = [e for e in scene.events if e.kind == "entry"]
    exits = [e for e in scene.events if e.kind == "exit"]
    assert len(entries) == scene.num_people and len(exits) == np.sum(scene.exit_zones >= 0)


def test_every_zone_has_entries_in_the_first_300_frames(video_scene):
    # The precondition of learning the entry zones from frames 1:300 of the ground truth.
    names = [zone.name for zone in video_scene.config.zones]
    entries = [e.zone for e in video_scene.events if e.kind == "entry" and e.frames[0] <= 290]
    assert all(3 <= entries.count(name) <= 10 for name in names)


def test_crossing_of_similarly_dressed_people(video_scene):
    scene = video_scene
    crossing = event(scene, "crossing")
    a, b = crossing.ids
    assert scene.roles[a - 1] == scene.roles[b - 1] == "crossing"
    assert scene.entry_zones[a - 1] != scene.entry_zones[b - 1]
    look = scene.appearance
    for colours in (look.top, look.bottom):
        assert np.abs(colours[a - 1].astype(int) - colours[b - 1]).max() <= 2 * SIMILAR_JITTER
    frames_a, feet_a = feet_of(scene, a)
    frames_b, feet_b = feet_of(scene, b)
    common, ia, ib = np.intersect1d(frames_a, frames_b, return_indices=True)
    distance = np.hypot(*(feet_a[ia] - feet_b[ib]).T)
    meet = common[np.argmin(distance)]
    height = nominal_height(feet_a[ia][np.argmin(distance), 1], scene.config)
    assert distance.min() <= 0.13 * height  # one CROSSING_OFFSET apart, nearer the camera
    assert crossing.frames[0] < meet < crossing.frames[1]
    assert distance[0] > 2 * height and distance[-1] > height  # from and to different places


def palette_index(colour):
    """The clothing palette colour a person's (jittered) colour was drawn from."""
    return int(np.argmin(np.abs(CLOTHING - colour.astype(int)).max(axis=1)))


@pytest.mark.parametrize("alike", ["top", "bottom"])
def test_crossing_pair_alike_in_one_half_only(video_scene, alike):
    scene = generate_video_scene(3, VideoSceneConfig(crossing_alike=alike))
    a, b = event(scene, "crossing").ids
    look = scene.appearance
    same, other = (look.top, look.bottom) if alike == "top" else (look.bottom, look.top)
    assert np.abs(same[a - 1].astype(int) - same[b - 1]).max() <= 2 * SIMILAR_JITTER
    assert palette_index(same[a - 1]) == palette_index(same[b - 1])
    # The other half: two palette colours, neither of them the alike half's.
    others = {palette_index(other[a - 1]), palette_index(other[b - 1])}
    assert len(others) == 2 and palette_index(same[a - 1]) not in others
    assert np.abs(other[a - 1].astype(int) - other[b - 1]).max() > 30
    # The same pair walks the same routes as under the default "both" (ids follow the later
    # draws), the alike half in the same palette colour.
    both = video_scene
    pair = sorted(event(scene, "crossing").ids, key=lambda i: feet_of(scene, i)[0][0])
    pair_both = sorted(event(both, "crossing").ids, key=lambda i: feet_of(both, i)[0][0])
    for i, j in zip(pair, pair_both, strict=True):
        np.testing.assert_allclose(feet_of(scene, i)[1], feet_of(both, j)[1], atol=0.01)
    both_same = both.appearance.top if alike == "top" else both.appearance.bottom
    assert palette_index(same[a - 1]) == palette_index(both_same[pair_both[0] - 1])


def test_unknown_crossing_alike_is_refused():
    with pytest.raises(InputError, match="crossing_alike must be one of both, top, bottom"):
        VideoSceneConfig(crossing_alike="shoes")


def test_group_walks_together_then_splits(video_scene):
    scene = video_scene
    group = event(scene, "group")
    assert len(group.ids) == 3 and len({scene.entry_zones[i - 1] for i in group.ids}) == 1
    assert len({scene.exit_zones[i - 1] for i in group.ids}) >= 2
    tracks = [dict(zip(*feet_of(scene, i), strict=True)) for i in group.ids]
    first, split = group.frames
    for frame in range(first, split + 1):
        feet = np.array([track[frame] for track in tracks])
        height = nominal_height(feet[:, 1].mean(), scene.config)
        gaps = np.hypot(*(feet[:, None] - feet[None]).transpose(2, 0, 1))
        assert gaps.max() <= 0.85 * height  # side by side, 0.4 heights apart
    later = sorted(set(tracks[0]) & set(tracks[1]) & set(tracks[2]))
    feet = np.array([[track[frame] for track in tracks] for frame in later])
    gaps = np.hypot(*(feet[:, :, None] - feet[:, None]).transpose(3, 0, 1, 2)).max(axis=(1, 2))
    assert gaps.max() > 2.5 * nominal_height(feet[-1, :, 1].mean(), scene.config)


def test_occluder_hides_the_person_behind_it(video_scene):
    scene = video_scene
    occlusion = event(scene, "occlusion")
    (person,) = occlusion.ids
    rows = scene.person_rows(person)
    frames, visibility = scene.gt_table.frames[rows], scene.visibility[rows]
    hidden = (frames >= occlusion.frames[0]) & (frames <= occlusion.frames[1])
    assert hidden.sum() >= 10 and np.all(visibility[hidden] == 0)
    before, after = frames < occlusion.frames[0], frames > occlusion.frames[1]
    assert visibility[before].max() >= 0.9 and visibility[after].max() >= 0.9  # recovers
    # It walks behind the board: feet above the board's bottom row, head below its top.
    box = scene.gt_table.boxes[rows][hidden]
    _, y, _, h = scene.occluder
    assert np.all(box[:, 1] >= y) and np.all(box[:, 1] + box[:, 3] < y + h)


def test_standing_person_stands_still(video_scene):
    scene = video_scene
    standing = event(scene, "standing")
    (person,) = standing.ids
    frames, feet = feet_of(scene, person)
    first, last = standing.frames
    assert last - first + 1 == scene.config.stand_frames
    still = (frames >= first) & (frames <= last)
    assert np.all(feet[still] == feet[still][0])
    assert np.all(scene.gt_walking[scene.person_rows(person)][still][1:] == False)  # noqa: E712
    steps = np.hypot(*np.diff(feet, axis=0).T)
    assert steps[frames[1:] == first].item() > 0 and steps[frames[1:] == last + 1].item() > 0


def test_ground_truth_layout(video_scene):
    gt = video_scene.gt_table
    assert gt.extra.shape[1] == 2 and np.all(gt.extra[:, 0] == 1)  # MOT16/17 class, visibility
    visibility = video_scene.visibility
    assert np.all((visibility >= 0) & (visibility <= 1))
    np.testing.assert_array_equal(visibility * 256, np.round(visibility * 256))  # 16x16 grid
    assert np.all(np.diff(gt.frames) >= 0)
    first_frames = [gt.frames[gt.ids == i].min() for i in range(1, video_scene.num_people + 1)]
    assert np.all(np.diff(first_frames) >= 0)  # ids in order of entry
    # Entering at an image edge truncates the box: visibility below 1 there (a sixteenth of
    # the width outside leaves a column of samples outside).
    edge = gt.boxes[:, 0] < -gt.boxes[:, 2] / 16
    assert edge.any() and np.all(visibility[edge] < 1)


def test_detections_follow_visibility_and_the_gusts(video_scene):
    scene = video_scene
    gt, det = scene.gt_table, scene.det_table
    true = scene.det_target_ids >= 0
    key = {(f, i): r for r, (f, i) in enumerate(zip(gt.frames, gt.ids, strict=True))}
    rows = np.array(
        [key[(f, i)] for f, i in zip(det.frames[true], scene.det_target_ids[true], strict=True)]
    )
    visibility = scene.visibility
    assert visibility[rows].min() >= 0.2  # never detected below 20 % visible
    seen = visibility >= 0.5
    rate = np.isin(np.arange(len(gt)), rows)[seen].mean()
    assert rate == pytest.approx(scene.config.detection_prob, abs=0.03)
    centre_error = (det.boxes[true, :2] + det.boxes[true, 2:] / 2) - (
        gt.boxes[rows, :2] + gt.boxes[rows, 2:] / 2
    )
    inside_image = (gt.boxes[rows, 0] > 0) & (gt.boxes[rows, 0] + gt.boxes[rows, 2] < 640)
    relative = np.abs(centre_error[inside_image] / gt.boxes[rows][inside_image, 2:])
    assert np.median(relative[:, 0]) == pytest.approx(0.674 * 0.04, rel=0.2)  # s_w = 0.04
    false_frames = det.frames[~true]
    gust = scene.gust[false_frames - 1]
    config = scene.config
    calm_expected = config.clutter_rate * (~scene.gust).sum()
    gust_expected = (config.clutter_rate + config.vegetation_clutter_rate) * scene.gust.sum()
    assert abs((~gust).sum() - calm_expected) < 4 * np.sqrt(calm_expected)
    assert abs(gust.sum() - gust_expected) < 4 * np.sqrt(gust_expected)


def test_layout_in_fractions_scales_the_whole_scene(video_scene, small_video_scene):
    big, small = video_scene, small_video_scene
    np.testing.assert_array_equal(small.gt_table.frames, big.gt_table.frames)
    np.testing.assert_allclose(small.gt_table.boxes, big.gt_table.boxes / 2, atol=1e-3)
    np.testing.assert_array_equal(small.visibility, big.visibility)
    assert small.events == big.events
    np.testing.assert_array_equal(small.appearance.bottom, big.appearance.bottom)


def test_too_short_a_scene_is_refused():
    with pytest.raises(InputError, match=r"num_frames 150 is too short .* at least \d+ frames"):
        generate_video_scene(3, VideoSceneConfig(num_frames=150))


def test_a_layout_without_room_for_the_events_is_refused():
    blocked = VideoSceneConfig(occluder=(0.2, 0.3, 0.6, 0.6))  # covers the middle of the ground
    with pytest.raises(InputError, match="clear of the occluder"):
        generate_video_scene(0, blocked)
