"""The video renderer: drawn pixels against the ground truth, compositing, lighting, noise.

Frames at 320x240 (the default scene scaled by 1/2); a noise-free copy of the scene
(``noise_std = 0``: same script, same canvas) gives exact colours.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from jaxtrack.datasets import build_canvas, generate_video_scene, render_frame, render_labels
from jaxtrack.datasets.render import pixel_bounds

FRAMES = range(20, 500, 40)


@pytest.fixture(scope="module")
def clean(small_video_scene):
    """The 320x240 scene without pixel noise, and its canvas."""
    config = dataclasses.replace(small_video_scene.config, noise_std=0.0)
    scene = generate_video_scene(small_video_scene.seed, config)
    return scene, build_canvas(scene)


def pixel_rows(box, lower, upper):
    """Pixel rows whose centres lie between ``lower`` and ``upper`` of the box's height."""
    y, h = box[1], box[3]
    rows = np.arange(int(np.floor(y)), int(np.ceil(y + h)))
    centres = rows + 0.5
    return rows[(centres >= y + lower * h) & (centres <= y + upper * h)]


def test_people_lie_inside_their_boxes_and_fill_them(small_video_scene):
    scene = small_video_scene
    checked = 0
    for frame in FRAMES:
        labels = render_labels(scene, frame)
        for row in scene.frame_rows(frame):
            person = scene.gt_table.ids[row]
            x, y, w, h = scene.gt_table.boxes[row]
            ys, xs = np.nonzero(labels == person)
            if xs.size:  # every drawn pixel centre within a pixel of the box
                assert xs.min() + 0.5 >= x - 1 and xs.max() + 0.5 <= x + w + 1
                assert ys.min() + 0.5 >= y - 1 and ys.max() + 0.5 <= y + h + 1
            whole = x >= 0 and y >= 0 and x + w <= 320 and y + h <= 240
            if scene.visibility[row] == 1 and whole and h >= 30:
                assert xs.size >= 0.35 * w * h
                assert ys.max() - ys.min() + 1 >= 0.93 * h
                assert xs.max() - xs.min() + 1 >= 0.55 * w
                checked += 1
    assert checked >= 50


def test_people_carry_their_true_colours(clean, small_video_scene):
    scene, canvas = clean
    look = scene.appearance
    checked = 0
    for frame in FRAMES:
        image, labels = render_frame(scene, canvas, frame), render_labels(scene, frame)
        for row in scene.frame_rows(frame):
            person = scene.gt_table.ids[row]
            box = scene.gt_table.boxes[row]
            if scene.visibility[row] < 1 or box[3] < 20:
                continue
            mine = labels == person
            for (lower, upper), colour in (
                ((0.22, 0.48), look.top[person - 1]),
                ((0.6, 0.97), look.bottom[person - 1]),
            ):
                band = np.zeros_like(mine)
                band[pixel_rows(box, lower, upper)] = True
                pixels = image[mine & band]
                assert len(pixels) >= 5
                assert np.all(pixels == colour)
            checked += 1
    assert checked >= 50
    # The noisy frames show the same colours within the noise.
    noisy = small_video_scene
    canvas = build_canvas(noisy)
    frame = FRAMES[5]
    image, labels = render_frame(noisy, canvas, frame), render_labels(noisy, frame)
    for row in noisy.frame_rows(frame):
        person = noisy.gt_table.ids[row]
        band = np.zeros(labels.shape, bool)
        band[pixel_rows(noisy.gt_table.boxes[row], 0.22, 0.48)] = True
        pixels = image[(labels == person) & band].astype(float)
        if len(pixels) >= 30:
            assert np.abs(np.median(pixels, axis=0) - look.top[person - 1]).max() <= 3


def test_people_are_composited_far_to_near_behind_the_occluder(small_video_scene):
    scene = small_video_scene
    crossing = next(e for e in scene.events if e.kind == "crossing")
    for frame in (*FRAMES, (crossing.frames[0] + crossing.frames[1]) // 2):
        rows = scene.frame_rows(frame)
        alone = []  # oracle: each person drawn alone, then the nearest one wins each pixel
        for row in rows:
            single = dataclasses.replace(
                scene,
                gt_table=scene.gt_table.select(np.array([row])),
                gt_phase=scene.gt_phase[[row]],
                gt_walking=scene.gt_walking[[row]],
            )
            alone.append(render_labels(single, frame) > 0)  # cut by the board when behind it
        feet = scene.gt_table.boxes[rows, 1] + scene.gt_table.boxes[rows, 3]
        expected = np.zeros(alone[0].shape, np.uint16)
        for k in np.argsort(feet, kind="stable"):
            expected[alone[k]] = scene.gt_table.ids[rows[k]]
        np.testing.assert_array_equal(render_labels(scene, frame), expected)


def test_occluder_hides_the_scripted_person(clean):
    scene, canvas = clean
    occlusion = next(e for e in scene.events if e.kind == "occlusion")
    (person,) = occlusion.ids
    x0, y0, x1, y1 = pixel_bounds(scene.occluder)
    base = scene.occluder[1] + scene.occluder[3]
    for frame in range(occlusion.frames[0], occlusion.frames[1] + 1):
        labels = render_labels(scene, frame)
        assert not np.any(labels == person)
        rows = scene.frame_rows(frame)
        feet = scene.gt_table.boxes[rows, 1] + scene.gt_table.boxes[rows, 3]
        on_board = np.unique(labels[y0:y1, x0:x1])
        assert set(on_board[on_board > 0]) <= set(scene.gt_table.ids[rows][feet >= base])
        board = labels[y0:y1, x0:x1] == 0
        image = render_frame(scene, canvas, frame)
        np.testing.assert_array_equal(
            image[y0:y1, x0:x1][board], canvas.background[y0:y1, x0:x1][board]
        )
    before = render_labels(scene, occlusion.frames[0] - 15)
    assert np.any(before == person)


def test_background_lighting_and_swaying_foliage(clean):
    scene, canvas = clean
    background = canvas.background.astype(float)
    ground = background[int(0.3 * 240) :]
    assert ground[:, :32].mean() < ground[:, -32:].mean() - 10  # illumination gradient
    x, y, w, h = scene.config.pixels(scene.config.bright_patch)
    cx, cy = round(x + w / 2), round(y + h / 2)
    patch = background[cy - 3 : cy + 3, cx - 3 : cx + 3].mean()
    beside = background[cy - 3 : cy + 3, round(x + 1.3 * w) : round(x + 1.3 * w) + 6].mean()
    assert patch > 1.2 * beside
    vx0, vy0, vx1, vy1 = pixel_bounds(scene.vegetation)
    offsets = scene.vegetation_offsets
    rest = canvas.background[vy0:vy1, vx0:vx1]
    for frame in (1 + np.flatnonzero(np.any(offsets != 0, axis=1)))[:5]:
        shown = render_frame(scene, canvas, frame)[vy0:vy1, vx0:vx1]
        dx, dy = offsets[frame - 1]
        assert not np.array_equal(shown, rest)
        height, width = rest.shape[:2]
        rows, cols = slice(max(0, -dy), height - max(0, dy)), slice(max(0, -dx), width - max(0, dx))
        shifted_rows = slice(max(0, dy), height + min(0, dy))
        shifted_cols = slice(max(0, dx), width + min(0, dx))
        np.testing.assert_array_equal(shown[rows, cols], rest[shifted_rows, shifted_cols])
    still = 1 + np.flatnonzero(np.all(offsets == 0, axis=1))[0]
    empty = render_labels(scene, still)[vy0:vy1, vx0:vx1] == 0
    np.testing.assert_array_equal(
        render_frame(scene, canvas, still)[vy0:vy1, vx0:vx1][empty], rest[empty]
    )
    assert scene.gust[np.any(np.abs(offsets) >= 2, axis=1)].mean() > 0.5  # big sways in gusts


def test_pixel_noise_is_gaussian_and_changes_every_frame(clean, small_video_scene):
    scene, canvas = clean
    noisy_canvas = build_canvas(small_video_scene)
    residuals = []
    for frame in (100, 101):
        quiet = render_frame(scene, canvas, frame).astype(float)
        noisy = render_frame(small_video_scene, noisy_canvas, frame).astype(float)
        away = (quiet > 20) & (quiet < 235)  # no saturation
        residuals.append(np.where(away, noisy - quiet, np.nan))
        assert np.nanstd(residuals[-1]) == pytest.approx(
            small_video_scene.config.noise_std, rel=0.05
        )
        assert abs(np.nanmean(residuals[-1])) < 0.1
    both = ~np.isnan(residuals[0]) & ~np.isnan(residuals[1])
    assert abs(np.corrcoef(residuals[0][both], residuals[1][both])[0, 1]) < 0.02


def test_frames_are_deterministic(small_video_scene):
    canvas = build_canvas(small_video_scene)
    first = render_frame(small_video_scene, canvas, 200)
    np.testing.assert_array_equal(
        render_frame(small_video_scene, build_canvas(small_video_scene), 200), first
    )
    other = generate_video_scene(4, small_video_scene.config)
    assert np.abs(render_frame(other, build_canvas(other), 200).astype(int) - first).mean() > 5
