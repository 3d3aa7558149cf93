"""Control flow for compiled steps (:mod:`jaxtrack.control`): ``when`` and ``materialise``."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.control import any_member, largest_member, materialise, when

BITS = np.random.default_rng(0).integers(0, 2**32, (3, 4, 50), dtype=np.uint32)


def _convert(bits, scale):
    """Two outputs of different shapes from integer bits and a float."""
    floats = (bits >> 9).astype(jnp.float32) * scale
    return {"sin": jnp.sin(floats), "sum": jnp.sum(floats, axis=-1)}


def test_materialise_equals_the_computation_unbatched_and_under_nested_vmap():
    """The written-once result is the computation's, member by member: one call, a batch
    (the batching rule's one loop for the whole batch), a batch of batches, and with an
    unbatched argument broadcast to the batch."""
    scale = np.float32(1e-6)
    expected = [[_convert(b, scale) for b in row] for row in BITS]

    def check(got, row, member):
        for name in ("sin", "sum"):
            np.testing.assert_array_equal(got[name], expected[row][member][name])

    check(jax.jit(lambda b: materialise(_convert, b, scale))(BITS[0, 0]), 0, 0)
    batched = jax.jit(jax.vmap(lambda b: materialise(_convert, b, scale)))(BITS[0])
    nested = jax.jit(jax.vmap(jax.vmap(lambda b: materialise(_convert, b, scale))))(BITS)
    scales = jnp.full(4, scale)
    mixed = jax.jit(jax.vmap(lambda s: materialise(_convert, BITS[0, 0], s)))(scales)
    for member in range(4):
        check(jax.tree.map(lambda x, m=member: x[m], batched), 0, member)
        check(jax.tree.map(lambda x, m=member: x[m], mixed), 0, 0)
        for row in range(3):
            check(jax.tree.map(lambda x, r=row, m=member: x[r, m], nested), row, member)


def test_when_runs_only_where_needed_and_keeps_the_fallback_elsewhere():
    def solve(x):
        return x * 2.0

    xs = jnp.arange(4.0)
    needed = jnp.array([True, False, True, False])
    got = jax.jit(jax.vmap(lambda n, x: when(n, solve, -1.0, x)))(needed, xs)
    np.testing.assert_array_equal(got, [0.0, -1.0, 4.0, -1.0])
    assert float(jax.jit(lambda x: when(jnp.asarray(False), solve, 7.0, x))(3.0)) == 7.0


def test_any_member_keeps_a_conditional_for_the_batch():
    """Unbatched it is the flag; under vmap it is one flag for the batch, so ``lax.cond``
    stays a conditional: its branch runs for no member when none needs it (a batched
    predicate would run both branches for every member)."""
    calls = []

    def branch(x):
        jax.debug.callback(lambda: calls.append(1))
        return x * 2.0

    def gated(flag, x):
        return jnp.where(flag, jax.lax.cond(any_member(flag), branch, lambda y: y, x), x)

    assert bool(jax.jit(any_member)(jnp.asarray(True)))
    xs = jnp.arange(3.0)
    batched = jax.jit(jax.vmap(gated))
    np.testing.assert_array_equal(batched(jnp.array([False, True, False]), xs), [0.0, 2.0, 2.0])
    jax.effects_barrier()
    assert len(calls) == 1
    np.testing.assert_array_equal(batched(jnp.zeros(3, bool), xs), xs)
    jax.effects_barrier()
    assert len(calls) == 1  # no member needed the branch: not run


def test_largest_member_is_one_value_for_the_batch_at_every_level():
    """Unbatched it is the value; under vmap (nested too) the largest member's, unbatched,
    so that a switch on it stays a conditional (no select over the branches)."""
    values = jnp.array([[3, 9, 1], [4, 2, 0]], jnp.int32)
    assert int(jax.jit(largest_member)(jnp.int32(5))) == 5
    np.testing.assert_array_equal(jax.jit(jax.vmap(largest_member))(values[0]), [9, 9, 9])
    np.testing.assert_array_equal(
        jax.jit(jax.vmap(jax.vmap(largest_member)))(values), np.full((2, 3), 9)
    )

    def switched(value):
        return jax.lax.switch(
            jnp.minimum(largest_member(value), 2), [lambda: 0, lambda: 1, lambda: 2]
        )

    for mapped, batch in ((jax.vmap(switched), values[0]), (jax.vmap(jax.vmap(switched)), values)):
        jaxpr = jax.make_jaxpr(mapped)(batch)
        assert [e.primitive.name for e in jaxpr.jaxpr.eqns].count("cond") == 1
