"""Several ``jax.random`` draws of one step from one Threefry evaluation, bit for bit.

A PHD step draws three arrays of random numbers (the survivors' motion noise, the births'
measurement noise and their velocities), each with its own key. ``jax.random`` evaluates the
Threefry-2x32 hash once per call, and on CPU each evaluation is a rolled loop of five
iterations of about sixteen small kernels: at tracking sizes (2048 particles) the three
loops were half of the kernels a frame runs, each costing a fixed launch overhead whatever
its size. :func:`draw` evaluates the hash once for every request (each element's key and
counter words chosen from its index, inside the hash's fusion: the hash is elementwise in
them) and converts the bits as ``jax.random.normal`` and ``jax.random.uniform`` do, so each
array equals the separate call's bit for bit (tested). The arrays are written to memory once
(:func:`~jaxtrack.control.materialise`), which changes how XLA fuses the arithmetic that
reads them: a tracker's results then differ from the separate calls' at float32 rounding.

:func:`split` likewise gives ``jax.random.split``'s keys from the hash written out: the step's
key splits were each a rolled loop of their own (session 64).

That equality rests on ``jax.random``'s documented bit layout for Threefry keys under
``jax_threefry_partitionable`` (the default since JAX 0.5: the bits of element ``i`` of a
draw hash the 64-bit counter ``i`` with the key, and a 32-bit draw is the xor of the two
output words). For any other key implementation or setting, :func:`draw` makes the separate
``jax.random`` calls instead.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

from jaxtrack.control import materialise

_FLOAT32_ONE_BITS = np.array(1.0, np.float32).view(np.uint32)
_NORMAL_LOW = np.nextafter(np.float32(-1.0), np.float32(0.0))


class Request(NamedTuple):
    """One draw: ``jax.random.normal(key, shape, dtype)`` (``minval`` and ``maxval`` None) or
    ``jax.random.uniform(key, shape, dtype, minval, maxval)``."""

    key: Array
    shape: tuple[int, ...]
    minval: Array | float | None = None
    maxval: Array | float | None = None
    dtype: jnp.dtype = jnp.float32


def normal(key: Array, shape: tuple[int, ...], dtype=jnp.float32) -> Request:
    """A request for ``jax.random.normal(key, shape, dtype)``."""
    return Request(key, tuple(shape), dtype=jnp.dtype(dtype))


def uniform(
    key: Array, shape: tuple[int, ...], minval=0.0, maxval=1.0, dtype=jnp.float32
) -> Request:
    """A request for ``jax.random.uniform(key, shape, dtype, minval, maxval)``."""
    return Request(key, tuple(shape), minval, maxval, jnp.dtype(dtype))


def draw(requests: list[Request], written: bool = True) -> list[Array]:
    """The requested arrays, from one evaluation of the Threefry hash when the keys allow.

    Args:
        requests: from :func:`normal` and :func:`uniform`; keys typed (``jax.random.key``)
            or raw (``jax.random.PRNGKey``), unbatched inside the traced function (``vmap``
            over keys is fine).
        written: write the arrays to memory once (:func:`~jaxtrack.control.materialise`, a
            one-trip loop); False leaves them to XLA, which fuses the hash into their
            consumers: for a handful of numbers (a resampling's single uniform), where the
            loop's own kernels would cost more than recomputing them.

    Returns:
        One array per request, equal to the separate ``jax.random`` call's. Requests of
        float32 with Threefry keys share one evaluation; others (e.g. float64, whose draws
        take 64 bits each) are drawn by ``jax.random``.
    """
    if not all(_merges(r.key) and r.dtype == jnp.float32 for r in requests):
        return [_separate(r) for r in requests]
    sizes = [math.prod(r.shape) for r in requests]
    words = [_key_words(r.key) for r in requests]
    # Element i of a draw hashes the 64-bit counter i (high word 0 below 2^32 elements)
    # with its request's key. Keys and counters are formed per element from one iota
    # (a select per request boundary), inside the hash's fusion: no full-size arrays.
    index = jax.lax.iota(jnp.uint32, sum(sizes))
    key_hi = jnp.full_like(index, words[0][0])
    key_lo = jnp.full_like(index, words[0][1])
    count_lo = index
    start = 0
    for word, size in zip(words[1:], sizes[:-1], strict=True):
        start += size
        later = index >= jnp.uint32(start)
        key_hi = jnp.where(later, word[0], key_hi)
        key_lo = jnp.where(later, word[1], key_lo)
        count_lo = jnp.where(later, index - jnp.uint32(start), count_lo)
    count_hi = jnp.zeros_like(count_lo)
    bits_hi, bits_lo = threefry2x32(key_hi, key_lo, count_hi, count_lo)
    bits = bits_hi ^ bits_lo

    def convert(bits):
        out = []
        start = 0
        for request, size in zip(requests, sizes, strict=True):
            out.append(_convert(bits[start : start + size].reshape(request.shape), request))
            start += size
        return out

    if not written:
        return convert(bits)
    # Written once: fused into their consumers, the normals' inverse error function would
    # run once per state component a draw enters (6 per particle for 4 draws).
    return materialise(convert, bits)


def split(key: Array, num: int = 2) -> Array:
    """``jax.random.split(key, num)``, bit for bit, with the hash written out.

    ``jax.random.split`` evaluates Threefry through JAX's CPU lowering, a rolled loop of five
    iterations of a dozen small kernels, whatever the size: splitting a step's key cost a
    PETS09-S2L1 frame more kernels than its resampling. Here the same words come from
    :func:`threefry2x32`, one small fusion. Under ``jax_threefry_partitionable`` new key
    ``i`` is the hash of the 64-bit counter ``i`` under ``key``; for other key
    implementations or settings this is ``jax.random.split``.

    Args:
        key: a typed (``jax.random.key``) or raw (``jax.random.PRNGKey``) key, unbatched
            inside the traced function (``vmap`` over keys is fine).
        num: keys to make (static).

    Returns:
        ``[num]`` keys of ``key``'s kind.
    """
    if not _merges(key):
        return jax.random.split(key, num)
    words = _key_words(key)
    count_lo = jax.lax.iota(jnp.uint32, num)
    hi, lo = threefry2x32(words[0], words[1], jnp.zeros_like(count_lo), count_lo)
    data = jnp.stack([hi, lo], axis=1)
    if jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key):
        return jax.random.wrap_key_data(data, impl=jax.random.key_impl(key))
    return data


_ROTATIONS = ((13, 15, 26, 6), (17, 29, 16, 24))


def threefry2x32(key_hi: Array, key_lo: Array, count_hi: Array, count_lo: Array):
    """The Threefry-2x32 hash (20 rounds), as ``jax.extend.random.threefry2x32_p``: the same
    output words (tested), written out round by round.

    JAX's CPU lowering is a rolled loop over the five groups of four rounds that carries the
    three key words and rotates them every group: each group is a dozen small kernels, each a
    pass over the full-size words in memory (with a key per element, as when one evaluation
    serves several draws, three more full-size copies per group). Written out, the 20 rounds
    and the key injections are one elementwise fusion whose words stay in registers: 2.4x
    faster than the rolled loop at 4e5 elements on 2 CPU cores (1.8 against 4.4 ms median,
    and faster than ``jax.random.bits``' 2.6 ms), for about 100 more operations to compile.
    """
    keys = (key_hi, key_lo, key_hi ^ key_lo ^ jnp.uint32(0x1BD11BDA))

    def rotate_left(x, r):
        return jax.lax.shift_left(x, jnp.uint32(r)) | jax.lax.shift_right_logical(
            x, jnp.uint32(32 - r)
        )

    x0, x1 = count_hi + keys[0], count_lo + keys[1]
    for group in range(5):
        for rotation in _ROTATIONS[group % 2]:
            x0 = x0 + x1
            x1 = rotate_left(x1, rotation) ^ x0
        x0 = x0 + keys[(group + 1) % 3]
        x1 = x1 + keys[(group + 2) % 3] + jnp.uint32(group + 1)
    return x0, x1


def _convert(bits: Array, request: Request) -> Array:
    """``jax.random.uniform``'s conversion of 32 random bits (and ``normal``'s on top)."""
    mantissa = jax.lax.shift_right_logical(bits, jnp.uint32(32 - 23))
    floats = jax.lax.bitcast_convert_type(
        jax.lax.bitwise_or(mantissa, jnp.uint32(_FLOAT32_ONE_BITS)), jnp.float32
    ) - jnp.float32(1.0)
    if request.minval is None:
        low, high = jnp.float32(_NORMAL_LOW), jnp.float32(1.0)
    else:
        low = jnp.asarray(request.minval, jnp.float32)
        high = jnp.asarray(request.maxval, jnp.float32)
    scaled = scale_uniform(floats, low, high)
    if request.minval is None:
        return jnp.float32(np.sqrt(2)) * jax.lax.erf_inv(scaled)
    return scaled


def scale_uniform(unit: Array, low, high) -> Array:
    """Unit draws in ``[0, 1)`` scaled to ``[low, high)`` with ``jax.random.uniform``'s
    arithmetic (``max(low, u (high - low) + low)``)."""
    return jnp.maximum(low, unit * (high - low) + low)


def _merges(key: Array) -> bool:
    if not jax.config.jax_threefry_partitionable or (key.ndim != 0 and key.shape != (2,)):
        return False
    if jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key):
        return key.ndim == 0 and str(jax.random.key_impl(key)) == "threefry2x32"
    return key.dtype == jnp.uint32 and jax.config.jax_default_prng_impl == "threefry2x32"


def _key_words(key: Array) -> Array:
    if jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key):
        return jax.random.key_data(key)
    return key


def _separate(request: Request) -> Array:
    if request.minval is None:
        return jax.random.normal(request.key, request.shape, request.dtype)
    return jax.random.uniform(
        request.key, request.shape, request.dtype, request.minval, request.maxval
    )
