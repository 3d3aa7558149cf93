"""The papers' region histograms of one box, composed from the sampling and counting stages.

Each per-box function takes one image and one box; ``jax.vmap`` over boxes
(``in_axes=(None, 0)``) gives the features of every particle of every target with one
compiled shape. Static arguments (patch shape, step, bins, colour space, ``min_rows``) are
bound with ``functools.partial`` before ``jax.jit``.

* :func:`frame_bins` then :func:`top_bottom_histograms`: joint colour histograms of the top
  and bottom halves (CMT Sec. VI; their :func:`~jaxtrack.appearance.histograms.marginals` are
  CMT's per-channel bucket features). The frame is quantised once per frame and each box
  reads its samples' bins (:func:`~jaxtrack.appearance.patches.sample_nearest`): the hot path
  of a particle tracker;
* :func:`linear_combination_histograms`: Collins' 49 feature histograms (Hierarchical
  Sec. 5.2, 64 bins at ``step = 4``), from bilinear samples;
* :func:`profile_histograms`: HSV histograms of the upper and lower parts split at the row
  that tells them apart best (Fusion Sec. 2.1, eq. 1), from bilinear samples.
"""

from __future__ import annotations

from collections.abc import Callable

import jax.numpy as jnp
from jaxtyping import Array, Float, Int, UInt8

from jaxtrack.appearance.colour import hsv, linear_combinations, rgb
from jaxtrack.appearance.histograms import (
    band_counts,
    band_histograms,
    joint_bins,
    num_bins,
    quantise,
)
from jaxtrack.appearance.patches import check_frame, sample_nearest, sample_patch
from jaxtrack.appearance.regions import Split, best_split, halves

ColourSpace = Callable[[Float[Array, "*shape 3"]], Float[Array, "*shape channels"]]


def frame_bins(
    frame: UInt8[Array, "height width 3"], step: float, colour_space: ColourSpace = rgb
) -> Int[Array, "height width"]:
    """Joint colour bin of every pixel: ``joint_bins(quantise(colour_space(F), step))``.

    Args:
        frame: RGB frame, uint8.
        step: quantisation step ``lambda`` (``ceil(256 / lambda)`` bins per channel).
        colour_space: :func:`~jaxtrack.appearance.colour.rgb` (default),
            :func:`~jaxtrack.appearance.colour.normalised_rg` or
            :func:`~jaxtrack.appearance.colour.hsv`.

    Returns:
        Bins in ``[0, ceil(256 / step) ** channels)``.
    """
    check_frame(frame)
    channels = quantise(colour_space(frame.astype(jnp.float32)), step)
    return joint_bins(channels, num_bins(step))


def top_bottom_histograms(
    bins: Int[Array, "height width"],
    box: Float[Array, " 4"],
    patch_shape: tuple[int, int],
    num_bins: int,
    kernel: Float[Array, "ph pw"] | None = None,
) -> Float[Array, "2 num_bins"]:
    """Normalised joint colour histograms of the top and bottom halves of a box (CMT Sec. VI).

    ``h_k(b) = C_k sum_{samples s in half k} w(s) delta(b(s) - b)`` with ``w`` the sample's
    validity times the kernel, ``b(s)`` the bin of the pixel under sample ``s`` and ``C_k``
    normalising (all zeros when half ``k`` has no sample inside the image).

    Args:
        bins: the frame's joint colour bins (:func:`frame_bins`).
        box: ``(x, y, w, h)``, pixels.
        patch_shape: ``(ph, pw)`` samples, ``ph`` even.
        num_bins: joint bins, ``ceil(256 / step) ** channels`` (512 for RGB at step 32).
        kernel: ``[ph, pw]`` sample weights (e.g. one
            :func:`~jaxtrack.appearance.histograms.epanechnikov` kernel per half, stacked),
            or None for uniform weights.

    Returns:
        ``[top, bottom]`` histograms.
    """
    bands = halves(patch_shape[0])
    patch = sample_nearest(bins, box, patch_shape)
    weights = patch.valid if kernel is None else patch.valid * kernel
    return band_histograms(patch.values[..., None], weights, bands, 2, num_bins)[:, 0]


def linear_combination_histograms(
    frame: UInt8[Array, "height width 3"],
    box: Float[Array, " 4"],
    patch_shape: tuple[int, int],
    step: float = 4.0,
    kernel: Float[Array, "ph pw"] | None = None,
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
    """
    patch = sample_patch(frame, box, patch_shape)
    channels = quantise(linear_combinations(patch.values), step)
    weights = patch.valid if kernel is None else patch.valid * kernel
    rows = jnp.zeros(patch_shape[0], jnp.int32)
    return band_histograms(channels, weights, rows, 1, num_bins(step))[0]


def profile_histograms(
    frame: UInt8[Array, "height width 3"],
    box: Float[Array, " 4"],
    patch_shape: tuple[int, int],
    step: float,
    min_rows: int,
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
    """
    patch = sample_patch(frame, box, patch_shape)
    per_channel = num_bins(step)
    bins = joint_bins(quantise(hsv(patch.values), step), per_channel)[..., None]
    rows = jnp.arange(patch_shape[0], dtype=jnp.int32)
    counts = band_counts(bins, patch.valid, rows, patch_shape[0], per_channel**3)
    return best_split(counts[:, 0], min_rows)
