"""The papers' region histograms of one box, composed from the sampling and counting stages.

Each function takes one frame and one box; ``jax.vmap`` over boxes (``in_axes=(None, 0)``)
gives the features of every particle of every target with one compiled shape. Static
arguments (patch shape, step, colour space, sampler, ``min_rows``) are bound with
``functools.partial`` before ``jax.jit``.

* :func:`top_bottom_histograms`: joint colour histograms of the top and bottom halves (CMT
  Sec. VI; their :func:`~jaxtrack.appearance.histograms.marginals` are CMT's per-channel
  bucket features);
* :func:`linear_combination_histograms`: Collins' 49 feature histograms (Hierarchical
  Sec. 5.2, 64 bins at ``step = 4``);
* :func:`profile_histograms`: HSV histograms of the upper and lower parts split at the row
  that tells them apart best (Fusion Sec. 2.1, eq. 1).

The sampler is injected: :func:`~jaxtrack.appearance.patches.sample_nearest` (default) or
:func:`~jaxtrack.appearance.patches.sample_patch` (bilinear). ``benchmarks/
appearance_features.py`` measured nearest-pixel samples faster than bilinear ones (one
gather per sample instead of four) and at least as close to full-resolution histograms
(bilinear samples between two differently coloured pixels blend into colours the box does
not hold).
"""

from __future__ import annotations

from collections.abc import Callable

import jax.numpy as jnp
from jaxtyping import Array, Float, UInt8

from jaxtrack.appearance.colour import hsv, linear_combinations, rgb
from jaxtrack.appearance.histograms import (
    band_counts,
    band_histograms,
    joint_bins,
    num_bins,
    quantise,
)
from jaxtrack.appearance.patches import Patch, check_frame, sample_nearest
from jaxtrack.appearance.regions import Split, best_split, halves

ColourSpace = Callable[[Float[Array, "*shape 3"]], Float[Array, "*shape channels"]]
Sampler = Callable[[UInt8[Array, "height width 3"], Float[Array, " 4"], tuple[int, int]], Patch]


def _samples(frame, box, patch_shape, sampler, colour_space) -> Patch:
    """The box's samples in ``colour_space``, after checking the frame.

    The colour spaces take float colours, except :func:`~jaxtrack.appearance.colour.rgb`,
    the identity, which keeps the sampler's dtype: nearest-pixel samples stay uint8, which
    :func:`~jaxtrack.appearance.histograms.quantise` bins by a bit shift (same bins).
    """
    check_frame(frame)
    patch = sampler(frame, box, patch_shape)
    values = patch.values if colour_space is rgb else patch.values.astype(jnp.float32)
    return Patch(colour_space(values), patch.valid)


def top_bottom_histograms(
    frame: UInt8[Array, "height width 3"],
    box: Float[Array, " 4"],
    patch_shape: tuple[int, int],
    step: float,
    colour_space: ColourSpace = rgb,
    kernel: Float[Array, "ph pw"] | None = None,
    sampler: Sampler = sample_nearest,
) -> Float[Array, "2 joint_bins"]:
    """Normalised joint colour histograms of the top and bottom halves of a box (CMT Sec. VI).

    ``h_k(b) = C_k sum_{valid samples s in half k} w(s) delta(b(s) - b)`` with ``w`` the
    kernel (1 without one), ``b(s)`` the joint bin of the sample's quantised channels and
    ``C_k`` normalising (all zeros when half ``k`` has no sample inside the image).

    Args:
        frame: RGB frame, uint8.
        box: ``(x, y, w, h)``, pixels.
        patch_shape: ``(ph, pw)`` samples, ``ph`` even.
        step: quantisation step ``lambda`` (``ceil(256 / lambda)`` bins per channel).
        colour_space: :func:`~jaxtrack.appearance.colour.rgb` (default; nearest-pixel
            samples then stay uint8 and a power-of-two step bins them by a bit shift),
            :func:`~jaxtrack.appearance.colour.normalised_rg` or
            :func:`~jaxtrack.appearance.colour.hsv`.
        kernel: ``[ph, pw]`` sample weights (e.g. one
            :func:`~jaxtrack.appearance.histograms.epanechnikov` kernel per half, stacked),
            or None for uniform weights.
        sampler: how samples read the frame (nearest pixel or bilinear).

    Returns:
        ``[top, bottom]`` histograms of ``ceil(256 / step) ** channels`` bins.
    """
    splits = halves(patch_shape[0])
    patch = _samples(frame, box, patch_shape, sampler, colour_space)
    channels = quantise(patch.values, step)
    per_channel = num_bins(step)
    bins = joint_bins(channels, per_channel)[..., None]
    total = per_channel ** channels.shape[-1]
    return band_histograms(bins, patch.valid, splits, total, kernel)[:, 0]


def linear_combination_histograms(
    frame: UInt8[Array, "height width 3"],
    box: Float[Array, " 4"],
    patch_shape: tuple[int, int],
    step: float = 4.0,
    kernel: Float[Array, "ph pw"] | None = None,
    sampler: Sampler = sample_nearest,
) -> Float[Array, "49 num_bins"]:
    """Normalised histograms of the 49 Collins features over a box (Hierarchical eq. 1).

    ``p^i_k = C_i sum_a w_a delta(b_i(x_a) - k)``, one histogram per feature ``i``; 64 bins at
    the default ``step = 4`` (Hierarchical Sec. 5.2). The background histograms ``q^i`` of
    the variance ratio are the same function of a background region.

    Args:
        frame: RGB frame, uint8.
        box: ``(x, y, w, h)``, pixels.
        patch_shape: ``(ph, pw)`` samples.
        step: quantisation step on the ``[0, 256]`` feature scale.
        kernel: ``[ph, pw]`` sample weights, or None for uniform weights.
        sampler: how samples read the frame (nearest pixel or bilinear).
    """
    patch = _samples(frame, box, patch_shape, sampler, linear_combinations)
    channels = quantise(patch.values, step)
    return band_histograms(channels, patch.valid, (), num_bins(step), kernel)[0]


def profile_histograms(
    frame: UInt8[Array, "height width 3"],
    box: Float[Array, " 4"],
    patch_shape: tuple[int, int],
    step: float,
    min_rows: int,
    sampler: Sampler = sample_nearest,
) -> Split:
    """Fusion's target profile: joint HSV histograms of the upper and lower body parts.

    The split row ``Y`` maximises the Bhattacharyya distance of the two parts' HSV histograms
    (Fusion eq. 1, :func:`~jaxtrack.appearance.regions.best_split`); rows are patch rows, so
    ``Y / ph`` is the split's fraction of the box height.

    Args:
        frame: RGB frame, uint8.
        box: ``(x, y, w, h)``, pixels.
        patch_shape: ``(ph, pw)`` samples.
        step: quantisation step of H, S and V.
        min_rows: fewest patch rows in a part.
        sampler: how samples read the frame (nearest pixel or bilinear).
    """
    patch = _samples(frame, box, patch_shape, sampler, hsv)
    per_channel = num_bins(step)
    bins = joint_bins(quantise(patch.values, step), per_channel)[..., None]
    rows = tuple(range(1, patch_shape[0]))
    counts = band_counts(bins, patch.valid, rows, per_channel**3)
    return best_split(counts[:, 0], min_rows)
