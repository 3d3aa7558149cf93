"""The functional filter interface and the one sequence runner, :func:`run` (DESIGN.md)."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
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


#: A per-frame output: ``(state_t, info_t, frame_index) -> output_t`` (``state_t`` the carry
#: after frame ``t``); :func:`run` stacks it over the frames instead of the infos.
FrameOutput = Callable[[Any, Any, Array], Any]


def run(
    filt: Filter,
    key: Array,
    params: Any,
    inputs: Detections,
    *,
    checkpoint: bool = False,
    chunk_frames: int | None = None,
    frame_output: FrameOutput | None = None,
) -> tuple[Any, Any]:
    """Runs a filter over a sequence with ``lax.scan``: the one scan driver.

    The key splits into the init key and one key per frame (``jax.random.split(key_frames,
    num_frames)``), whatever the options, so every option gives the same per-frame results.

    Unchunked (default), it is pure in all of its array arguments, so ``jax.jit``,
    ``jax.vmap`` (over keys, over batches of params, over sequences of equal shape) and
    ``jax.grad`` (w.r.t. params) apply to it, e.g.
    ``jax.vmap(lambda p: run(filt, key, p, detections))(batched_params)``.

    With ``chunk_frames``, the scan is compiled for a chunk of that many frames (once per
    filter, chunk length, option set, parameter and detection shapes: the compile is cached
    on the :class:`Filter`) and called ``ceil(num_frames / chunk_frames)`` times from a host
    loop with the state carried between calls, the last chunk padded with empty frames (the
    last frame repeated with every detection masked out; their outputs are dropped).
    Sequences of different lengths then share one compile, at the cost of at most
    ``chunk_frames - 1`` wasted frames. Not for ``jax.grad`` or ``jax.vmap`` (a host loop).

    Args:
        filt: the filter (e.g. :func:`~jaxtrack.filters.phd.phd_filter`).
        key: PRNG key.
        params: the filter's parameter PyTree.
        inputs: padded detections ``[num_frames, max_detections]``.
        checkpoint: wrap each frame in ``jax.checkpoint``, so that a backward pass stores
            one carry per frame and recomputes the frame's intermediates.
        chunk_frames: frames per compiled call (> 0), or None for one scan.
        frame_output: what to stack per frame instead of the infos (e.g. a per-frame loss
            of the posterior state, which then need not be stored for every frame).

    Returns:
        The final state (when chunked: after the padding frames, which only predict) and the
        per-frame outputs stacked over ``num_frames`` (NumPy arrays when chunked).

    Raises:
        ValueError: ``chunk_frames`` not positive.
    """
    if chunk_frames is not None and chunk_frames <= 0:
        raise ValueError(f"chunk_frames must be positive, got {chunk_frames}")
    key_init, key_frames = jax.random.split(key)
    num_frames = int(np.shape(inputs.mask)[0])
    frame_keys = jax.random.split(key_frames, num_frames)
    if chunk_frames is not None:
        return _run_chunks(
            filt,
            key_init,
            key_frames,
            frame_keys,
            params,
            inputs,
            chunk_frames,
            checkpoint,
            frame_output,
        )
    scan = _frame_scan(filt, checkpoint, frame_output)
    return scan(filt.init(key_init, params), params, frame_keys, inputs, jnp.arange(num_frames))


def _frame_scan(
    filt: Filter, checkpoint: bool, frame_output: FrameOutput | None
) -> Callable[..., tuple[Any, Any]]:
    """The scan ``(state, params, frame_keys, inputs, frame_indices) -> (state, outputs)``."""

    def scan(state, params, frame_keys, inputs, frame_indices):
        def body(state, xs):
            frame_key, inputs_t, index = xs
            new_state, info = filt.step(frame_key, state, params, inputs_t)
            output = info if frame_output is None else frame_output(new_state, info, index)
            return new_state, output

        if checkpoint:
            body = jax.checkpoint(body)
        return jax.lax.scan(body, state, (frame_keys, inputs, frame_indices))

    return scan


def _run_chunks(filt, key_init, key_frames, frame_keys, params, inputs, chunk_frames, *options):
    """:func:`run` with ``chunk_frames``: a host loop over the cached, jitted chunk scan."""
    num_frames = frame_keys.shape[0]
    num_chunks = max(1, -(-num_frames // chunk_frames))
    padded = num_chunks * chunk_frames
    if padded > num_frames:
        extra = jax.random.split(jax.random.fold_in(key_frames, 1), padded - num_frames)
        frame_keys = jnp.concatenate([frame_keys, extra])
    # Padding frames repeat the last frame with every detection masked out (no detections).
    padded_inputs = jax.tree.map(
        lambda x: np.concatenate([x, np.repeat(x[-1:], padded - num_frames, axis=0)]),
        jax.tree.map(np.asarray, inputs),
    )
    padded_inputs.mask[num_frames:] = False
    init, scan_chunk = _chunk_functions(filt, *options)
    state = init(key_init, params)
    outputs = []
    for c in range(num_chunks):
        window = slice(c * chunk_frames, (c + 1) * chunk_frames)
        state, output = scan_chunk(
            state,
            params,
            frame_keys[window],
            jax.tree.map(lambda x, w=window: x[w], padded_inputs),
            np.arange(window.start, window.stop),
        )
        outputs.append(output)
    stacked = jax.tree.map(lambda *xs: np.concatenate([np.asarray(x) for x in xs]), *outputs)
    return state, jax.tree.map(lambda x: x[:num_frames], stacked)


@functools.lru_cache(maxsize=16)
def _chunk_functions(filt: Filter, checkpoint: bool, frame_output: FrameOutput | None):
    """Jitted ``init`` and chunk scan of a filter (cached, so that calls share compiles)."""
    return jax.jit(filt.init), jax.jit(_frame_scan(filt, checkpoint, frame_output))
