"""Parts of a box: top and bottom halves (CMT), the profile split (Fusion), the shape feature.

Parts are bands of patch rows (:func:`jaxtrack.appearance.histograms.band_counts`), so every
part of every box has a fixed number of samples.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
from jaxtyping import Array, Float, Int

from jaxtrack.appearance.histograms import normalise
from jaxtrack.appearance.similarity import bhattacharyya_distance
from jaxtrack.errors import InputError


def halves(num_rows: int) -> tuple[int]:
    """Band splits of the top and bottom halves of a patch (CMT Sec. VI): ``(ph // 2,)``.

    Raises:
        InputError: ``num_rows`` is odd (the halves would differ in size).
    """
    if num_rows % 2:
        raise InputError(f"top/bottom halves need an even number of patch rows, got {num_rows}")
    return (num_rows // 2,)


class Split(NamedTuple):
    """A box split into an upper and a lower part at a patch row.

    Attributes:
        row: first patch row of the lower part.
        distance: Bhattacharyya distance of the two parts' histograms.
        histograms: normalised ``[upper, lower]`` histograms.
    """

    row: Int[Array, ""]
    distance: Float[Array, ""]
    histograms: Float[Array, "2 num_bins"]


def best_split(row_counts: Float[Array, "ph num_bins"], min_rows: int) -> Split:
    """The split row maximising the distance between the upper and lower parts (Fusion eq. 1).

    ``Y = argmax_y d_Bh(h(I_u(y)), h(I_l(y)))``, ``I_u(y)`` = rows ``< y``, ``I_l(y)`` = rows
    ``>= y``, ``y`` in ``[min_rows, ph - min_rows]``: each part keeps at least ``min_rows``
    rows (the paper does not bound ``y``; a part of one or two rows has a noisy histogram that
    is far from anything, so the bound is a parameter). Ties go to the upper-most row.

    Args:
        row_counts: bin counts of each patch row (``band_counts`` with one band per row),
            HSV in the paper.
        min_rows: fewest rows in a part, static, ``1 <= min_rows <= ph / 2``.

    Returns:
        The best :class:`Split`.

    Raises:
        InputError: ``min_rows`` is out of range.
    """
    num_rows = row_counts.shape[0]
    if not 1 <= min_rows <= num_rows // 2:
        raise InputError(f"min_rows must be in [1, {num_rows // 2}], got {min_rows}")
    upper = jnp.cumsum(row_counts, axis=0)[min_rows - 1 : num_rows - min_rows]
    lower = jnp.sum(row_counts, axis=0) - upper
    parts = normalise(jnp.stack([upper, lower], axis=1))
    distances = bhattacharyya_distance(parts[:, 0], parts[:, 1])
    best = jnp.argmax(distances)
    return Split(best + min_rows, distances[best], parts[best])


def aspect_ratio(box: Float[Array, "*shape 4"]) -> Float[Array, "*shape"]:
    """The shape feature ``w / h`` of ``(x, y, w, h)`` boxes (CMT Sec. VI)."""
    return box[..., 2] / box[..., 3]
