"""The functional filter interface and the sequence runner (DESIGN.md)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
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
