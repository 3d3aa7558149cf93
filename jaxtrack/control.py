"""Control flow that XLA compiles the way a step needs (pure JAX, no dependencies)."""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
from jaxtyping import Array


def when(needed: Array, solve, fallback: Any, *args: Array) -> Any:
    """``solve(*args)`` where ``needed``, else ``fallback``; computed only if needed.

    A ``while_loop`` of at most one trip: unbatched it is a conditional; under ``vmap`` the
    batched loop runs its body once if any member needs it (and keeps the others'
    ``fallback``), where a batched ``lax.cond`` would run ``solve`` for every member always.
    Its outputs are written to memory once: XLA does not fuse a loop's body into the
    loop's consumers (see :func:`materialise`).

    Args:
        needed: scalar bool (per member under ``vmap``).
        solve: ``(*args) -> PyTree`` with ``fallback``'s structure, shapes and dtypes.
        fallback: the result where not needed.
        *args: arrays for ``solve``.
    """

    def body(state):
        running, _ = state
        # The inputs are made to depend on the loop's state: XLA hoists loop-invariant work
        # out of a while loop, which would run `solve` unconditionally again.
        varying = jnp.where(running, 0, 1).astype(jnp.int32)
        inputs = [
            x + varying.astype(x.dtype) if x.dtype != bool else x ^ (varying > 0) for x in args
        ]
        return jnp.asarray(False), solve(*inputs)

    _, result = jax.lax.while_loop(lambda state: state[0], body, (needed, fallback))
    return result


def materialise(compute, *args: Array) -> Any:
    """``compute(*args)``, written to memory once instead of fused into its consumers.

    XLA fuses cheap elementwise producers into every consumer, so an array that several
    fusions read (e.g. normal draws, whose inverse error function is dozens of operations,
    read once per state component they enter) is recomputed in each. Computed in a one-trip
    loop (:func:`when`, under a condition XLA cannot evaluate at compile time) it is written
    once. The first argument must be an unsigned or signed integer array (it decides the
    condition: ``(args[0].flat[0] | 1) != 0``, always true). Under ``vmap`` the loop runs the
    batched computation once for the whole batch (a batching rule), with the same values.
    """

    @jax.custom_batching.custom_vmap
    def once(*xs):
        return _written_once(compute, *xs)

    @once.def_vmap
    def once_batched(axis_size: int, in_batched: list[bool], *xs):
        # Under vmap the condition is one for the whole batch (it is always true): a loop
        # whose condition is per member would select between its body's results and the
        # fallback, one more pass over the outputs (the sweep's draws: 1.7x slower).
        xs = [
            x if batched else jnp.broadcast_to(x, (axis_size, *x.shape))
            for x, batched in zip(xs, in_batched, strict=True)
        ]
        out = _written_once(jax.vmap(compute), *xs)
        return out, jax.tree.map(lambda _: True, out)

    return once(*args)


def _written_once(compute, *args: Array) -> Any:
    fallback = jax.eval_shape(compute, *args)
    fallback = jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), fallback)
    always = (jnp.ravel(args[0])[0] | 1) != 0
    return when(always, compute, fallback, *args)


@jax.custom_batching.custom_vmap
def any_member(flag: Array) -> Array:
    """``flag`` itself; under ``vmap``, whether any member's ``flag`` is true (unbatched).

    A ``lax.cond`` on a batched predicate becomes a ``select`` that runs both branches for
    every member; on ``any_member(predicate)`` it stays a conditional, which skips the
    branch when no member of the batch needs it. The branch then runs for the whole batch,
    so a caller keeps each member's own choice with ``jnp.where(predicate, ...)``.
    """
    return flag


@any_member.def_vmap
def _any_member_batch(axis_size: int, in_batched: list[bool], flag: Array):
    return jnp.any(flag, axis=0), False


@jax.custom_batching.custom_vmap
def largest_member(value: Array) -> Array:
    """``value`` itself; under ``vmap``, the largest member's ``value`` (unbatched).

    A static size chosen from a batched count (a ``lax.switch`` over buckets) would run
    every branch for every member; chosen from ``largest_member(count)`` it stays a
    conditional that runs the one branch that fits the whole batch. Nested ``vmap`` levels
    each take their maximum (the batching rule calls this function again).
    """
    return value


@largest_member.def_vmap
def _largest_member_batch(axis_size: int, in_batched: list[bool], value: Array):
    return largest_member(jnp.max(value, axis=0)), False
