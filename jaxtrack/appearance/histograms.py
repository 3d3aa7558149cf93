"""Weighted histograms of quantised patch samples, per horizontal band of the patch.

Quantisation step ``lambda`` = bin width on the ``[0, 256]`` channel scale
(:mod:`jaxtrack.appearance.colour`): ``ceil(256 / lambda)`` bins per channel, bin
``floor(v / lambda)``, the top value 256 in the last bin (CMT Sec. VI; ``lambda = 32`` gives
8 bins per channel). A *joint* colour histogram (one bin per combination of channel bins,
``8^3 = 512`` for RGB at ``lambda = 32``) is the histogram of :func:`joint_bins`; per-channel
histograms (CMT's "2 x 3 x 255 / lambda" bucket features, Collins' 49 feature histograms) are
those of the channels themselves, or the marginals of a joint one (:func:`marginals`).

Raw uint8 colours with a whole power-of-two step are binned by a bit shift (:func:`quantise`;
the default RGB features, ``lambda = 32``: ``v >> 5``), the same bins as the float formula.
Counting is one scatter-add of the sample weights per box (``.at[].add``):
``benchmarks/appearance_features.py`` found it more than ten times faster on CPU than
summing one-hot vectors over 512 bins, and an integral histogram of the frame slower still
(even for 3 x 8 per-channel bins; a joint 512-bin one would not fit in memory).
"""

from __future__ import annotations

import itertools
import math

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int, Real

from jaxtrack.appearance.colour import SCALE
from jaxtrack.errors import InputError


def num_bins(step: float) -> int:
    """Bins per channel for quantisation step ``lambda``: ``ceil(256 / lambda)``.

    Raises:
        InputError: the step is not in ``(0, 256]``.
    """
    if not 0 < step <= SCALE:
        raise InputError(f"the quantisation step must be in (0, 256], got {step!r}")
    return math.ceil(SCALE / step)


def quantise(values: Real[Array, "*shape"], step: float) -> Int[Array, "*shape"]:
    """Bin index ``floor(v / lambda)`` of each channel value, clipped to the bins.

    uint8 values (raw pixel colours, e.g. nearest-pixel RGB samples) with a whole
    power-of-two step ``lambda = 2^k`` take the exact integer shortcut ``v >> k``: no value
    needs clipping (``255 >> k < 256 / 2^k``) and the result is that of the float formula.
    ``benchmarks/appearance_features.py`` measured it a quarter faster than the float formula
    for the default features (``float_quantise_16x8``). Any other values or step: the float
    formula.
    """
    bins = num_bins(step)
    shift = math.log2(step)
    if values.dtype == jnp.uint8 and shift.is_integer() and shift >= 0:
        return values.astype(jnp.int32) >> int(shift)
    return jnp.clip(jnp.floor(values / step), 0, bins - 1).astype(jnp.int32)


def joint_bins(
    channel_bins: Int[Array, "*shape num_channels"], bins_per_channel: int
) -> Int[Array, "*shape"]:
    """Joint bin ``sum_c b_c n^(C - 1 - c)`` of per-channel bins ``b_c`` (first channel slowest)."""
    joint = channel_bins[..., 0]
    for channel in range(1, channel_bins.shape[-1]):
        joint = joint * bins_per_channel + channel_bins[..., channel]
    return joint


def band_counts(
    bins: Int[Array, "ph pw num_channels"],
    valid: Bool[Array, "ph pw"],
    splits: tuple[int, ...],
    num_bins: int,
    kernel: Float[Array, "ph pw"] | None = None,
) -> Float[Array, "num_bands num_channels num_bins"]:
    """Bin counts of each channel in each band of patch rows, over the valid samples.

    The bands are the row ranges between consecutive ``splits`` (``(ph // 2,)``: top and
    bottom halves; ``()``: the whole patch; ``range(1, ph)``: one band per row).
    ``counts[k, c, b] = sum_{i in band k, j: valid[i, j], bins[i, j, c] = b} w[i, j]`` with
    ``w`` the kernel (1 without one): one scatter-add into ``num_bands * num_channels *
    num_bins`` cells. Invalid samples go to an index past the end, which the scatter drops
    (measured faster than adding them with weight 0).

    Args:
        bins: bin index of every sample and channel, in ``[0, num_bins)`` (as
            :func:`quantise` makes them); for a joint histogram, :func:`joint_bins` with a
            trailing axis of 1.
        valid: the samples to count (inside the image).
        splits: first row of each band after the first, increasing, in ``(0, ph)``, static.
        num_bins: bins per channel histogram, static.
        kernel: weight of each sample, or None for 1.

    Returns:
        The (unnormalised) counts, ``num_bands = len(splits) + 1``.

    Raises:
        InputError: the splits are not increasing rows inside the patch.
    """
    weights = jnp.ones((), jnp.float32) if kernel is None else kernel[..., None]
    return _scatter(bins, valid, splits, num_bins, weights)


def band_histograms(
    bins: Int[Array, "ph pw num_channels"],
    valid: Bool[Array, "ph pw"],
    splits: tuple[int, ...],
    num_bins: int,
    kernel: Float[Array, "ph pw"] | None = None,
) -> Float[Array, "num_bands num_channels num_bins"]:
    """Normalised histograms of each channel in each band: :func:`band_counts` / band weight.

    Each sample's weight is divided by its band's total before counting (instead of a pass
    over every bin after); a band with no valid sample has an all-zero histogram. Arguments
    as :func:`band_counts`.
    """
    _row_bands(splits, bins.shape[0])  # checks the splits
    weights = valid if kernel is None else jnp.where(valid, kernel, 0.0)
    row_totals = jnp.sum(weights, axis=1, dtype=jnp.float32)
    edges = tuple(itertools.pairwise((0, *splits, bins.shape[0])))
    totals = jnp.stack([jnp.sum(row_totals[a:b]) for a, b in edges])
    inverse = jnp.where(totals > 0, 1.0 / jnp.where(totals > 0, totals, 1.0), 0.0)
    row_scale = jnp.concatenate(
        [jnp.broadcast_to(inverse[k], (b - a, 1, 1)) for k, (a, b) in enumerate(edges)]
    )
    scaled = row_scale if kernel is None else row_scale * kernel[..., None]
    return _scatter(bins, valid, splits, num_bins, scaled)


def _scatter(bins, valid, splits, num_bins, weights):
    """Adds ``weights`` (broadcast to ``bins``) at each valid sample's band, channel and bin."""
    bands = _row_bands(splits, bins.shape[0])
    channels = bins.shape[-1]
    size = (len(splits) + 1) * channels * num_bins
    cell = (bands[:, None, None] * channels + np.arange(channels)) * num_bins + bins
    cell = jnp.where(valid[..., None], cell, size)
    updates = jnp.broadcast_to(weights, bins.shape).astype(jnp.float32)
    counts = jnp.zeros(size, jnp.float32).at[cell.ravel()].add(updates.ravel(), mode="drop")
    return counts.reshape(len(splits) + 1, channels, num_bins)


def _row_bands(splits: tuple[int, ...], num_rows: int) -> np.ndarray:
    """Band of each row (a constant): the number of splits at or before it."""
    if any(a >= b for a, b in itertools.pairwise((0, *splits, num_rows))):
        raise InputError(f"band splits must be increasing rows in (0, {num_rows}), got {splits}")
    return np.searchsorted(np.asarray(splits, int), np.arange(num_rows), side="right")


def normalise(counts: Float[Array, "*shape num_bins"]) -> Float[Array, "*shape num_bins"]:
    """``h(b) = counts(b) / sum counts``; all zeros where there is no count (nothing seen)."""
    total = jnp.sum(counts, axis=-1, keepdims=True)
    return jnp.where(total > 0, counts / jnp.where(total > 0, total, 1.0), 0.0)


def marginals(
    joint: Float[Array, "*shape total_bins"], num_channels: int
) -> Float[Array, "*shape num_channels bins_per_channel"]:
    """Per-channel histograms of a joint histogram over ``num_channels`` equal channels.

    ``m_c(b)`` sums the joint bins whose channel ``c`` is in bin ``b`` (the layout of
    :func:`joint_bins`), e.g. the CMT bucket features from a joint RGB histogram.

    Raises:
        InputError: the number of joint bins is not a ``num_channels``-th power.
    """
    per_channel = round(joint.shape[-1] ** (1.0 / num_channels))
    if per_channel**num_channels != joint.shape[-1]:
        raise InputError(f"{joint.shape[-1]} joint bins are not a {num_channels}-channel histogram")
    cube = joint.reshape(*joint.shape[:-1], *(per_channel,) * num_channels)
    axes = range(joint.ndim - 1, joint.ndim - 1 + num_channels)
    return jnp.stack(
        [jnp.sum(cube, axis=tuple(a for a in axes if a != axis)) for axis in axes], axis=-2
    )


def epanechnikov(patch_shape: tuple[int, int]) -> Float[Array, "ph pw"]:
    """Epanechnikov profile ``k(r) = max(1 - r^2, 0)`` at the patch's sample points.

    ``r^2 = ((j + 1/2) / pw - 1/2)^2 / (1/2)^2 + ((i + 1/2) / ph - 1/2)^2 / (1/2)^2``: the
    squared distance from the patch centre in units of the half width and half height, so
    the kernel spans the box (Comaniciu, Ramesh and Meer's kernel-weighted histograms). For
    band histograms (top and bottom halves), stack one kernel per band.
    """
    rows, cols = patch_shape
    dy = ((jnp.arange(rows) + 0.5) / rows - 0.5) / 0.5
    dx = ((jnp.arange(cols) + 0.5) / cols - 0.5) / 0.5
    return jnp.maximum(1.0 - dy[:, None] ** 2 - dx[None, :] ** 2, 0.0)
