"""Fixed-size patch sampling of a box, so that every box costs the same under jit.

A box ``(x, y, w, h)`` (MOTChallenge: top-left corner, width, height, pixels) is divided into
``ph x pw`` equal cells; one sample is taken at the centre of each cell,

    s_x(j) = x + (j + 1/2) w / pw,    s_y(i) = y + (i + 1/2) h / ph,

frame pixel ``(r, c)`` covering ``[c, c + 1) x [r, r + 1)``, centre ``(c + 1/2, r + 1/2)``.
The cost is ``ph * pw`` samples whatever the box size, so boxes and particles ``vmap`` with
one compiled shape. Two lookups:

* :func:`sample_nearest`: the value of the pixel that contains the sample point (any
  per-pixel image): one gather per sample, and every sampled colour is one the box holds;
* :func:`sample_patch`: the colour bilinear in the four nearest pixel centres.

The features (:mod:`jaxtrack.appearance.features`) take the sampler as an argument, nearest
by default: ``benchmarks/appearance_features.py`` measured it faster than bilinear and at
least as close to full-resolution histograms (a bilinear sample between two differently
coloured pixels blends them into a colour the box does not hold, which matters once the
patch is dense enough for the sampling noise to drop). Sample points within float32
rounding of a pixel boundary may read either pixel.

Boxes partly outside the image: a sample point outside ``[0, W) x [0, H)`` is invalid (its
value is that of the nearest border pixel and must be ignored); histograms count the valid
samples only (:func:`jaxtrack.appearance.histograms.band_counts`), so a box that straddles
the border is described by its samples inside the image, and a box wholly outside (or with a
non-finite coordinate) by none: its histograms are all zero.

The sample density follows the box: a box smaller than the patch is oversampled, a larger one
subsampled (no pre-filtering). The benchmark measures the effect of the patch size on
histograms against full-resolution ones.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Shaped, UInt8

from jaxtrack.errors import InputError

#: Default ``(ph, pw)``: 16 x 8 samples (64 per half) suit pedestrian boxes (about 2.5 times
#: as tall as wide). On PETS09-S2L1 people (median box 80 px tall) the halves' 512-bin RGB
#: histograms lie at a median Bhattacharyya distance 0.29 from full-resolution ones (0.61
#: between two people), and 16 targets x 64 particles take about 1.5 ms per 768x576 frame on 2
#: otherwise idle CPU cores; 8 x 4 halves the time at distance 0.45, 32 x 16 triples it at
#: 0.15 (``benchmarks/appearance_features.py``).
DEFAULT_PATCH_SHAPE = (16, 8)


class Patch(NamedTuple):
    """A box sampled on a fixed grid.

    Attributes:
        values: the value of each sample: an RGB colour (float32 in ``[0, 255]``) from
            :func:`sample_patch`, the image's value from :func:`sample_nearest`.
        valid: True where the sample point lies inside the image.
    """

    values: Array
    valid: Bool[Array, "ph pw"]


def sample_points(
    box: Float[Array, " 4"], patch_shape: tuple[int, int]
) -> tuple[Float[Array, " ph"], Float[Array, " pw"]]:
    """Image coordinates of the sample grid: ``s_y(i)`` (rows) and ``s_x(j)`` (columns).

    Args:
        box: ``(x, y, w, h)``, pixels.
        patch_shape: ``(ph, pw)``, samples per column and per row of the box.

    Returns:
        ``(ys, xs)``: ``y + (i + 1/2) h / ph`` for ``i < ph`` and ``x + (j + 1/2) w / pw``
        for ``j < pw``.
    """
    rows, cols = patch_shape
    x, y, w, h = box[0], box[1], box[2], box[3]
    ys = y + (jnp.arange(rows, dtype=jnp.float32) + 0.5) * (h / rows)
    xs = x + (jnp.arange(cols, dtype=jnp.float32) + 0.5) * (w / cols)
    return ys, xs


def sample_patch(
    frame: UInt8[Array, "height width 3"],
    box: Float[Array, " 4"],
    patch_shape: tuple[int, int],
) -> Patch:
    """Bilinear samples of ``frame`` at the ``ph x pw`` cell centres of ``box``.

    With ``u = s_x - 1/2``, ``v = s_y - 1/2`` clamped to ``[0, W - 1] x [0, H - 1]``,
    ``u0 = floor(u)``, ``v0 = floor(v)`` (at most ``W - 2``, ``H - 2``), ``a = u - u0``,
    ``b = v - v0``:

        I(s) = (1 - b) [(1 - a) F(v0, u0) + a F(v0, u0 + 1)]
               + b [(1 - a) F(v0 + 1, u0) + a F(v0 + 1, u0 + 1)].

    Args:
        frame: RGB frame, uint8, at least 2 x 2 pixels.
        box: ``(x, y, w, h)``, pixels.
        patch_shape: ``(ph, pw)``, static.

    Returns:
        The samples' colours and validity (:class:`Patch`).

    Raises:
        InputError: the frame is not uint8 ``H x W x 3`` with ``H, W >= 2``, or the patch
            shape is not two positive integers.
    """
    check_frame(frame)
    _check_patch(patch_shape)
    height, width = frame.shape[0], frame.shape[1]
    ys, xs = sample_points(box, patch_shape)
    u = jnp.clip(xs - 0.5, 0.0, width - 1.0)
    v = jnp.clip(ys - 0.5, 0.0, height - 1.0)
    u0 = jnp.minimum(jnp.floor(u), width - 2.0)
    v0 = jnp.minimum(jnp.floor(v), height - 2.0)
    a = (u - u0)[None, :, None]
    b = (v - v0)[:, None, None]
    flat = frame.reshape(height * width, 3)
    index = v0.astype(jnp.int32)[:, None] * width + u0.astype(jnp.int32)[None, :]

    def at(offset):
        return flat[index + offset].astype(jnp.float32)

    top = (1.0 - a) * at(0) + a * at(1)
    bottom = (1.0 - a) * at(width) + a * at(width + 1)
    return Patch((1.0 - b) * top + b * bottom, _inside(ys, xs, height, width))


def sample_nearest(
    image: Shaped[Array, "height width *channels"],
    box: Float[Array, " 4"],
    patch_shape: tuple[int, int],
) -> Patch:
    """The value of the pixel ``(floor(s_y), floor(s_x))`` at each cell centre of ``box``.

    Row and column are clamped to the image (the validity marks the samples outside).

    Args:
        image: any per-pixel array, e.g. a frame or its colour bins, at least 1 x 1.
        box: ``(x, y, w, h)``, pixels.
        patch_shape: ``(ph, pw)``, static.

    Returns:
        The samples' values (``[ph, pw, *channels]``, the image's dtype) and validity.
    """
    _check_patch(patch_shape)
    height, width = image.shape[0], image.shape[1]
    ys, xs = sample_points(box, patch_shape)
    rows = jnp.clip(jnp.floor(ys), 0, height - 1).astype(jnp.int32)
    cols = jnp.clip(jnp.floor(xs), 0, width - 1).astype(jnp.int32)
    flat = image.reshape(height * width, *image.shape[2:])
    return Patch(flat[rows[:, None] * width + cols[None, :]], _inside(ys, xs, height, width))


def _inside(ys, xs, height, width) -> Bool[Array, "ph pw"]:
    return ((ys >= 0) & (ys < height))[:, None] & ((xs >= 0) & (xs < width))[None, :]


def check_frame(frame) -> None:
    """Raises InputError unless ``frame`` is a uint8 ``H x W x 3`` array, ``H, W >= 2``."""
    if frame.ndim != 3 or frame.shape[2] != 3 or min(frame.shape[:2]) < 2:
        raise InputError(f"a frame must be H x W x 3 with H, W >= 2, got shape {frame.shape}")
    if frame.dtype != jnp.uint8:
        raise InputError(f"a frame must be uint8 RGB, got dtype {frame.dtype}")


def _check_patch(patch_shape) -> None:
    if len(patch_shape) != 2 or not all(isinstance(n, int) and n > 0 for n in patch_shape):
        raise InputError(f"patch_shape must be two positive integers, got {patch_shape!r}")
