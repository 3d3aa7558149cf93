"""Reductions over the leading axis of ``[rows, n]`` arrays by pairwise halving.

XLA's CPU backend reduces over a major (leading) axis of a row-major array with a loop that
does not vectorise along the trailing axis: summing a ``[18, 100000]`` float32 array over its
rows took 8.3 ms on the 2-core development machine (jaxlib 0.10.2), against 0.9 ms over its
columns. The trackers hold ``[detections, particles]`` and ``[slots, particles]`` pair
arrays and reduce them over their leading axis (the eq. 10 sum over detections, a
softmax over detections). :func:`reduce_leading` instead combines the first half of the rows
with the second, elementwise, until one row remains (a row left over by an odd count is
carried to the next round): ``ceil(log2(rows))`` elementwise operations, each vectorised
along the trailing axis, which XLA fuses with the operations that produce the rows: 0.7-1.2 ms
for the example above, 3.3 ms instead of 75 ms for 128 rows.

The combination order differs from a sequential sum, so sums agree with ``jnp.sum`` up to
float32 rounding (pairwise summation: the error grows with ``log2(rows)``, not ``rows``);
maxima are exact.
"""

from __future__ import annotations

from collections.abc import Callable

import jax.numpy as jnp
from jaxtyping import Array


def reduce_leading(x: Array, combine: Callable[[Array, Array], Array]) -> Array:
    """``combine`` over the leading axis by pairwise halving (``rows`` static, > 0).

    Args:
        x: the array, reduced over axis 0.
        combine: an associative, commutative elementwise binary operation
            (``jnp.add``, ``jnp.maximum``, ``jnp.logaddexp``...).

    Returns:
        ``x[0] op x[1] op ... op x[rows - 1]`` (in a pairwise order).

    Raises:
        ValueError: ``x`` has no rows.
    """
    if x.shape[0] == 0:
        raise ValueError("reduce_leading needs at least one row")
    while x.shape[0] > 1:
        rows, half = x.shape[0], x.shape[0] // 2
        paired = combine(x[:half], x[half : 2 * half])
        x = jnp.concatenate([paired, x[2 * half :]]) if rows % 2 else paired
    return x[0]


def sum_leading(x: Array) -> Array:
    """``jnp.sum(x, axis=0)`` by :func:`reduce_leading` (pairwise, vectorised on CPU)."""
    return reduce_leading(x, jnp.add)


def max_leading(x: Array) -> Array:
    """``jnp.max(x, axis=0)`` by :func:`reduce_leading` (exact)."""
    return reduce_leading(x, jnp.maximum)
