"""Gated assignment: isolated pairs, the enumerated small part and the Hungarian fallback
against exhaustive search and SciPy, jitted and vmapped."""

import itertools

import jax
import numpy as np
from scipy.optimize import linear_sum_assignment

from jaxtrack.association.assignment import LARGE_SIDE, SMALL_SIDE, _hungarian, gated_assignment


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


def scipy_optimum(cost, allowed):
    """(size, cost) of the largest, then cheapest, matching over the allowed pairs."""
    big = np.where(allowed, cost, 1e4)
    r, c = linear_sum_assignment(big)
    keep = allowed[r, c]
    return int(keep.sum()), float(cost[r[keep], c[keep]].sum())


def matching_value(match, cost, allowed):
    rows = np.nonzero(match >= 0)[0]
    cols = match[rows]
    assert np.all(allowed[rows, cols]), "a forbidden pair"
    assert len(set(cols.tolist())) == cols.size, "a column used twice"
    return int(rows.size), float(cost[rows, cols].sum())


def open_part(allowed):
    """Sizes of the part left after isolated pairs (the enumeration's condition)."""
    rows, cols = allowed.sum(1), allowed.sum(0)
    paired = (allowed & (rows[:, None] == 1) & (cols[None, :] == 1)).any(1)
    open_rows = (rows > 0) & ~paired
    return int(open_rows.sum()), int((allowed & open_rows[:, None]).any(0).sum())


def test_enumerated_and_fallback_parts_are_optimal_at_every_shape():
    rng = np.random.default_rng(7)
    solve = jax.jit(gated_assignment)
    enumerated = fallback = 0
    for _ in range(400):
        num_rows, num_cols = rng.integers(1, 13, 2)
        density = rng.choice([0.05, 0.15, 0.3, 0.6])
        cost = rng.uniform(-1, 1, (num_rows, num_cols)).astype(np.float32)
        allowed = rng.uniform(size=(num_rows, num_cols)) < density
        # Padded to one shape (one compile): padded slots are never allowed.
        padded_cost = np.zeros((12, 12), np.float32)
        padded_allowed = np.zeros((12, 12), bool)
        padded_cost[:num_rows, :num_cols] = cost
        padded_allowed[:num_rows, :num_cols] = allowed
        match = np.asarray(solve(padded_cost, padded_allowed))[:num_rows]
        size, total = matching_value(match, cost, allowed)
        expected = scipy_optimum(cost, allowed)
        assert size == expected[0]
        np.testing.assert_allclose(total, expected[1], atol=1e-5)
        r, c = open_part(allowed)
        small = (r <= SMALL_SIDE and c <= LARGE_SIDE) or (c <= SMALL_SIDE and r <= LARGE_SIDE)
        enumerated += small and r > 0
        fallback += not small
    assert enumerated > 100 and fallback > 50  # both paths were exercised


def test_vmapped_batch_mixing_small_and_large_parts():
    """Under vmap the Hungarian runs for the batch when one member needs it; every member
    keeps its own optimum."""
    rng = np.random.default_rng(11)
    cost = rng.uniform(-1, 1, (6, 64, 16)).astype(np.float32)
    allowed = np.zeros((6, 64, 16), bool)
    for b in range(6):
        allowed[b, rng.permutation(64)[:6], rng.permutation(16)[:6]] = True
        allowed[b, :3, :3] |= rng.uniform(size=(3, 3)) < 0.5
    allowed[2, :12, :12] = rng.uniform(size=(12, 12)) < 0.5  # needs the Hungarian
    assert open_part(allowed[2])[0] > LARGE_SIDE
    batched = np.asarray(jax.jit(jax.vmap(gated_assignment))(cost, allowed))
    for b in range(6):
        got = matching_value(batched[b], cost[b], allowed[b])
        expected = scipy_optimum(cost[b], allowed[b])
        assert got[0] == expected[0]
        np.testing.assert_allclose(got[1], expected[1], atol=1e-5)


def test_empty_sides():
    assert gated_assignment(np.zeros((0, 3), np.float32), np.zeros((0, 3), bool)).shape == (0,)
    np.testing.assert_array_equal(
        gated_assignment(np.zeros((2, 0), np.float32), np.zeros((2, 0), bool)), [-1, -1]
    )
