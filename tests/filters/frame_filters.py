"""Test-only filters that look at the images: the mean colour under each detection, and a
checksum of the frame.

The mean-colour filter (``MEAN_COLOUR``) steps on :class:`~jaxtrack.types.FrameInputs` like
the appearance trackers will, and its outputs are simple enough to check against frames read
directly: each detection's mean RGB over the pixels its rounded box covers (an integral
image under jit; NumPy slices in the oracle), a score ``colour . channel_weights`` (so params
enter the step), a per-frame uniform draw from the frame's key (so the per-frame keys can be
compared across chunkings) and the frame's checksum. As a registered tracker
(``MEAN_COLOUR_ENTRY``) it reports each detection as a track whose id is its slot + 1 and
whose score is its mean colour.

``CHECKSUM`` only adds up each frame's pixel values (the frame is really read, nothing else
is done): the cheapest filter a streamed run can have. :func:`random_video` and
:func:`random_detections` make small clips for them.
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.configs import MAX_GAP, OUTPUT, TrackerConfig, setting
from jaxtrack.filters.base import Filter
from jaxtrack.filters.registry import TrackerEntry
from jaxtrack.parameters import frozen_properties
from jaxtrack.resources import MemoryEstimate
from jaxtrack.types import PAD_BOX, Detections, FrameInputs, Tracks


class MeanColourParams(NamedTuple):
    channel_weights: jax.Array  # [3]: score = mean colour . channel_weights


class MeanColourState(NamedTuple):
    frames_seen: jax.Array  # int32: frames stepped on (padded frames are skipped)
    checksum: jax.Array  # uint32: sum of every pixel value seen (wrapping)


class MeanColourInfo(NamedTuple):
    colours: jax.Array  # [max_detections, 3] mean RGB under each box (0 in padded slots)
    draw: jax.Array  # uniform draw from the frame's key
    checksum: jax.Array  # uint32 sum of the frame's pixel values
    tracks: Tracks
    candidates: Tracks


def pixel_span(x, w, size):
    """The pixels ``[first, stop)`` a box side covers: its rounded ends, clipped to the image."""
    first = jnp.clip(jnp.round(x), 0, size)
    stop = jnp.clip(jnp.round(x + w), 0, size)
    return first.astype(jnp.int32), stop.astype(jnp.int32)


def mean_colour(integral: jax.Array, box: jax.Array) -> jax.Array:
    """Mean RGB over the rounded box, from the integral image ``[H + 1, W + 1, 3]``."""
    height, width = integral.shape[0] - 1, integral.shape[1] - 1
    c0, c1 = pixel_span(box[0], box[2], width)
    r0, r1 = pixel_span(box[1], box[3], height)
    total = integral[r1, c1] - integral[r0, c1] - integral[r1, c0] + integral[r0, c0]
    count = jnp.maximum((r1 - r0) * (c1 - c0), 1)
    return total.astype(jnp.float32) / count.astype(jnp.float32)


def init(key, params):
    del key, params
    return MeanColourState(jnp.zeros((), jnp.int32), jnp.zeros((), jnp.uint32))


def step(key, state, params, inputs: FrameInputs):
    frame, detections = inputs.frame, inputs.detections
    integral = jnp.pad(
        jnp.cumsum(jnp.cumsum(frame.astype(jnp.int32), axis=0), axis=1), ((1, 0), (1, 0), (0, 0))
    )
    colours = jax.vmap(mean_colour, (None, 0))(integral, detections.boxes)
    colours = jnp.where(detections.mask[:, None], colours, 0.0)
    checksum = jnp.sum(frame, dtype=jnp.uint32)
    slots = jnp.arange(detections.mask.shape[0])
    tracks = Tracks(
        boxes=detections.boxes,
        ids=jnp.where(detections.mask, slots + 1, -1),
        scores=colours @ params.channel_weights,
        mask=detections.mask,
    )
    info = MeanColourInfo(colours, jax.random.uniform(key), checksum, tracks, tracks)
    return MeanColourState(state.frames_seen + 1, state.checksum + checksum), info


MEAN_COLOUR = Filter(init, step)
RED = MeanColourParams(jnp.array([1.0, 0.0, 0.0], jnp.float32))


def numpy_mean_colours(frame: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """The oracle: mean RGB of ``frame[r0:r1, c0:c1]`` per box (rounded ends, clipped)."""
    height, width = frame.shape[:2]
    colours = np.zeros((len(boxes), 3))
    for k, (x, y, w, h) in enumerate(np.asarray(boxes, np.float64)):
        c0, c1 = (int(np.clip(np.round(v), 0, width)) for v in (x, x + w))
        r0, r1 = (int(np.clip(np.round(v), 0, height)) for v in (y, y + h))
        if r1 > r0 and c1 > c0:
            colours[k] = frame[r0:r1, c0:c1].reshape(-1, 3).mean(axis=0)
    return colours


@dataclasses.dataclass(frozen=True)
class MeanColourConfig(TrackerConfig):
    """The test tracker's configuration (``jaxtrack track --tracker mean-colour``)."""

    tracker: ClassVar[str] = "mean-colour"

    output: str = setting("online", OUTPUT)
    max_gap: int = setting(0, MAX_GAP)


def build_mean_colour(config, info, context=None, variant="GM"):
    del config, info, context, variant
    return MEAN_COLOUR, RED


def mean_colour_memory(config, capacity: int, chunk_frames: int) -> MemoryEstimate:
    del config
    return MemoryEstimate(chunk_bytes=256 * chunk_frames * capacity, frame_output_bytes=64)


MEAN_COLOUR_ENTRY = TrackerEntry(
    MeanColourConfig,
    MeanColourParams,
    build_mean_colour,
    frozen_properties,
    takes_context=False,
    memory=mean_colour_memory,
    uses_frames=True,
)


def checksum_init(key, params):
    del key, params
    return jnp.zeros((), jnp.uint32)


def checksum_step(key, state, params, inputs: FrameInputs):
    """Adds up every pixel value of the frame (wrapping uint32): a filter that reads the
    whole frame and does nothing else."""
    del key, params
    total = jnp.sum(inputs.frame, dtype=jnp.uint32)
    return state + total, total


CHECKSUM = Filter(checksum_init, checksum_step)


#: The size of the random clips: frames of 24 x 32 pixels, 4 detection slots.
HEIGHT, WIDTH, NUM_FRAMES, SLOTS = 24, 32, 11, 4


def random_video(seed: int, num_frames: int = NUM_FRAMES, height: int = HEIGHT) -> np.ndarray:
    """Random RGB ``uint8`` frames ``[num_frames, height, WIDTH, 3]``."""
    return np.random.default_rng(seed).integers(0, 256, (num_frames, height, WIDTH, 3), np.uint8)


def random_detections(seed: int, num_frames: int = NUM_FRAMES, slots: int = SLOTS) -> Detections:
    """Boxes partly outside the image included; 0..slots detections per frame."""
    rng = np.random.default_rng(seed)
    boxes = np.column_stack(
        [rng.uniform(-5, WIDTH, num_frames * slots), rng.uniform(-5, HEIGHT, num_frames * slots)]
        + [rng.uniform(1, 15, num_frames * slots) for _ in range(2)]
    ).reshape(num_frames, slots, 4)
    mask = rng.random((num_frames, slots)) < 0.6
    mask[0] = True
    boxes[~mask] = PAD_BOX
    scores = np.where(mask, 1.0, 0.0)
    return Detections(boxes.astype(np.float32), scores.astype(np.float32), mask)
