"""The functional filter interface and the sequence runner (DESIGN.md)."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import numpy as np
from jaxtyping import Array

from jaxtrack.types import Detections


class Filter(NamedTuple):
    """A filter as a pair of pure functions; static sizes live in their closure.

    Attributes:
        init: ``(key, params) -> state``.
        step: ``(key, state, params, detections_t) -> (state, info)``, where
            ``detections_t`` is one frame of :class:`~jaxtrack.types.Detections`.
    """

    init: Callable[[Array, Any], Any]
    step: Callable[[Array, Any, Any, Detections], tuple[Any, Any]]


def run(filt: Filter, key: Array, params: Any, detections: Detections) -> tuple[Any, Any]:
    """Runs a filter over a whole sequence with ``lax.scan``.

    Pure in all of its array arguments, so ``jax.jit``, ``jax.vmap`` (over keys, over batches of
    params, over sequences of equal shape) and ``jax.grad`` (w.r.t. params) apply to it, e.g.
    ``jax.vmap(lambda p: run(filt, key, p, detections))(batched_params)``.

    Args:
        filt: the filter (e.g. :func:`~jaxtrack.filters.phd.phd_filter`).
        key: PRNG key; split into the init key and one key per frame.
        params: the filter's parameter PyTree.
        detections: padded detections ``[num_frames, max_detections]``.

    Returns:
        The final state and the per-frame infos stacked over ``num_frames``.
    """
    key_init, key_frames = jax.random.split(key)
    state = filt.init(key_init, params)
    frame_keys = jax.random.split(key_frames, detections.mask.shape[0])

    def body(state, inputs):
        frame_key, detections_t = inputs
        return filt.step(frame_key, state, params, detections_t)

    return jax.lax.scan(body, state, (frame_keys, detections))


def run_chunked(
    filt: Filter, key: Array, params: Any, detections: Detections, chunk_frames: int = 128
) -> tuple[Any, Any]:
    """:func:`run` in chunks of ``chunk_frames`` frames: one compile for any sequence length.

    The same computation as :func:`run` (same per-frame keys, same results), but the scan is
    compiled for a chunk and called ``ceil(num_frames / chunk_frames)`` times with the state
    carried between calls, the last chunk padded with empty frames (whose outputs are
    dropped). Sequences of different lengths (and the same detection capacity and parameter
    shapes) then share one compile, at the cost of at most ``chunk_frames - 1`` wasted frames.
    Not for ``jax.grad`` or ``jax.vmap`` (it is a host-side loop); use :func:`run` there.

    Args:
        filt: the filter.
        key: PRNG key, used as by :func:`run`.
        params: the filter's parameter PyTree.
        detections: padded detections ``[num_frames, max_detections]``.
        chunk_frames: frames per compiled call (> 0).

    Returns:
        The state after the last chunk (after the padding frames, which only predict: use
        :func:`run` for the exact final state) and the per-frame infos stacked over
        ``num_frames`` (NumPy arrays).
    """
    if chunk_frames <= 0:
        raise ValueError(f"chunk_frames must be positive, got {chunk_frames}")
    num_frames = int(np.shape(detections.mask)[0])
    num_chunks = max(1, -(-num_frames // chunk_frames))
    padded = num_chunks * chunk_frames
    key_init, key_frames = jax.random.split(key)
    frame_keys = jax.random.split(key_frames, num_frames)
    if padded > num_frames:
        extra = jax.random.split(jax.random.fold_in(key_frames, 1), padded - num_frames)
        frame_keys = jax.numpy.concatenate([frame_keys, extra])

    # Padding frames repeat the last frame with every detection masked out (no detections).
    inputs = jax.tree.map(
        lambda x: np.concatenate([x, np.repeat(x[-1:], padded - num_frames, axis=0)]),
        jax.tree.map(np.asarray, detections),
    )
    inputs.mask[num_frames:] = False
    init, scan_chunk = _chunk_functions(filt)
    state = init(key_init, params)
    infos = []
    for c in range(num_chunks):
        window = slice(c * chunk_frames, (c + 1) * chunk_frames)
        state, info = scan_chunk(
            state, params, frame_keys[window], jax.tree.map(lambda x, w=window: x[w], inputs)
        )
        infos.append(info)
    stacked = jax.tree.map(lambda *xs: np.concatenate([np.asarray(x) for x in xs]), *infos)
    return state, jax.tree.map(lambda x: x[:num_frames], stacked)


@functools.lru_cache(maxsize=16)
def _chunk_functions(filt: Filter):
    """Jitted ``init`` and chunk scan of a filter (cached, so that calls share compiles)."""

    def scan_chunk(state, params, frame_keys, detections):
        def body(state, inputs):
            frame_key, detections_t = inputs
            return filt.step(frame_key, state, params, detections_t)

        return jax.lax.scan(body, state, (frame_keys, detections))

    return jax.jit(filt.init), jax.jit(scan_chunk)
