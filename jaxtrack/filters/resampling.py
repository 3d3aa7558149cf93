"""Resampling a weighted particle set to a fixed number of particles, preserving its mass.

PHD-context Sec. III, step 4: after the update the ``L + J`` weighted particles are resampled
to ``num_samples`` particles of equal weight ``M / num_samples``, ``M`` the total PHD mass.

A scheme maps normalised probabilities to ancestor indices,
``(key, probs[n], num_samples) -> indices[num_samples]``: :func:`systematic` (default, one
uniform draw), :func:`stratified`, :func:`multinomial`, :func:`residual` (Douc, Cappe &
Moulines 2005). Cumulative sums run in float64 when ``jax_enable_x64`` is on, and otherwise
blockwise in float32 (:func:`prefix_sum`: sums within blocks of 32 plus block offsets), which
keeps the rounding error of the CDF at a few ulps instead of ``n`` for a million particles.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float, Int

from jaxtrack.filters import draws

ResamplingScheme = Callable[[Array, Float[Array, " n"], int], Int[Array, " num_samples"]]


#: Elements per block of :func:`prefix_sum`: each block's running sums are one product with
#: a ``[PREFIX_BLOCK, PREFIX_BLOCK]`` triangular matrix of ones.
PREFIX_BLOCK = 32
#: :func:`prefix_sum` of integers runs in float32 while the sum is at most this (every partial
#: sum is then an exactly representable integer).
EXACT_FLOAT32_INTEGERS = 2**24


def prefix_sum(values: Array) -> Array:
    """Inclusive cumulative sum of a vector, by blocks of :data:`PREFIX_BLOCK` elements.

    Each block's running sums are one product with an upper-triangular matrix of ones, and the
    blocks' offsets are the prefix sums of their totals (recursively), so the whole is a few
    matrix products and additions: on CPU 4-7x faster than ``jnp.cumsum`` at 1e5-1e6
    elements, whose lowering (a parallel prefix: ``log2 n`` levels of strided slices) passes
    over the memory about ``2 log2 n`` times. In float32 the error is a few ulps of the total
    (sums of 32 terms, then of the block totals), below ``jnp.cumsum``'s at 1e6 elements.
    Integers (the caller's guarantee: non-negative, total at most
    :data:`EXACT_FLOAT32_INTEGERS`) are summed in float32, exactly, and returned in their
    dtype; other dtypes (float64 under x64) use ``jnp.cumsum``.

    Args:
        values: ``[n]`` array.

    Returns:
        ``[n]`` running sums, ``values``' dtype.
    """
    n = values.shape[0]
    if jnp.issubdtype(values.dtype, jnp.integer):
        return prefix_sum(values.astype(jnp.float32)).astype(values.dtype)
    if values.dtype != jnp.float32 or n <= PREFIX_BLOCK:
        return jnp.cumsum(values)
    num_blocks = -(-n // PREFIX_BLOCK)
    blocks = jnp.pad(values, (0, num_blocks * PREFIX_BLOCK - n)).reshape(num_blocks, -1)
    ones = jnp.triu(jnp.ones((PREFIX_BLOCK, PREFIX_BLOCK), values.dtype))
    within = jnp.dot(blocks, ones, precision=jax.lax.Precision.HIGHEST)
    totals = within[:, -1]
    offsets = jnp.concatenate([jnp.zeros(1, values.dtype), prefix_sum(totals)[:-1]])
    return (within + offsets[:, None]).reshape(-1)[:n]


def cumulative_probs(probs: Float[Array, " n"]) -> Float[Array, " n"]:
    """Normalised CDF of ``probs`` (last entry exactly 1), accurate for large ``n``.

    Args:
        probs: non-negative weights with a positive sum.

    Returns:
        ``cumsum(probs) / sum(probs)``: float64 if x64 is enabled, else float32 by
        :func:`prefix_sum` (sums of 32 terms and their block offsets).
    """
    wide = jax.dtypes.canonicalize_dtype(jnp.float64)
    if wide == jnp.float64:
        cdf = jnp.cumsum(probs.astype(wide))
        return (cdf / cdf[-1]).astype(probs.dtype)
    cdf = prefix_sum(probs)
    return cdf / cdf[-1]


def _inverse_cdf(probs: Float[Array, " n"], uniforms: Float[Array, " m"]) -> Int[Array, " m"]:
    """Index ``i`` with ``cdf[i-1] <= u < cdf[i]`` for each uniform ``u`` in ``[0, 1)``."""
    cdf = cumulative_probs(probs)
    indices = jnp.searchsorted(cdf, uniforms, side="right")
    return jnp.clip(indices, 0, probs.shape[0] - 1).astype(jnp.int32)


def systematic(
    key: Array, probs: Float[Array, " n"], num_samples: int
) -> Int[Array, " num_samples"]:
    """Systematic resampling: one uniform ``u``, points ``(u + j) / num_samples``.

    Equal to :func:`_inverse_cdf` of those points (``searchsorted``, a binary search per
    point), computed in ``O(n + num_samples)`` instead: the points are evenly spaced, so the
    number of points below ``cdf[i]`` is ``K_i = ceil(num_samples cdf[i] - u)`` (corrected by
    one either way where float32 rounding of the points disagrees, so the ancestors are those
    of the float32 points exactly), and point ``j``'s ancestor is the number of ``i`` with
    ``K_i <= j``: a histogram of the ``K_i`` and its cumulative sum.
    """
    # One uniform, its hash fused into its consumers (jax.random.uniform's number).
    (offset,) = draws.draw([draws.uniform(key, (), dtype=probs.dtype)], written=False)
    cdf = cumulative_probs(probs)

    def point(j):
        return (offset + j.astype(probs.dtype)) / num_samples

    guess = jnp.clip(jnp.ceil(num_samples * cdf - offset), 0, num_samples).astype(jnp.int32)
    below = jnp.where((guess > 0) & (point(guess - 1) >= cdf), guess - 1, guess)
    below = jnp.where((below < num_samples) & (point(below) < cdf), below + 1, below)
    histogram = jnp.zeros(num_samples + 1, jnp.int32).at[below].add(1)
    # Exact in float32 up to 2**24 particles (the histogram's total).
    count = prefix_sum if probs.shape[0] <= EXACT_FLOAT32_INTEGERS else jnp.cumsum
    ancestors = count(histogram[:num_samples])
    return jnp.clip(ancestors, 0, probs.shape[0] - 1).astype(jnp.int32)


def stratified(
    key: Array, probs: Float[Array, " n"], num_samples: int
) -> Int[Array, " num_samples"]:
    """Stratified resampling: one uniform per stratum ``[i, i + 1) / num_samples``."""
    offsets = jax.random.uniform(key, (num_samples,), probs.dtype)
    return _inverse_cdf(probs, (offsets + jnp.arange(num_samples)) / num_samples)


def multinomial(
    key: Array, probs: Float[Array, " n"], num_samples: int
) -> Int[Array, " num_samples"]:
    """Multinomial resampling: independent draws from ``probs``."""
    return _inverse_cdf(probs, jax.random.uniform(key, (num_samples,), probs.dtype))


def residual(key: Array, probs: Float[Array, " n"], num_samples: int) -> Int[Array, " num_samples"]:
    """Residual resampling: ``floor(num_samples p_i)`` copies, the rest multinomial.

    The deterministic copies fill the first slots, the multinomial draws on the residual
    weights ``num_samples p_i - floor(num_samples p_i)`` fill the remaining ones.
    """
    expected = num_samples * probs / jnp.sum(probs)
    copies = jnp.floor(expected).astype(jnp.int32)
    num_copies = jnp.sum(copies)
    deterministic = jnp.repeat(
        jnp.arange(probs.shape[0], dtype=jnp.int32), copies, total_repeat_length=num_samples
    )
    remainder = expected - copies
    has_remainder = jnp.sum(remainder) > 0
    remainder = jnp.where(has_remainder, remainder, 1.0)
    random = _inverse_cdf(remainder, jax.random.uniform(key, (num_samples,), probs.dtype))
    return jnp.where(jnp.arange(num_samples) < num_copies, deterministic, random)


def resample(
    key: Array,
    particles: Any,
    log_weights: Float[Array, " n"],
    num_samples: int,
    scheme: ResamplingScheme = systematic,
    stop_gradient: bool = False,
    soft_weight: float = 0.0,
) -> tuple[Any, Float[Array, " num_samples"]]:
    """Resamples to ``num_samples`` particles of weight ``M / num_samples``, ``M = sum w``.

    Args:
        key: PRNG key for the scheme.
        particles: particle states: an array ``[n, ...]`` or a PyTree of such arrays (e.g.
            states and per-particle values that travel with them).
        log_weights: unnormalised log-weights; their total mass is preserved.
        num_samples: number of particles after resampling (static).
        scheme: :func:`systematic` (default), :func:`stratified`, :func:`multinomial` or
            :func:`residual`.
        stop_gradient: if True, the new log-weights are
            ``log(M / num_samples) + log w_a - stop_gradient(log w_a)`` (Scibior & Wood 2021):
            the same values, but gradients carry the score of the ancestor draw, which makes
            gradient estimates unbiased. If False, ancestors are treated as constants
            (lower variance, biased).
        soft_weight: ``alpha`` in ``[0, 1)`` of soft resampling (Karkus, Hsu & Lee 2018),
            0 (default) for plain resampling: ancestors are drawn from
            ``q = (1 - alpha) p + alpha / n`` (``p`` the normalised weights) and get weights
            ``M p_a / q_a`` normalised to the mass ``M``, with gradients through ``p_a`` (a
            biased, lower-variance gradient estimator; the weights are no longer equal).
            Not combined with ``stop_gradient``.

    Returns:
        The resampled particles (the PyTree's leaves indexed by the ancestors) and their
        log-weights.

    Raises:
        ValueError: ``soft_weight`` outside ``[0, 1)``, or combined with ``stop_gradient``.
    """
    if not 0.0 <= soft_weight < 1.0:
        raise ValueError(f"soft_weight must lie in [0, 1), got {soft_weight}")
    if soft_weight > 0 and stop_gradient:
        raise ValueError("soft resampling and stop-gradient resampling are exclusive")
    log_mass = jax.nn.logsumexp(log_weights)
    probs = jnp.exp(jax.lax.stop_gradient(log_weights - log_mass))
    if soft_weight > 0:
        n = log_weights.shape[0]
        proposal = jax.lax.stop_gradient((1 - soft_weight) * probs + soft_weight / n)
        ancestors = scheme(key, proposal, num_samples)
        log_ratios = (log_weights - log_mass)[ancestors] - jnp.log(proposal[ancestors])
        return _select(particles, ancestors), log_mass + jax.nn.log_softmax(log_ratios)
    ancestors = scheme(key, probs, num_samples)
    new_log_weights = jnp.full((num_samples,), log_mass - math.log(num_samples))
    if stop_gradient:
        ancestor_log_weights = log_weights[ancestors]
        new_log_weights = (
            jax.lax.stop_gradient(new_log_weights)
            + ancestor_log_weights
            - jax.lax.stop_gradient(ancestor_log_weights)
        )
    return _select(particles, ancestors), new_log_weights


def _select(particles: Any, ancestors: Int[Array, " num_samples"]) -> Any:
    """The ancestors' rows of every leaf of ``particles``."""
    return jax.tree.map(lambda leaf: leaf[ancestors], particles)
