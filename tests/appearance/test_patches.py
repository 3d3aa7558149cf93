"""Patch sampling against per-pixel loops: bilinear as a tent-weighted sum, nearest by index."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.appearance import sample_nearest, sample_patch, sample_points
from jaxtrack.errors import InputError

RNG = np.random.default_rng(0)
FRAME = RNG.integers(0, 256, (23, 31, 3), dtype=np.uint8)
BOXES = np.array(
    [
        [3.3, 2.65, 17.9, 12.4],  # inside, fractional
        [0.0, 0.0, 31.0, 23.0],  # the whole frame
        [-6.5, 15.2, 12.0, 14.0],  # straddles the left and bottom borders
        [25.2, -4.0, 9.0, 9.0],  # straddles the right and top borders
        [40.0, 30.0, 5.0, 5.0],  # wholly outside
        [10.0, 10.0, 1.5, 2.5],  # smaller than the patch
    ],
    np.float32,
)
PATCH = (6, 5)
# No sample point of these boxes lies within 0.01 px of a pixel boundary, where float32
# rounding (which differs between jit and eager) could pick either pixel.


def _tent_bilinear(frame, x, y):
    """Bilinear colour at image point (x, y): sum over all pixels of tent weights."""
    height, width = frame.shape[:2]
    u = min(max(x - 0.5, 0.0), width - 1.0)
    v = min(max(y - 0.5, 0.0), height - 1.0)
    total = np.zeros(3)
    for r in range(height):
        for c in range(width):
            weight = max(0.0, 1 - abs(u - c)) * max(0.0, 1 - abs(v - r))
            total += weight * frame[r, c]
    return total


def _points(box, patch):
    x, y, w, h = (float(v) for v in box)
    ys = [y + (i + 0.5) * h / patch[0] for i in range(patch[0])]
    xs = [x + (j + 0.5) * w / patch[1] for j in range(patch[1])]
    return ys, xs


def test_sample_points_are_cell_centres():
    ys, xs = sample_points(jnp.asarray(BOXES[0]), PATCH)
    expected_ys, expected_xs = _points(BOXES[0], PATCH)
    np.testing.assert_allclose(ys, expected_ys, rtol=1e-6)
    np.testing.assert_allclose(xs, expected_xs, rtol=1e-6)
    for box in BOXES:  # the premise of the exact comparisons below
        points = np.concatenate(_points(box, PATCH))
        assert np.min(np.abs(points - np.round(points))) > 0.01


@pytest.mark.parametrize("box", BOXES)
def test_bilinear_matches_tent_loop(box):
    patch = sample_patch(jnp.asarray(FRAME), jnp.asarray(box), PATCH)
    ys, xs = _points(box, PATCH)
    expected = np.array([[_tent_bilinear(FRAME, x, y) for x in xs] for y in ys])
    inside = np.array([[0 <= y < 23 and 0 <= x < 31 for x in xs] for y in ys])
    # float32 sample coordinates (about 30 px) are off by up to ~4e-6 px; times colour steps
    # of up to 255 per pixel, that is ~1e-3.
    np.testing.assert_allclose(patch.values, expected, atol=1e-3)
    np.testing.assert_array_equal(patch.valid, inside)


@pytest.mark.parametrize("box", BOXES)
def test_nearest_matches_index_loop(box):
    patch = sample_nearest(jnp.asarray(FRAME), jnp.asarray(box), PATCH)
    ys, xs = _points(box, PATCH)
    expected = np.array(
        [
            [
                FRAME[min(max(int(np.floor(y)), 0), 22), min(max(int(np.floor(x)), 0), 30)]
                for x in xs
            ]
            for y in ys
        ]
    )
    np.testing.assert_array_equal(patch.values, expected)
    assert patch.values.dtype == jnp.uint8


def test_pixel_aligned_patch_is_the_crop():
    # A box on pixel boundaries with one sample per pixel samples every pixel centre.
    box = jnp.array([4.0, 5.0, 9.0, 7.0])
    crop = FRAME[5:12, 4:13]
    np.testing.assert_allclose(sample_patch(jnp.asarray(FRAME), box, (7, 9)).values, crop)
    np.testing.assert_array_equal(sample_nearest(jnp.asarray(FRAME), box, (7, 9)).values, crop)


def test_non_finite_box_has_no_valid_sample():
    box = jnp.array([np.nan, 3.0, 5.0, 5.0])
    for sampler in (sample_patch, sample_nearest):
        patch = sampler(jnp.asarray(FRAME), box, PATCH)
        assert float(jnp.sum(patch.valid)) == 0.0


@pytest.mark.parametrize("sampler", [sample_patch, sample_nearest])
def test_vmap_equals_loop_and_jit_equals_eager(sampler):
    frame = jnp.asarray(FRAME)
    bound = functools.partial(sampler, patch_shape=PATCH)
    batched = jax.jit(jax.vmap(bound, in_axes=(None, 0)))(frame, jnp.asarray(BOXES))
    for i, box in enumerate(BOXES):
        eager = bound(frame, jnp.asarray(box))
        # XLA may contract a * b + c into one rounding under jit: float32 ulps of 255.
        np.testing.assert_allclose(batched.values[i], eager.values, atol=1e-3)
        np.testing.assert_array_equal(batched.valid[i], eager.valid)


def test_bad_input_is_refused():
    box = jnp.asarray(BOXES[0])
    with pytest.raises(InputError, match="uint8"):
        sample_patch(jnp.asarray(FRAME, jnp.float32), box, PATCH)
    with pytest.raises(InputError, match="H x W x 3"):
        sample_patch(jnp.asarray(FRAME[..., :2]), box, PATCH)
    with pytest.raises(InputError, match="patch_shape"):
        sample_patch(jnp.asarray(FRAME), box, (0, 4))
    with pytest.raises(InputError, match="patch_shape"):
        sample_nearest(jnp.asarray(FRAME), box, (4.0, 4))
