"""Small dense linear algebra (Cholesky, triangular and SPD solves) from elementwise operations.

The filters factor many tiny covariance matrices (4 x 4 clutter and measurement covariances,
6 x 6 birth and state covariances). ``jnp.linalg.cholesky`` and
``jax.scipy.linalg.solve_triangular`` lower to LAPACK custom calls on CPU, and under
``vmap`` (parameter sweeps, particle batches) jaxlib parallelises those calls over the batch
on the same thread pool that runs the computation. On a 2-core machine that pool can be full
of such calls waiting for each other: the whole computation deadlocks (seen with jaxlib
0.10.2: two ``lapack_strsm_ffi`` calls, each waiting in ``ParallelBatchMap`` for the other's
thread). These functions unroll the (static, small) matrix dimension in Python into
elementwise array operations instead: no custom calls, any batch shape by broadcasting,
differentiable, and on CPU as fast as LAPACK at these sizes.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float


def cholesky(a: Float[Array, "... n n"]) -> Float[Array, "... n n"]:
    """The lower Cholesky factor ``L`` (``a = L L^T``) of symmetric positive definite ``a``.

    Only the lower triangle of ``a`` is read. NaN where ``a`` is not positive definite (as
    ``jnp.linalg.cholesky``).
    """
    n = a.shape[-1]
    factor: list[list[Array | None]] = [[None] * n for _ in range(n)]
    for j in range(n):
        pivot = jnp.sqrt(a[..., j, j] - sum(factor[j][k] ** 2 for k in range(j)))
        factor[j][j] = pivot
        for i in range(j + 1, n):
            partial = sum(factor[i][k] * factor[j][k] for k in range(j))
            factor[i][j] = (a[..., i, j] - partial) / pivot
    zero = jnp.zeros_like(a[..., 0, 0])
    return jnp.stack(
        [jnp.stack([factor[i][j] if j <= i else zero for j in range(n)], -1) for i in range(n)],
        -2,
    )


def solve_lower(lower: Float[Array, "... n n"], b: Float[Array, "... n"]) -> Float[Array, "... n"]:
    """``x`` with ``lower @ x = b`` (forward substitution); batch axes broadcast."""
    n = lower.shape[-1]
    return jnp.stack(forward_substitution(lower, [b[..., i] for i in range(n)]), -1)


def forward_substitution(lower: Float[Array, "... n n"], b: list[Array]) -> list[Array]:
    """:func:`solve_lower` with ``b`` and ``x`` as lists of their ``n`` components.

    Each component broadcasts against ``lower[..., i, k]`` (e.g. ``[points, components]``
    arrays against ``[components, n, n]`` factors); the components are not stacked, so XLA
    can fuse the whole substitution into one loop over the broadcast shape.
    """
    x: list[Array] = []
    for i, b_i in enumerate(b):
        partial = sum(lower[..., i, k] * x[k] for k in range(i))
        x.append((b_i - partial) / lower[..., i, i])
    return x


def solve_upper_transposed(
    lower: Float[Array, "... n n"], b: Float[Array, "... n"]
) -> Float[Array, "... n"]:
    """``x`` with ``lower^T @ x = b`` (back substitution); batch axes broadcast."""
    n = lower.shape[-1]
    x: list[Array | None] = [None] * n
    for i in reversed(range(n)):
        partial = sum(lower[..., k, i] * x[k] for k in range(i + 1, n))
        x[i] = (b[..., i] - partial) / lower[..., i, i]
    return jnp.stack(x, -1)


def solve_spd(a: Float[Array, "... n n"], b: Float[Array, "... n"]) -> Float[Array, "... n"]:
    """``x`` with ``a @ x = b`` for symmetric positive definite ``a`` (via :func:`cholesky`)."""
    lower = cholesky(a)
    return solve_upper_transposed(lower, solve_lower(lower, b))


@jax.jit
def cholesky_loop(a: Float[Array, "... n n"]) -> Float[Array, "... n n"]:
    """:func:`cholesky` as a loop over the columns (``lax.fori_loop``): the same arithmetic
    (the columns not yet computed are zeros in the sums), equal up to float32 rounding (XLA
    orders and contracts the fused arithmetic of either form its own way).

    For factors of parameters, computed once per compiled run (a context's 64 mixture
    covariances): XLA gives the unrolled form's chain of dependent divisions and square roots
    a kernel each, about 60 kernels per mixture, and every kernel costs compile time (about
    15 ms each on 2 cores); the loop compiles to a handful. Inside a per-frame step, prefer
    :func:`cholesky` (no loop overhead). Jitted, so that eager calls reuse one compile per
    shape (inside another ``jit`` it is inlined).
    """
    n = a.shape[-1]
    index = jnp.arange(n)

    def column(j, factor):
        row_j = jnp.take(factor, j, axis=-2)  # L[j, k] for k < j, zeros from k = j on
        a_column = jnp.take(a, j, axis=-1)
        pivot = jnp.sqrt(jnp.take(a_column, j, axis=-1) - jnp.sum(row_j * row_j, -1))
        partial = jnp.sum(factor * row_j[..., None, :], -1)
        below = (a_column - partial) / pivot[..., None]
        new = jnp.where(index > j, below, jnp.where(index == j, pivot[..., None], 0.0))
        return jnp.where(index == j, new[..., :, None], factor)

    return jax.lax.fori_loop(0, n, column, jnp.zeros_like(a))


@jax.jit
def solve_lower_loop(
    lower: Float[Array, "... n n"], b: Float[Array, "... n"]
) -> Float[Array, "... n"]:
    """:func:`solve_lower` as a loop over the rows, equal up to float32 rounding (see
    :func:`cholesky_loop`, and use it likewise for parameters)."""
    n = lower.shape[-1]
    shape = jnp.broadcast_shapes(lower.shape[:-1], b.shape)
    lower = jnp.broadcast_to(lower, (*shape, n))
    b = jnp.broadcast_to(b, shape)
    index = jnp.arange(n)

    def row(i, x):
        lower_i = jnp.take(lower, i, axis=-2)
        x_i = (jnp.take(b, i, axis=-1) - jnp.sum(lower_i * x, -1)) / jnp.take(lower_i, i, -1)
        return jnp.where(index == i, x_i[..., None], x)

    return jax.lax.fori_loop(0, n, row, jnp.zeros_like(b))
