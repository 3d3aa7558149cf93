"""Similarity of normalised histograms: Bhattacharyya coefficient, distance and likelihood.

All reduce the last axis (the bins) and broadcast over the others.
"""

from __future__ import annotations

import jax.numpy as jnp
from jaxtyping import Array, Float


def bhattacharyya_coefficient(
    p: Float[Array, "*shape num_bins"], q: Float[Array, "*shape num_bins"]
) -> Float[Array, "*shape"]:
    """``BC(p, q) = sum_b sqrt(p(b) q(b))``: 1 for equal histograms, 0 for disjoint ones."""
    return jnp.sum(jnp.sqrt(p * q), axis=-1)


def bhattacharyya_distance(
    p: Float[Array, "*shape num_bins"], q: Float[Array, "*shape num_bins"]
) -> Float[Array, "*shape"]:
    """``d(p, q) = sqrt(1 - BC(p, q))`` in ``[0, 1]`` (Hierarchical Sec. 5.3).

    Rounding can push ``BC`` a little above 1 for equal histograms; ``1 - BC`` is clipped at 0.
    An all-zero histogram (nothing seen) is at distance 1 from everything.
    """
    return jnp.sqrt(jnp.maximum(1.0 - bhattacharyya_coefficient(p, q), 0.0))


def histogram_likelihood(
    p: Float[Array, "*shape num_bins"],
    q: Float[Array, "*shape num_bins"],
    sigma: Float[Array, ""],
) -> Float[Array, "*shape"]:
    """``exp(-d(p, q)^2 / (2 sigma^2))`` with ``d^2 = 1 - BC`` (no square root, so smooth).

    Args:
        p: candidate histograms (e.g. of a particle's box).
        q: reference histograms (e.g. a target's appearance model).
        sigma: spread of the likelihood in distance units, positive.
    """
    squared = jnp.maximum(1.0 - bhattacharyya_coefficient(p, q), 0.0)
    return jnp.exp(-squared / (2.0 * sigma**2))
