"""Gated assignment: the unambiguous fast path and the Hungarian path against SciPy."""

import itertools

import jax
import numpy as np

from jaxtrack.association.assignment import _hungarian, gated_assignment


def brute_force(cost, allowed):
    """Largest matchings over allowed pairs, then the cheapest (exhaustive, tiny problems)."""
    rows, cols = cost.shape
    best = (-1, np.inf, None)
    for perm in itertools.permutations(range(cols), rows) if rows <= cols else []:
        pairs = [(r, c) for r, c in enumerate(perm) if allowed[r, c]]
        size, total = len(pairs), sum(cost[r, c] for r, c in pairs)
        if size > best[0] or (size == best[0] and total < best[1] - 1e-9):
            best = (size, total, pairs)
    match = np.full(rows, -1)
    for r, c in best[2]:
        match[r] = c
    return match


def test_matches_exhaustive_search_whether_ambiguous_or_not():
    rng = np.random.default_rng(0)
    assign = jax.jit(gated_assignment)
    unambiguous_seen = 0
    for density in np.repeat([0.1, 0.3, 0.6], 25):
        cost = rng.uniform(size=(4, 5)).astype(np.float32)
        allowed = rng.uniform(size=(4, 5)) < density
        unambiguous_seen += bool((allowed.sum(0) <= 1).all() and (allowed.sum(1) <= 1).all())
        expected = brute_force(cost, allowed)
        got = np.asarray(assign(cost, allowed))
        # Same size and cost (ties between equal-cost matchings are not expected here).
        np.testing.assert_array_equal(got, expected)
    assert 0 < unambiguous_seen < 75  # both paths ran


def test_fast_path_equals_hungarian_on_separated_pairs():
    rng = np.random.default_rng(3)
    allowed = np.zeros((64, 18), bool)
    rows = rng.permutation(64)[:12]
    cols = rng.permutation(18)[:12]
    allowed[rows, cols] = True
    cost = rng.uniform(size=(64, 18)).astype(np.float32)
    np.testing.assert_array_equal(
        np.asarray(jax.jit(gated_assignment)(cost, allowed)),
        np.asarray(jax.jit(_hungarian)(cost, allowed)),
    )
    vmapped = jax.vmap(gated_assignment)(np.stack([cost, cost]), np.stack([allowed, allowed]))
    np.testing.assert_array_equal(np.asarray(vmapped[0]), np.asarray(vmapped[1]))
