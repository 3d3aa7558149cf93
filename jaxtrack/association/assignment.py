"""Gated linear assignment between two padded sets (jit / vmap compatible)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import optax
from jaxtyping import Array, Bool, Float, Int


def gated_assignment(
    cost: Float[Array, "num_rows num_cols"], allowed: Bool[Array, "num_rows num_cols"]
) -> Int[Array, " num_rows"]:
    """Minimum-cost one-to-one matching restricted to the allowed pairs.

    Runs the Hungarian algorithm (``optax.assignment.hungarian_algorithm``) on the cost with
    forbidden pairs priced above any sum of allowed costs, then drops the forbidden pairs it
    had to use. Among matchings of maximum size over allowed pairs, the result has minimum
    cost.

    When the allowed pairs already form a matching (no row and no column with two allowed
    pairs: separated targets, the usual frame), that matching is the only one of maximum
    size and is returned without the Hungarian algorithm's iterations (``lax.cond``; under
    ``vmap`` both branches run).

    Args:
        cost: pair costs, finite where allowed.
        allowed: True where a row may be matched to a column (the gate, padded slots False).

    Returns:
        For each row, the matched column, or -1.
    """
    unambiguous = jnp.all(jnp.sum(allowed, axis=0) <= 1) & jnp.all(jnp.sum(allowed, axis=1) <= 1)
    return jax.lax.cond(unambiguous, _allowed_pairs, _hungarian, cost, allowed)


def _allowed_pairs(cost: Array, allowed: Array) -> Array:
    """Each row's only allowed column (the allowed pairs form a matching), or -1."""
    del cost
    return jnp.where(jnp.any(allowed, axis=1), jnp.argmax(allowed, axis=1), -1).astype(jnp.int32)


def _hungarian(cost: Array, allowed: Array) -> Array:
    """The gated matching by the Hungarian algorithm (see :func:`gated_assignment`)."""
    safe_cost = jnp.where(allowed, cost, 0.0)
    span = jnp.max(jnp.abs(safe_cost))
    forbidden = (1.0 + 2.0 * span) * (1 + min(cost.shape))
    rows, cols = optax.assignment.hungarian_algorithm(jnp.where(allowed, safe_cost, forbidden))
    matches = jnp.full(cost.shape[0], -1, jnp.int32)
    keep = allowed[rows, cols]
    return matches.at[rows].set(jnp.where(keep, cols, -1).astype(jnp.int32))
