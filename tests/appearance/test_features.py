"""Region histograms of drawn frames (exact), against full-resolution NumPy histograms, in scan."""

from __future__ import annotations

import colorsys
import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.appearance import (
    LINEAR_COMBINATION_WEIGHTS,
    epanechnikov,
    hsv,
    linear_combination_histograms,
    normalised_rg,
    profile_histograms,
    rgb,
    sample_nearest,
    sample_patch,
    top_bottom_histograms,
)
from jaxtrack.errors import InputError

RED, BLUE, WHITE, GREY = (200, 30, 30), (20, 40, 180), (250, 250, 250), (90, 120, 60)
# Box of the drawn person: 16 x 32 pixels at (20, 10); patch 8 x 4: cells of 4 x 4 pixels.
BOX = np.array([20.0, 10.0, 16.0, 32.0], np.float32)
PATCH = (8, 4)
SAMPLERS = [sample_nearest, sample_patch]
# Jitted once per static configuration (eager op-by-op dispatch is slower to run here).
_top_bottom = jax.jit(
    top_bottom_histograms, static_argnames=("patch_shape", "step", "colour_space", "sampler")
)
_linear = jax.jit(linear_combination_histograms, static_argnames=("patch_shape", "sampler"))
_profile = jax.jit(
    profile_histograms, static_argnames=("patch_shape", "step", "min_rows", "sampler")
)


def _person_frame() -> np.ndarray:
    """Grey background; the box's top half red, bottom half blue but its left quarter white."""
    frame = np.empty((60, 80, 3), np.uint8)
    frame[:] = GREY
    frame[10:26, 20:36] = RED
    frame[26:42, 20:36] = BLUE
    frame[26:42, 20:24] = WHITE
    return frame


def _bin(colour, space, step):
    """Joint bin of one colour, computed with colorsys / explicit formulas."""
    red, green, blue = (float(c) for c in colour)
    if space is rgb:
        channels = [red, green, blue]
    elif space is hsv:
        h, s, v = colorsys.rgb_to_hsv(red / 255, green / 255, blue / 255)
        channels = [256 * h, 256 * s, 255 * v]
    else:
        total = red + green + blue
        channels = [256 * red / total, 256 * green / total]
    per_channel = int(np.ceil(256 / step))
    index = 0
    for value in channels:
        index = index * per_channel + min(int(value // step), per_channel - 1)
    return index, per_channel ** len(channels)


@pytest.mark.parametrize("sampler", SAMPLERS)
@pytest.mark.parametrize("space", [rgb, hsv, normalised_rg])
def test_uniform_rectangles_are_exact(space, sampler):
    step = 32.0
    red, total = _bin(RED, space, step)
    blue, _ = _bin(BLUE, space, step)
    white, _ = _bin(WHITE, space, step)
    expected = np.zeros((2, total))
    expected[0, red] = 1.0
    expected[1, blue] += 0.75
    expected[1, white] += 0.25
    got = _top_bottom(
        jnp.asarray(_person_frame()),
        jnp.asarray(BOX),
        patch_shape=PATCH,
        step=step,
        colour_space=space,
        sampler=sampler,
    )
    np.testing.assert_allclose(got, expected, atol=1e-6)


def test_kernel_weights_the_samples():
    half = epanechnikov((4, 4))
    kernel = jnp.concatenate([half, half])
    got = np.asarray(
        _top_bottom(jnp.asarray(_person_frame()), jnp.asarray(BOX), PATCH, 32.0, kernel=kernel)
    )
    white_share = float(half[:, 0].sum() / half.sum())  # the first patch column is white
    assert got[1, _bin(WHITE, rgb, 32.0)[0]] == pytest.approx(white_share, abs=1e-6)
    assert got[1, _bin(BLUE, rgb, 32.0)[0]] == pytest.approx(1 - white_share, abs=1e-6)
    assert got[0, _bin(RED, rgb, 32.0)[0]] == pytest.approx(1.0, abs=1e-6)


def test_box_partly_or_wholly_outside():
    frame = _person_frame()
    frame[10:26, 0:8] = RED  # the visible half of a box at x = -8
    frame = jnp.asarray(frame)
    straddling = _top_bottom(frame, jnp.array([-8.0, 10.0, 16.0, 32.0]), PATCH, 32.0)
    assert float(straddling[0, _bin(RED, rgb, 32.0)[0]]) == pytest.approx(1.0, abs=1e-6)
    outside = _top_bottom(frame, jnp.array([100.0, 10.0, 16.0, 32.0]), PATCH, 32.0)
    np.testing.assert_array_equal(outside, 0.0)


@pytest.mark.parametrize("sampler", SAMPLERS)
def test_one_sample_per_pixel_is_the_full_resolution_histogram(sampler):
    frame = np.random.default_rng(3).integers(0, 256, (40, 50, 3), dtype=np.uint8)
    box = np.array([7.0, 5.0, 13.0, 22.0], np.float32)  # pixel-aligned
    got = _top_bottom(
        jnp.asarray(frame), jnp.asarray(box), patch_shape=(22, 13), step=32.0, sampler=sampler
    )
    for half, rows in enumerate((slice(5, 16), slice(16, 27))):
        pixels = frame[rows, 7:20].reshape(-1, 3)
        counts, _ = np.histogramdd(pixels, bins=(8, 8, 8), range=[(0, 256)] * 3)
        np.testing.assert_allclose(got[half], counts.ravel() / len(pixels), atol=1e-6)


@pytest.mark.parametrize("sampler", SAMPLERS)
def test_linear_combination_histograms_full_resolution(sampler):
    frame = np.random.default_rng(4).integers(0, 256, (20, 24, 3), dtype=np.uint8)
    box = np.array([3.0, 2.0, 9.0, 12.0], np.float32)  # one sample per pixel
    got = _linear(jnp.asarray(frame), jnp.asarray(box), patch_shape=(12, 9), sampler=sampler)
    got = np.asarray(got)
    pixels = frame[2:14, 3:12].reshape(-1, 3).astype(np.float64)
    assert got.shape == (49, 64)
    for k, weights in enumerate(LINEAR_COMBINATION_WEIGHTS.astype(np.float64)):
        low, high = 255 * np.minimum(weights, 0).sum(), 255 * np.maximum(weights, 0).sum()
        values = 256 * (pixels @ weights - low) / (high - low)
        bins = np.minimum(np.floor(values / 4), 63).astype(int)
        np.testing.assert_allclose(got[k], np.bincount(bins, minlength=64) / len(pixels), atol=1e-6)


def test_profile_splits_at_the_clothing_boundary():
    frame = np.empty((60, 40, 3), np.uint8)
    frame[:] = GREY
    frame[5:17, 10:22] = RED  # upper 12 of 40 rows: 30 %
    frame[17:45, 10:22] = BLUE
    box = jnp.array([10.0, 5.0, 12.0, 40.0])
    split = _profile(jnp.asarray(frame), box, patch_shape=(20, 6), step=32.0, min_rows=2)
    assert int(split.row) == 6  # 6 of 20 patch rows
    assert float(split.distance) == pytest.approx(1.0, abs=1e-6)
    red, total = _bin(RED, hsv, 32.0)
    blue, _ = _bin(BLUE, hsv, 32.0)
    expected = np.zeros((2, total))
    expected[0, red] = expected[1, blue] = 1.0
    np.testing.assert_allclose(split.histograms, expected, atol=1e-6)


@pytest.mark.parametrize("sampler", SAMPLERS)
def test_features_in_scan_and_vmap_equal_single_boxes(sampler):
    rng = np.random.default_rng(5)
    frames = rng.integers(0, 256, (3, 30, 40, 3), dtype=np.uint8)
    boxes = rng.uniform([-5, -5, 5, 8], [30, 20, 15, 20], (3, 7, 4)).astype(np.float32)
    per_box = functools.partial(
        top_bottom_histograms, patch_shape=(6, 4), step=32.0, sampler=sampler
    )

    def step(carry, inputs):
        frame, frame_boxes = inputs
        return carry, jax.vmap(per_box, in_axes=(None, 0))(frame, frame_boxes)

    _, scanned = jax.jit(lambda f, b: jax.lax.scan(step, 0, (f, b)))(frames, boxes)
    single = jax.jit(per_box)  # one box at a time (jit == eager: tests/appearance/test_patches)
    for t in range(3):
        for k in range(7):
            np.testing.assert_allclose(scanned[t, k], single(frames[t], boxes[t, k]), atol=1e-6)


def test_bad_arguments_are_refused():
    frame = jnp.asarray(_person_frame())
    with pytest.raises(InputError, match="even number"):
        _top_bottom(frame, jnp.asarray(BOX), (7, 4), 32.0)
    with pytest.raises(InputError, match="uint8"):
        _top_bottom(jnp.zeros((10, 10, 3)), jnp.asarray(BOX), (8, 4), 32.0)
    with pytest.raises(InputError, match="min_rows"):
        _profile(frame, jnp.asarray(BOX), (8, 4), 32.0, 5)
