"""The functional filter interface and the one sequence runner, :func:`run` (DESIGN.md)."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

from jaxtrack.context.intensity import DEFAULT_FRAME_RATE
from jaxtrack.errors import InputError
from jaxtrack.filters import draws
from jaxtrack.types import PAD_BOX, Detections, FrameInputs, SequenceInfo


class Filter(NamedTuple):
    """A filter as a pair of pure functions; static sizes live in their closure.

    Attributes:
        init: ``(key, params) -> state``.
        step: ``(key, state, params, inputs_t) -> (state, info)``, where ``inputs_t`` is one
            frame of :class:`~jaxtrack.types.Detections`, or, for a filter that looks at the
            images, of :class:`~jaxtrack.types.FrameInputs` (detections and frame).
    """

    init: Callable[[Array, Any], Any]
    step: Callable[[Array, Any, Any, Any], tuple[Any, Any]]


#: A per-frame output: ``(state_t, info_t, frame_index) -> output_t`` (``state_t`` the carry
#: after frame ``t``); :func:`run` stacks it over the frames instead of the infos.
FrameOutput = Callable[[Any, Any, Array], Any]

#: The images of a chunked run (``frames=`` of :func:`run`): ``frames(start, stop)`` returns
#: those of the run's frames ``start..stop-1`` (0-based, as the detections) as RGB ``uint8``
#: ``[stop - start, height, width, 3]``. The runner asks for each frame once, in order, and
#: is done with a chunk's array (which JAX may read without a copy while the chunk runs)
#: when it asks for the chunk after next: a source may then refill that array.
FrameSource = Callable[[int, int], np.ndarray]
#: Byte alignment of the frame arrays a chunked run is given (:func:`aligned_frames`): XLA's
#: CPU client uses a NumPy argument's memory in place when it is 64-byte aligned, and copies
#: it into fresh memory otherwise (0.6-0.8 ms a 768x576 frame in place against 1.9 ms with
#: the copy, for the no-op filter of ``benchmarks/stream_speed.py``).
FRAME_ALIGNMENT = 64


#: Smallest detection capacity of a chunk with ``fit_capacity`` (a power of two).
MIN_CAPACITY = 16
#: A chunk of crowded frames whose ``frames x capacity`` is at most this compiles with XLA's
#: backend optimisation off: about half the compile time, several times the run time per
#: frame, a gain for a few crowded frames.
QUICK_COMPILE_WORK = 8192
#: With ``fit_capacity``, a frame is *crowded* when its detections need more than this many
#: times the capacity of the sequence's median frame; crowded frames run in chunks of their own.
CROWDED_FACTOR = 4


class Chunk(NamedTuple):
    """One compiled call of a chunked :func:`run`: frames ``start..stop-1`` at ``capacity``;
    ``crowded`` for a chunk of crowded frames."""

    start: int
    stop: int
    capacity: int
    crowded: bool = False


def capacity_for(count: float) -> int:
    """The detection capacity for ``count`` detections: a power of two, at least
    :data:`MIN_CAPACITY` (so that capacities, and compiles, come in few sizes)."""
    return max(MIN_CAPACITY, 1 << max(0, math.ceil(math.log2(max(count, 1)))))


def plan_chunks(counts: np.ndarray, chunk_frames: int) -> list[Chunk]:
    """How :func:`run` with ``fit_capacity`` splits a sequence into compiled calls.

    The capacity depends on the sequence's own detection counts only. Regular frames use
    one capacity, :func:`capacity_for` of the largest regular count, in chunks of
    ``chunk_frames``. A frame is crowded when its count exceeds :data:`CROWDED_FACTOR` times
    the capacity of the median count; each run of consecutive crowded frames gets chunks of
    its own, at the capacity its largest count needs. One crowded frame thus costs one
    frame at its capacity (and one compile per new capacity), not a whole run padded to it.

    Args:
        counts: detections per frame.
        chunk_frames: frames per chunk at most (> 0).

    Returns:
        The chunks, in frame order, covering every frame once.
    """
    counts = np.asarray(counts, np.int64)
    if counts.size == 0:
        return []
    crowded = counts > CROWDED_FACTOR * capacity_for(float(np.median(counts)))
    regular = capacity_for(int(counts[~crowded].max(initial=0)))
    chunks = []
    edges = np.flatnonzero(np.diff(crowded.astype(np.int8))) + 1
    for start, stop in zip([0, *edges.tolist()], [*edges.tolist(), counts.size], strict=True):
        for first in range(start, stop, chunk_frames):
            last = min(first + chunk_frames, stop)
            capacity = capacity_for(int(counts[first:last].max())) if crowded[first] else regular
            chunks.append(Chunk(first, last, capacity, bool(crowded[first])))
    return chunks


def fit_detections(inputs: Detections) -> Detections:
    """Detections brought to the capacity a ``fit_capacity`` run gives the sequence.

    Each frame's real detections move to its first slots and the slots are cut (or padded)
    to the largest capacity of :func:`plan_chunks`. An unchunked run over these detections
    (e.g. a vmapped sweep) then gives what the chunked ``fit_capacity`` run gives whenever
    the sequence has no crowded frames (one capacity for every chunk).
    """
    inputs = _compact(jax.tree.map(np.asarray, inputs))
    counts = inputs.mask.sum(axis=1)
    capacity = max(chunk.capacity for chunk in plan_chunks(counts, max(1, counts.size)))
    return _fit_slots(inputs, capacity)


def run(
    filt: Filter,
    key: Array,
    params: Any,
    inputs: Detections,
    *,
    checkpoint: bool = False,
    chunk_frames: int | None = None,
    fit_capacity: bool = False,
    frame_output: FrameOutput | None = None,
    frames: FrameSource | None = None,
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
    on the :class:`Filter`) and called from a host loop with the state carried between
    calls. A chunk with fewer frames (the last one, or a crowded run) is padded with frames
    that are skipped (``lax.cond``: the state passes through unchanged, their outputs are
    dropped), so sequences of any length share one compile. Not for ``jax.grad`` or
    ``jax.vmap`` (a host loop).

    With ``fit_capacity`` as well, each chunk's detections are cut to the capacity that
    :func:`plan_chunks` gives it (from the sequence's own counts: a power of two, crowded
    frames in chunks of their own), instead of the ``max_detections`` of ``inputs``. The
    result then depends on the sequence only, not on how much ``inputs`` were padded (e.g. to
    share an array with other sequences), and a crowded frame does not slow every frame.
    Per-frame outputs whose shapes follow the capacity (e.g. the PHD tracker's estimates and
    tracks) are padded with zeros (``False`` in masks) to the largest chunk's.

    A filter that looks at the images takes :class:`~jaxtrack.types.FrameInputs` per frame
    (DESIGN.md, "Frames under jit"). Unchunked, ``inputs`` are then ``FrameInputs`` stacked
    over frames (the images in memory: short clips, tests). Chunked, ``inputs`` stay the
    detections and ``frames`` (a :data:`FrameSource`) gives each chunk's images just before
    the chunk is called; the frames padding a short chunk are zeros (and skipped). The loop
    hands a chunk to JAX (asynchronous dispatch) and asks for the next chunk's frames
    before it waits for the previous chunk's outputs, so a source that decodes ahead in a
    background thread (:class:`~jaxtrack.io.frame_stream.FrameStream`) decodes while the
    filter runs, and no more than a few chunks of images need exist at once. The compile
    is per frame size too.

    Args:
        filt: the filter (e.g. :func:`~jaxtrack.filters.phd.phd_filter`).
        key: PRNG key.
        params: the filter's parameter PyTree.
        inputs: padded detections ``[num_frames, max_detections]``, or (unchunked)
            :class:`~jaxtrack.types.FrameInputs` stacked over ``num_frames``.
        checkpoint: wrap each frame in ``jax.checkpoint``, so that a backward pass stores
            one carry per frame and recomputes the frame's intermediates.
        chunk_frames: frames per compiled call (> 0), or None for one scan.
        fit_capacity: with ``chunk_frames``, fit each chunk's detection capacity to its
            frames (see above).
        frame_output: what to stack per frame instead of the infos (e.g. a per-frame loss
            of the posterior state, which then need not be stored for every frame).
        frames: with ``chunk_frames``, the images of the frames (see above); the filter
            then gets ``FrameInputs(detections_t, frame_t)``.

    Returns:
        The final state and the per-frame outputs stacked over ``num_frames`` (NumPy arrays
        when chunked).

    Raises:
        ValueError: ``chunk_frames`` not positive; ``fit_capacity`` or ``frames`` without
            it; chunked ``inputs`` that are not :class:`~jaxtrack.types.Detections`.
        InputError: ``frames`` returned images of the wrong count, dtype or shape, or of
            another size than the first chunk's.
    """
    if chunk_frames is not None and chunk_frames <= 0:
        raise ValueError(f"chunk_frames must be positive, got {chunk_frames}")
    if fit_capacity and chunk_frames is None:
        raise ValueError("fit_capacity needs chunk_frames (a host loop over chunks)")
    if frames is not None and chunk_frames is None:
        raise ValueError("frames need chunk_frames (a host loop over chunks)")
    if chunk_frames is not None and not isinstance(inputs, Detections):
        raise ValueError("a chunked run takes Detections; give its images as frames=")
    key_init, key_frames = draws.split(key)
    num_frames = int(np.shape(jax.tree.leaves(inputs)[0])[0])
    frame_keys = draws.split(key_frames, num_frames)
    if chunk_frames is not None:
        return _run_chunks(
            filt,
            key_init,
            frame_keys,
            params,
            inputs,
            frames,
            chunk_frames,
            fit_capacity,
            checkpoint,
            frame_output,
        )
    scan = _frame_scan(filt, checkpoint, frame_output)
    return scan(filt.init(key_init, params), params, frame_keys, inputs, jnp.arange(num_frames))


def _frame_body(filt: Filter, params: Any, checkpoint: bool, frame_output: FrameOutput | None):
    """The scan body ``(state, (frame_key, inputs_t, index)) -> (state, output)``."""

    def body(state, xs):
        frame_key, inputs_t, index = xs
        new_state, info = filt.step(frame_key, state, params, inputs_t)
        output = info if frame_output is None else frame_output(new_state, info, index)
        return new_state, output

    return jax.checkpoint(body) if checkpoint else body


def _frame_scan(
    filt: Filter, checkpoint: bool, frame_output: FrameOutput | None
) -> Callable[..., tuple[Any, Any]]:
    """The scan ``(state, params, frame_keys, inputs, frame_indices) -> (state, outputs)``."""

    def scan(state, params, frame_keys, inputs, frame_indices):
        body = _frame_body(filt, params, checkpoint, frame_output)
        return jax.lax.scan(body, state, (frame_keys, inputs, frame_indices))

    return scan


def _chunk_scan(
    filt: Filter, checkpoint: bool, frame_output: FrameOutput | None
) -> Callable[..., tuple[Any, Any]]:
    """:func:`_frame_scan` with a per-frame ``valid`` flag; invalid frames are skipped
    (``lax.cond``, so a skipped frame costs nothing): the state passes through unchanged and
    the outputs are zeros."""

    def scan(state, params, frame_keys, inputs, frame_indices, valid):
        body = _frame_body(filt, params, checkpoint, frame_output)

        def frame(state, xs):
            *frame_xs, valid_t = xs

            def skip(state):
                new_state, output = jax.eval_shape(body, state, frame_xs)
                state = jax.tree.map(lambda x, s: x.astype(s.dtype), state, new_state)
                return state, jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), output)

            return jax.lax.cond(valid_t, lambda s: body(s, frame_xs), skip, state)

        return jax.lax.scan(frame, state, (frame_keys, inputs, frame_indices, valid))

    return scan


def _plan(inputs: Detections, chunk_frames: int, fit: bool) -> tuple[Detections, list[Chunk]]:
    """The host detections of a chunked run (compacted with ``fit``) and its chunks."""
    inputs = jax.tree.map(np.asarray, inputs)
    num_frames, slots = inputs.mask.shape
    if num_frames == 0:
        raise ValueError("a chunked run needs at least one frame")
    if fit:
        inputs = _compact(inputs)
        return inputs, plan_chunks(inputs.mask.sum(axis=1), chunk_frames)
    chunks = [
        Chunk(start, min(start + chunk_frames, num_frames), slots)
        for start in range(0, num_frames, chunk_frames)
    ]
    return inputs, chunks


def _chunk_calls(inputs: Detections, chunks: list[Chunk], chunk_frames: int, frames):
    """Per chunk: ``(chunk, window, chunk_inputs, indices, valid, quick)``, the arguments of
    its compiled call (``window`` indexes the frame keys), the images read from ``frames``
    (if any) just before the chunk is yielded; ``quick`` for a small crowded chunk."""
    num_frames = inputs.mask.shape[0]
    frame_size = None
    for chunk in chunks:
        indices = np.arange(chunk.start, chunk.start + chunk_frames)
        window = np.minimum(indices, max(num_frames - 1, 0))
        chunk_inputs = _fit_slots(jax.tree.map(lambda x, w=window: x[w], inputs), chunk.capacity)
        valid = indices < chunk.stop
        chunk_inputs.mask[~valid] = False
        if frames is not None:
            images, frame_size = _chunk_frames(frames, chunk, chunk_frames, frame_size)
            chunk_inputs = FrameInputs(chunk_inputs, images)
        quick = chunk.crowded and (chunk.stop - chunk.start) * chunk.capacity <= QUICK_COMPILE_WORK
        yield chunk, window, chunk_inputs, indices, valid, quick


def _run_chunks(filt, key_init, frame_keys, params, inputs, frames, chunk_frames, fit, *options):
    """:func:`run` with ``chunk_frames``: a host loop over the cached, jitted chunk scan.

    Chunk ``k``'s outputs are brought to the host after chunk ``k + 1`` is dispatched, so
    that chunk ``k + 1``'s inputs (its frames) are prepared while chunk ``k`` runs, and
    chunk ``k`` has finished when chunk ``k + 2``'s frames are asked for (:data:`FrameSource`)."""
    inputs, chunks = _plan(inputs, chunk_frames, fit)
    init, scan_chunk, quick_scan_chunk = _chunk_functions(filt, *options)
    state = init(key_init, params)
    outputs, running = [], None
    for chunk, window, chunk_inputs, indices, valid, quick in _chunk_calls(
        inputs, chunks, chunk_frames, frames
    ):
        state, output = (quick_scan_chunk if quick else scan_chunk)(
            state, params, frame_keys[window], chunk_inputs, indices, valid
        )
        if running is not None:
            outputs.append(_host_outputs(*running))
        running = (state, output, chunk.stop - chunk.start)
    outputs.append(_host_outputs(*running))
    return state, _concatenate(outputs)


def run_batch(
    filt: Filter,
    keys: Array,
    params: Any,
    inputs: Detections,
    *,
    chunk_frames: int,
    group_size: int = 16,
    fit_capacity: bool = True,
    checkpoint: bool = False,
    frame_output: FrameOutput | None = None,
    frames: FrameSource | None = None,
    progress: Callable[[int], None] | None = None,
) -> Any:
    """A chunked :func:`run` of many configurations at once, each frame chunk read once.

    Configuration ``b`` (``keys[b]``, the ``b``-th entry of every leaf of ``params``) gives
    what ``run(filt, keys[b], params_b, inputs, chunk_frames=chunk_frames,
    fit_capacity=fit_capacity, frames=frames)`` gives (the same keys, chunks and capacities;
    batched and single XLA programs may round differently in float32). The host loop runs
    over the frame chunks; inside it, the configurations go ``group_size`` at a time through
    one ``jit(vmap(chunk scan))`` (the last group padded by repeating its last
    configuration, so every group shares one compile), each group's state carried to the
    next frame chunk. A chunk's images (``frames``) are thus read once and shared by every
    configuration: a sweep of a tracker that looks at the images decodes its video once.
    One device (the default one).

    Args:
        filt: the filter.
        keys: one PRNG key per configuration, ``[batch]`` typed keys or ``[batch, 2]`` raw.
        params: the parameter PyTree with a leading ``batch`` axis on every leaf.
        inputs: padded detections ``[num_frames, max_detections]``, shared by all.
        chunk_frames: frames per compiled call (> 0).
        group_size: configurations per compiled call (> 0).
        fit_capacity, checkpoint, frame_output, frames: as :func:`run`.
        progress: called with the number of frames done after each frame chunk.

    Returns:
        The per-frame outputs, stacked as ``[batch, num_frames, ...]`` (NumPy arrays).

    Raises:
        ValueError: a chunk length or group size that is not positive, no frames, or
            ``inputs`` that are not :class:`~jaxtrack.types.Detections`.
        InputError: keys and parameters of different batch sizes; bad images (as :func:`run`).
    """
    if chunk_frames <= 0 or group_size <= 0:
        raise ValueError(
            f"chunk_frames and group_size must be positive, got {chunk_frames}, {group_size}"
        )
    if not isinstance(inputs, Detections):
        raise ValueError("run_batch takes Detections; give the images as frames=")
    batch = int(np.shape(keys)[0])
    sizes = {int(np.shape(leaf)[0]) for leaf in jax.tree.leaves(params)}
    if sizes != {batch}:
        raise InputError(f"{batch} keys but parameters with batch sizes {sorted(sizes)}")
    num_frames = int(np.shape(inputs.mask)[0])
    key_init, key_frames = jax.vmap(draws.split, out_axes=1)(keys)
    frame_keys = jax.vmap(lambda k: draws.split(k, num_frames))(key_frames)
    group_size = min(group_size, batch)
    groups = [
        np.minimum(np.arange(start, start + group_size), batch - 1)
        for start in range(0, batch, group_size)
    ]
    params = jax.tree.map(np.asarray, params)
    group_params = [jax.tree.map(lambda x, g=g: x[g], params) for g in groups]
    inputs, chunks = _plan(inputs, chunk_frames, fit_capacity)
    init, scan_chunk, quick_scan_chunk = _chunk_functions(filt, checkpoint, frame_output, True)
    states = [init(key_init[g], p) for g, p in zip(groups, group_params, strict=True)]
    outputs: list[list[Any]] = [[] for _ in groups]
    running: list[Any] = [None] * len(groups)
    for chunk, window, chunk_inputs, indices, valid, quick in _chunk_calls(
        inputs, chunks, chunk_frames, frames
    ):
        for k, (g, p) in enumerate(zip(groups, group_params, strict=True)):
            states[k], output = (quick_scan_chunk if quick else scan_chunk)(
                states[k], p, frame_keys[g][:, window], chunk_inputs, indices, valid
            )
            if running[k] is not None:
                outputs[k].append(_host_outputs(*running[k], axis=1))
            running[k] = (states[k], output, chunk.stop - chunk.start)
        if progress is not None:
            progress(chunk.stop - chunk.start)
    for k in range(len(groups)):
        outputs[k].append(_host_outputs(*running[k], axis=1))
    joined = [_concatenate(parts, axis=1) for parts in outputs]
    stacked = _concatenate(joined, axis=0)
    return jax.tree.map(lambda x: x[:batch], stacked)


def _host_outputs(state: Any, output: Any, used: int, axis: int = 0) -> Any:
    """A chunk's outputs on the host, its ``used`` real frames (along ``axis``) only, once
    the chunk has finished (its final ``state`` is ready)."""
    jax.block_until_ready(state)
    return jax.tree.map(lambda x: np.take(np.asarray(x), np.arange(used), axis=axis), output)


def _chunk_frames(
    frames: FrameSource, chunk: Chunk, chunk_frames: int, size: tuple[int, int] | None
) -> tuple[np.ndarray, tuple[int, int]]:
    """A chunk's images from ``frames``, padded with zero frames to ``chunk_frames``, and
    their ``(height, width)``: the first chunk's, which every chunk must keep.

    Raises:
        InputError: images of the wrong count, dtype or shape.
    """
    used = chunk.stop - chunk.start
    images = np.asarray(frames(chunk.start, chunk.stop))
    first = size is None
    size = tuple(images.shape[1:3]) if first else size
    if images.dtype != np.uint8 or images.shape != (used, *size, 3):
        raise InputError(
            f"frames({chunk.start}, {chunk.stop}) gave {images.dtype} images of shape "
            f"{images.shape}; expected uint8 [{used}, height, width, 3]"
            + ("" if first else f" with the first chunk's height and width {size}")
        )
    if used < chunk_frames:
        padded = aligned_frames(chunk_frames, *size)
        padded[:used] = images
        padded[used:] = 0
        images = padded
    return images, size


def aligned_frames(count: int, height: int, width: int) -> np.ndarray:
    """An uninitialised ``uint8`` array ``[count, height, width, 3]`` whose data starts on an
    :data:`FRAME_ALIGNMENT`-byte boundary, so that a chunked run reads it in place."""
    size = count * height * width * 3
    raw = np.empty(size + FRAME_ALIGNMENT, np.uint8)
    offset = -raw.ctypes.data % FRAME_ALIGNMENT
    return raw[offset : offset + size].reshape(count, height, width, 3)


def _compact(inputs: Detections) -> Detections:
    """The detections with each frame's real ones in its first slots (order kept)."""
    order = np.argsort(~inputs.mask, axis=1, kind="stable")
    return jax.tree.map(
        lambda x: np.take_along_axis(x, order.reshape(order.shape + (1,) * (x.ndim - 2)), 1),
        inputs,
    )


def _fit_slots(inputs: Detections, capacity: int) -> Detections:
    """Detections ``[T, D]`` cut, or padded with empty slots, to ``[T, capacity]``."""
    extra = capacity - inputs.mask.shape[1]
    if extra <= 0:
        return jax.tree.map(lambda x: x[:, :capacity], inputs)
    boxes = np.concatenate(
        [
            inputs.boxes,
            np.broadcast_to(
                np.asarray(PAD_BOX, inputs.boxes.dtype), (*inputs.mask.shape[:1], extra, 4)
            ),
        ],
        axis=1,
    )
    return Detections(
        boxes=boxes,
        scores=np.pad(inputs.scores, ((0, 0), (0, extra))),
        mask=np.pad(inputs.mask, ((0, 0), (0, extra))),
    )


def _concatenate(outputs: list[Any], axis: int = 0) -> Any:
    """Per-chunk outputs concatenated along ``axis`` (frames); the other axes that differ
    between chunks (those that follow the detection capacity) are padded with zeros to the
    largest."""

    def join(*xs):
        shape = np.max([x.shape for x in xs], axis=0)
        padded = [
            np.pad(
                x,
                [
                    (0, 0) if k == axis else (0, int(n - m))
                    for k, (n, m) in enumerate(zip(shape, x.shape, strict=True))
                ],
            )
            for x in xs
        ]
        return np.concatenate(padded, axis=axis)

    return jax.tree.map(join, *outputs)


@functools.lru_cache(maxsize=16)
def _chunk_functions(
    filt: Filter, checkpoint: bool, frame_output: FrameOutput | None, batched: bool = False
):
    """Jitted ``init`` and chunk scan of a filter, and the chunk scan compiled quickly
    (:data:`QUICK_COMPILE_WORK`); cached, so that calls share compiles. ``batched``: all
    three vmapped over the keys, parameters and state (the chunk's inputs shared)."""
    scan = _chunk_scan(filt, checkpoint, frame_output)
    init = filt.init
    if batched:
        scan = jax.vmap(scan, in_axes=(0, 0, 0, None, None, None))
        init = jax.vmap(init)
    quick = jax.jit(scan, compiler_options={"xla_backend_optimization_level": 0})
    return jax.jit(init), jax.jit(scan), quick


def frame_rate(info: SequenceInfo) -> float:
    """The sequence's frame rate (:data:`~jaxtrack.context.intensity.DEFAULT_FRAME_RATE`, 25,
    when ``seqinfo.ini`` has none)."""
    return float(info.frame_rate or DEFAULT_FRAME_RATE)
