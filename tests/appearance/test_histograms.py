"""Quantisation, joint bins, band counts and kernels against NumPy loops and closed forms."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.appearance import (
    band_counts,
    band_histograms,
    epanechnikov,
    joint_bins,
    marginals,
    normalise,
    num_bins,
    quantise,
)
from jaxtrack.errors import InputError

RNG = np.random.default_rng(2)


@pytest.mark.parametrize(("step", "bins"), [(32.0, 8), (4.0, 64), (1.0, 256), (24.0, 11)])
def test_quantise(step, bins):
    values = np.concatenate([RNG.uniform(0, 256, 500), [0.0, 255.0, 255.99, 256.0]])
    got = np.asarray(quantise(jnp.asarray(values, jnp.float32), step))
    assert num_bins(step) == bins
    np.testing.assert_array_equal(got, np.minimum(np.floor(values / step), bins - 1))


def test_num_bins_refuses_bad_steps():
    for step in (0.0, -4.0, 300.0):
        with pytest.raises(InputError, match="quantisation step"):
            num_bins(step)


def test_joint_bins_is_ravel_multi_index():
    channel_bins = RNG.integers(0, 8, (50, 3))
    expected = np.ravel_multi_index(tuple(channel_bins.T), (8, 8, 8))
    np.testing.assert_array_equal(joint_bins(jnp.asarray(channel_bins), 8), expected)


def _band_counts_loop(bins, valid, kernel, splits, num_bins):
    edges = [0, *splits, bins.shape[0]]
    counts = np.zeros((len(edges) - 1, bins.shape[-1], num_bins))
    for band in range(len(edges) - 1):
        for i in range(edges[band], edges[band + 1]):
            for j in range(bins.shape[1]):
                for c in range(bins.shape[2]):
                    if valid[i, j]:
                        counts[band, c, bins[i, j, c]] += kernel[i, j]
    return counts


@pytest.mark.parametrize("with_kernel", [False, True])
def test_band_counts_and_histograms_loop(with_kernel):
    bins = RNG.integers(0, 6, (7, 4, 3))
    valid = RNG.uniform(0, 1, (7, 4)) < 0.8
    valid[5:] = False  # band 2 (rows 5-6) has no valid sample: all-zero histograms
    kernel = RNG.uniform(0.1, 1, (7, 4)) if with_kernel else np.ones((7, 4))
    splits = (2, 5)
    expected = _band_counts_loop(bins, valid, kernel, splits, 6)
    args = (jnp.asarray(bins), jnp.asarray(valid), splits, 6)
    weights = jnp.asarray(kernel, jnp.float32) if with_kernel else None
    np.testing.assert_allclose(band_counts(*args, weights), expected, rtol=1e-6, atol=1e-6)
    totals = expected.sum(-1, keepdims=True)
    expected_histograms = np.divide(expected, totals, out=np.zeros_like(expected), where=totals > 0)
    np.testing.assert_allclose(
        band_histograms(*args, weights), expected_histograms, rtol=1e-5, atol=1e-7
    )
    np.testing.assert_allclose(normalise(jnp.asarray(expected)), expected_histograms, rtol=1e-5)


def test_band_counts_vmap_equals_loop():
    bins = RNG.integers(0, 5, (6, 4, 3, 1))
    valid = RNG.uniform(0, 1, (6, 4, 3)) < 0.7
    batched = jax.jit(jax.vmap(lambda b, v: band_counts(b, v, (2,), 5)))
    got = batched(jnp.asarray(bins), jnp.asarray(valid))
    for k in range(6):
        expected = _band_counts_loop(bins[k], valid[k], np.ones((4, 3)), (2,), 5)
        np.testing.assert_allclose(got[k], expected, rtol=1e-6)


def test_band_splits_are_checked():
    bins, valid = jnp.zeros((4, 2, 1), jnp.int32), jnp.ones((4, 2), bool)
    for splits in ((0,), (2, 2), (3, 1), (4,)):
        with pytest.raises(InputError, match="band splits"):
            band_counts(bins, valid, splits, 3)


def test_marginals_sum_the_joint_histogram():
    joint = RNG.uniform(0, 1, (2, 4**3))
    cube = joint.reshape(2, 4, 4, 4)
    expected = np.stack([cube.sum((2, 3)), cube.sum((1, 3)), cube.sum((1, 2))], axis=1)
    np.testing.assert_allclose(marginals(jnp.asarray(joint), 3), expected, rtol=1e-6)
    with pytest.raises(InputError, match="joint bins"):
        marginals(jnp.ones(10), 3)


def test_epanechnikov_profile():
    kernel = np.asarray(epanechnikov((4, 3)))
    for i in range(4):
        for j in range(3):
            dy = ((i + 0.5) / 4 - 0.5) / 0.5
            dx = ((j + 0.5) / 3 - 0.5) / 0.5
            assert kernel[i, j] == pytest.approx(max(1 - dx * dx - dy * dy, 0.0), abs=1e-6)
    assert kernel[1, 1] == kernel.max() and kernel[0, 0] == 0.0  # centre high, corner out
