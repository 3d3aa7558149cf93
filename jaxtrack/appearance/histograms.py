"""Weighted histograms of quantised patch samples, per horizontal band of the patch.

Quantisation step ``lambda`` = bin width on the ``[0, 256]`` channel scale
(:mod:`jaxtrack.appearance.colour`): ``ceil(256 / lambda)`` bins per channel, bin
``floor(v / lambda)``, the top value 256 in the last bin (CMT Sec. VI; ``lambda = 32`` gives
8 bins per channel). A *joint* colour histogram (one bin per combination of channel bins,
``8^3 = 512`` for RGB at ``lambda = 32``) is the histogram of :func:`joint_bins`; per-channel
histograms (CMT's "2 x 3 x 255 / lambda" bucket features, Collins' 49 feature histograms) are
those of the channels themselves, or the marginals of a joint one (:func:`marginals`).

Counting is a scatter-add of the sample weights (one ``segment_sum``-like ``.at[].add`` per
box): the benchmark ``benchmarks/appearance_features.py`` found it about 30 times faster on
CPU than summing one-hot vectors over 512 bins.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
from jaxtyping import Array, Float, Int

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


def quantise(values: Float[Array, "*shape"], step: float) -> Int[Array, "*shape"]:
    """Bin index ``floor(v / lambda)`` of each channel value, clipped to the bins."""
    return jnp.clip(jnp.floor(values / step), 0, num_bins(step) - 1).astype(jnp.int32)


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
    weights: Float[Array, "ph pw"],
    row_bands: Int[Array, " ph"],
    num_bands: int,
    num_bins: int,
) -> Float[Array, "num_bands num_channels num_bins"]:
    """Weighted bin counts of each channel in each band of rows of a patch.

    ``counts[k, c, b] = sum_{i, j: band(i) = k, bins[i, j, c] = b} weights[i, j]``: one
    scatter-add into ``num_bands * num_channels * num_bins`` cells.

    Args:
        bins: bin index of every sample and channel, in ``[0, num_bins)`` (as
            :func:`quantise` makes them; under jit an index out of range cannot raise, and
            JAX's scatter drops it); for a joint histogram, :func:`joint_bins` with a
            trailing axis of 1.
        weights: weight of every sample (validity, times a kernel if any).
        row_bands: band of each patch row, in ``[0, num_bands)`` (e.g. 0 for the top half and
            1 for the bottom half, :func:`jaxtrack.appearance.regions.halves`).
        num_bands: number of bands, static.
        num_bins: bins per channel histogram, static.

    Returns:
        The (unnormalised) counts.
    """
    channels = bins.shape[-1]
    cell = (row_bands[:, None, None] * channels + jnp.arange(channels)) * num_bins + bins
    sample_weights = jnp.broadcast_to(weights[..., None], bins.shape)
    counts = jnp.zeros(num_bands * channels * num_bins, jnp.float32)
    counts = counts.at[cell.ravel()].add(sample_weights.ravel())
    return counts.reshape(num_bands, channels, num_bins)


def band_histograms(
    bins: Int[Array, "ph pw num_channels"],
    weights: Float[Array, "ph pw"],
    row_bands: Int[Array, " ph"],
    num_bands: int,
    num_bins: int,
) -> Float[Array, "num_bands num_channels num_bins"]:
    """Normalised histograms of each channel in each band: :func:`band_counts` / band weight.

    The weights are divided by their band's total before counting (``ph * pw`` divisions
    instead of a pass over every bin); a band with no weight has an all-zero histogram.
    Arguments as :func:`band_counts`.
    """
    totals = jnp.zeros(num_bands, weights.dtype).at[row_bands].add(jnp.sum(weights, axis=1))
    per_row = totals[row_bands]
    scaled = weights / jnp.where(per_row > 0, per_row, 1.0)[:, None]
    return band_counts(bins, scaled, row_bands, num_bands, num_bins)


def normalise(counts: Float[Array, "*shape num_bins"]) -> Float[Array, "*shape num_bins"]:
    """``h(b) = counts(b) / sum counts``; all zeros where there is no count (nothing seen)."""
    total = jnp.sum(counts, axis=-1, keepdims=True)
    return jnp.where(total > 0, counts / jnp.where(total > 0, total, 1.0), 0.0)


def marginals(
    joint: Float[Array, "*shape total_bins"], num_channels: int
) -> Float[Array, "*shape num_channels bins_per_channel"]:
    """Per-channel histograms of a joint histogram over ``num_channels`` equal channels.

    ``m_c(b) = sum over joint bins whose channel-``c`` bin is ``b```` (the layout of
    :func:`joint_bins`), e.g. the CMT bucket features from a joint RGB histogram.
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
