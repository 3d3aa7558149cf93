"""The uint8 shift quantisation: the float formula's bins, alone and in the RGB features."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.appearance import num_bins, quantise, rgb, top_bottom_histograms
from jaxtrack.errors import InputError

RNG = np.random.default_rng(16)
PATCH = (8, 4)
VALUES = np.arange(256, dtype=np.uint8)


def _as_float(pixels):
    """RGB as floats: the float quantisation path (the default before the shift)."""
    return pixels.astype(jnp.float32)


@pytest.mark.parametrize("step", [1.0, 2, 4.0, 8.0, 16.0, 32.0, 64.0, 128.0, 256.0, 24.0, 0.5, 3.0])
def test_every_uint8_value_gets_the_float_bin(step):
    got = quantise(jnp.asarray(VALUES), step)
    expected = np.minimum(np.floor(VALUES / step), num_bins(step) - 1)
    assert got.dtype == jnp.int32
    np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(got, quantise(jnp.asarray(VALUES, jnp.float32), step))


def test_uint8_values_still_check_the_step():
    for step in (0.0, 512.0):
        with pytest.raises(InputError, match="quantisation step"):
            quantise(jnp.asarray(VALUES), step)


def _boxes(count, height, width):
    """Boxes on a quarter-pixel grid, sizes multiples of the patch: sample points are exact.

    Some straddle the border; the last lies wholly outside the frame.
    """
    rows, cols = PATCH
    x = RNG.integers(-40, 4 * width, count) / 4
    y = RNG.integers(-40, 4 * height, count) / 4
    w = cols * RNG.integers(1, 40, count) / 4
    h = rows * RNG.integers(1, 40, count) / 4
    boxes = np.stack([x, y, w, h], 1)
    boxes[-1] = (width + 2.0, 3.0, 8.0, 16.0)
    return boxes.astype(np.float32)


def _loop_histograms(frame, box, step):
    """Top and bottom joint RGB histograms of the nearest-pixel samples, by loops."""
    rows, cols = PATCH
    bins = num_bins(step)
    x, y, w, h = (float(v) for v in box)
    counts = np.zeros((2, bins**3))
    for i in range(rows):
        sy = y + (i + 0.5) * h / rows
        for j in range(cols):
            sx = x + (j + 0.5) * w / cols
            if 0 <= sy < frame.shape[0] and 0 <= sx < frame.shape[1]:
                red, green, blue = (
                    min(int(c // step), bins - 1) for c in frame[int(sy), int(sx)].astype(float)
                )
                counts[i // (rows // 2), (red * bins + green) * bins + blue] += 1
    totals = counts.sum(1, keepdims=True)
    return np.divide(counts, totals, out=np.zeros_like(counts), where=totals > 0)


@pytest.mark.parametrize("step", [32.0, 64.0, 24.0])
def test_rgb_features_equal_the_float_path_and_a_loop(step):
    height, width = 30, 44
    frame = RNG.integers(0, 256, (height, width, 3), dtype=np.uint8)
    boxes = _boxes(24, height, width)

    def features(colour_space):
        one = functools.partial(
            top_bottom_histograms, patch_shape=PATCH, step=step, colour_space=colour_space
        )
        return jax.jit(jax.vmap(one, in_axes=(None, 0)))(frame, boxes)

    fast = np.asarray(features(rgb))
    np.testing.assert_array_equal(fast, features(_as_float))  # bit-identical
    expected = np.stack([_loop_histograms(frame, box, step) for box in boxes])
    np.testing.assert_allclose(fast, expected, rtol=1e-6, atol=1e-7)
    assert not fast[-1].any()  # the box outside the frame has no sample
    assert np.count_nonzero(fast.sum(-1) > 0.999) > len(boxes)  # most halves are seen
    one = top_bottom_histograms(frame, boxes[0], PATCH, step)  # eager, unbatched
    np.testing.assert_array_equal(one, fast[0])
