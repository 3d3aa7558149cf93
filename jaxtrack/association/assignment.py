"""Gated linear assignment between two padded sets (jit / vmap compatible)."""

from __future__ import annotations

import functools
import itertools

import jax
import jax.numpy as jnp
import numpy as np
import optax
from jaxtyping import Array, Bool, Float, Int

from jaxtrack.control import when

#: Largest ambiguous part solved by enumeration: ``SMALL_SIDE`` slots of one side matched
#: (or not) into ``LARGE_SIDE`` slots of the other, every partial injection listed.
SMALL_SIDE = 4
LARGE_SIDE = 8


def _partial_injections(small: int, large: int) -> np.ndarray:
    """Every partial injection of ``small`` slots into ``large`` ones (-1: unmatched)."""
    rows = []
    for size in range(small + 1):
        for chosen in itertools.combinations(range(small), size):
            for target in itertools.permutations(range(large), size):
                row = np.full(small, -1)
                row[list(chosen)] = target
                rows.append(row)
    return np.asarray(rows, np.int32)


def gated_assignment(
    cost: Float[Array, "num_rows num_cols"], allowed: Bool[Array, "num_rows num_cols"]
) -> Int[Array, " num_rows"]:
    """Minimum-cost one-to-one matching restricted to the allowed pairs.

    Among matchings of maximum size over the allowed pairs, the result has minimum cost.

    A frame's gate is sparse, so the problem is solved in parts:

    1. an *isolated pair* (the row's only allowed column, whose only allowed row it is) is in
       every maximum matching and is taken as it is; rows without an allowed pair stay
       unmatched;
    2. the rest (the ambiguous rows and the columns they may take) is compacted; when one
       side has at most :data:`SMALL_SIDE` members and the other at most :data:`LARGE_SIDE`
       (over 99 % of the frames of MOT15 sequences), every partial injection of the small
       side into the large one (3,393 for 4 into 8) is scored at once by two matrix
       products: the largest number of allowed pairs, then the lowest cost (ties: the first
       listed);
    3. otherwise the whole problem goes to the Hungarian algorithm
       (``optax.assignment.hungarian_algorithm``, forbidden pairs priced above any sum of
       allowed costs). It runs only when needed: under ``vmap`` (sweeps), when some member
       of the batch needs it (a one-trip ``while_loop``, where ``lax.cond`` would run both
       branches for every member).

    The Hungarian algorithm's iterations are a loop of small kernels per augmenting step;
    in a 28-configuration sweep of PETS09-S2L1 they took about a fifth of the PHD step.

    Args:
        cost: pair costs, finite where allowed.
        allowed: True where a row may be matched to a column (the gate, padded slots False).

    Returns:
        For each row, the matched column, or -1.
    """
    num_rows, num_cols = cost.shape
    if num_rows == 0 or num_cols == 0:
        return jnp.full(num_rows, -1, jnp.int32)
    # A matching has no derivative; stopping it lets reverse-mode differentiation of a
    # tracker pass the while loops and the custom_vmap rule below (not differentiable).
    return _solve(jax.lax.stop_gradient(cost), allowed)


@jax.custom_batching.custom_vmap
def _solve(cost: Array, allowed: Array) -> Array:
    """One problem: the usual frame has no open part, and its matching is the isolated pairs
    (the open part is solved only when there is one)."""
    matches, open_rows = _isolated_pairs(allowed)
    return when(jnp.any(open_rows), _open_part, matches, cost, allowed, matches, open_rows)


@_solve.def_vmap
def _solve_batch(axis_size: int, in_batched: list[bool], cost: Array, allowed: Array):
    """A batch (a sweep's configurations): some member nearly always has an open part, so
    it is solved for all without the conditional (which would cost more than it saves)."""
    cost, allowed = (
        x if batched else jnp.broadcast_to(x, (axis_size, *x.shape))
        for x, batched in zip((cost, allowed), in_batched, strict=True)
    )
    return jax.vmap(lambda c, a: _open_part(c, a, *_isolated_pairs(a)))(cost, allowed), True


def _isolated_pairs(allowed: Array) -> tuple[Array, Array]:
    """Each row's isolated pair's column (or -1), and the open rows (allowed pairs, none
    isolated)."""
    row_degree = jnp.sum(allowed, axis=1)
    col_degree = jnp.sum(allowed, axis=0)
    isolated = allowed & (row_degree[:, None] == 1) & (col_degree[None, :] == 1)
    paired = jnp.any(isolated, axis=1)
    matches = jnp.where(paired, jnp.argmax(isolated, axis=1), -1).astype(jnp.int32)
    return matches, (row_degree > 0) & ~paired


def _open_part(cost: Array, allowed: Array, matches: Array, open_rows: Array) -> Array:
    """:func:`gated_assignment` when some rows are open (steps 2 and 3), from the isolated
    pairs' ``matches`` and the ``open_rows`` (:func:`_isolated_pairs`)."""
    num_rows = cost.shape[0]
    open_cols = jnp.any(allowed & open_rows[:, None], axis=0)
    num_open_rows, num_open_cols = jnp.sum(open_rows), jnp.sum(open_cols)
    rows_small = (num_open_rows <= SMALL_SIDE) & (num_open_cols <= LARGE_SIDE)
    cols_small = (num_open_cols <= SMALL_SIDE) & (num_open_rows <= LARGE_SIDE)

    # The open part as a SMALL_SIDE x LARGE_SIDE problem: its rows first when they fit the
    # small side, else its columns (the transposed problem).
    def first(mask, size):
        """Indices of the first ``size`` members of ``mask`` and which of them exist."""
        index = jnp.nonzero(mask, size=size, fill_value=0)[0]
        return index, jnp.arange(size) < jnp.sum(mask)

    rows_s, rows_s_ok = first(open_rows, SMALL_SIDE)
    rows_l, rows_l_ok = first(open_rows, LARGE_SIDE)
    cols_s, cols_s_ok = first(open_cols, SMALL_SIDE)
    cols_l, cols_l_ok = first(open_cols, LARGE_SIDE)
    small_ok = jnp.where(rows_small, rows_s_ok, cols_s_ok)
    large_ok = jnp.where(rows_small, cols_l_ok, rows_l_ok)
    sub_allowed = jnp.where(
        rows_small, allowed[rows_s][:, cols_l], allowed.T[cols_s][:, rows_l]
    ) & (small_ok[:, None] & large_ok[None, :])
    sub_cost = jnp.where(
        sub_allowed, jnp.where(rows_small, cost[rows_s][:, cols_l], cost.T[cols_s][:, rows_l]), 0
    )
    candidates, one_hot, sizes = (jnp.asarray(t) for t in _candidate_table())
    # Per candidate, by matrix products with its pair indicator: the forbidden pairs it uses
    # and the cost of its pairs. Then the largest size, the lowest cost, the first index
    # (plain reductions: XLA's argmin is a slow variadic reduction on CPU).
    forbidden_used = one_hot @ (~sub_allowed).reshape(-1).astype(cost.dtype)
    total = one_hot @ sub_cost.reshape(-1).astype(cost.dtype)
    size = jnp.where(forbidden_used == 0, sizes, -1)
    key = jnp.where(size == jnp.max(size), total, jnp.inf)
    position = jnp.arange(candidates.shape[0])
    best = jnp.min(jnp.where(key == jnp.min(key), position, candidates.shape[0]))
    chosen = candidates[best]
    linked = small_ok & (chosen >= 0)
    target = jnp.maximum(chosen, 0)
    to_row = jnp.where(rows_small, rows_s, rows_l[target])
    to_col = jnp.where(rows_small, cols_l[target], cols_s)
    enumerated = matches.at[jnp.where(linked, to_row, num_rows)].set(
        to_col.astype(jnp.int32), mode="drop"
    )
    return when(~(rows_small | cols_small), _hungarian, enumerated, cost, allowed)


@functools.cache
def _candidate_table() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Partial injections of :data:`SMALL_SIDE` into :data:`LARGE_SIDE` slots, their pair
    indicators ``[candidates, SMALL_SIDE * LARGE_SIDE]`` and their sizes."""
    candidates = _partial_injections(SMALL_SIDE, LARGE_SIDE)
    one_hot = np.zeros((candidates.shape[0], SMALL_SIDE * LARGE_SIDE), np.float32)
    for slot in range(SMALL_SIDE):
        taken = candidates[:, slot] >= 0
        one_hot[np.nonzero(taken)[0], slot * LARGE_SIDE + candidates[taken, slot]] = 1.0
    return candidates, one_hot, (candidates >= 0).sum(axis=1).astype(np.int32)


def _hungarian(cost: Array, allowed: Array) -> Array:
    """The gated matching by the Hungarian algorithm (see :func:`gated_assignment`)."""
    safe_cost = jnp.where(allowed, cost, 0.0)
    span = jnp.max(jnp.abs(safe_cost))
    forbidden = (1.0 + 2.0 * span) * (1 + min(cost.shape))
    rows, cols = optax.assignment.hungarian_algorithm(jnp.where(allowed, safe_cost, forbidden))
    matches = jnp.full(cost.shape[0], -1, jnp.int32)
    keep = allowed[rows, cols]
    return matches.at[rows].set(jnp.where(keep, cols, -1).astype(jnp.int32))
