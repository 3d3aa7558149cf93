"""The runner with frames: chunked frames == one scan over frames in memory, oracle outputs,
padded frames skipped, clear errors, one compile per frame size and capacity."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.errors import InputError
from jaxtrack.filters.base import _chunk_functions, aligned_frames, run
from jaxtrack.types import FrameInputs
from tests.filters.frame_filters import (
    HEIGHT,
    MEAN_COLOUR,
    NUM_FRAMES,
    RED,
    SLOTS,
    MeanColourParams,
    numpy_mean_colours,
    random_detections,
    random_video,
)

COMPILE_EVENT = "/jax/core/compile/backend_compile_duration"
_compiles: list[str] = []
jax.monitoring.register_event_duration_secs_listener(
    lambda name, *_, **__: _compiles.append(name) if name == COMPILE_EVENT else None
)


VIDEO = random_video(0)
DETECTIONS = random_detections(1)
KEY = jax.random.key(7)


class RecordingFrames:
    """A frame source over frames in memory that records what the runner asks for."""

    def __init__(self, video: np.ndarray):
        self.video = video
        self.calls: list[tuple[int, int]] = []

    def __call__(self, start: int, stop: int) -> np.ndarray:
        self.calls.append((start, stop))
        return self.video[start:stop]


def _equal(a, b, **tolerance):
    jax.tree.map(lambda x, y: np.testing.assert_allclose(x, y, **tolerance), a, b)


def run_fitted(filt, detections, video):
    """A chunked run (4 frames, fitted capacities) with the frames read from ``video``."""
    frames = RecordingFrames(video)
    return run(filt, KEY, RED, detections, chunk_frames=4, fit_capacity=True, frames=frames)


@functools.cache
def one_scan():
    """The unchunked run over the frames in memory (the reference of the chunked runs)."""
    return run(MEAN_COLOUR, KEY, RED, FrameInputs(DETECTIONS, jnp.asarray(VIDEO)))


@pytest.mark.parametrize("chunk_frames", [3, 4, 11, 16])
def test_chunked_frames_equal_one_scan_over_frames_in_memory(chunk_frames):
    frames = RecordingFrames(VIDEO)
    state, info = run(MEAN_COLOUR, KEY, RED, DETECTIONS, chunk_frames=chunk_frames, frames=frames)
    expected_state, expected = one_scan()
    _equal(info, expected, rtol=1e-6)
    _equal(state, expected_state)
    # Each frame asked for once, in order; the padded frames of the last chunk are skipped.
    starts = list(range(0, NUM_FRAMES, chunk_frames))
    assert frames.calls == [(s, min(s + chunk_frames, NUM_FRAMES)) for s in starts]
    assert int(state.frames_seen) == NUM_FRAMES


class RefillingFrames(RecordingFrames):
    """A source that spoils the array it returned two calls before, as the runner allows
    (:data:`~jaxtrack.filters.base.FrameSource`): a chunk still reading it would see 255s
    until the array is refilled on the next call. Three arrays in turn, aligned so that JAX
    reads them in place."""

    def __init__(self, video: np.ndarray, chunk_frames: int):
        super().__init__(video)
        self.ring = [aligned_frames(chunk_frames, *video.shape[1:3]) for _ in range(3)]

    def __call__(self, start: int, stop: int) -> np.ndarray:
        if len(self.calls) >= 2:
            self.ring[(len(self.calls) - 2) % 3][...] = 255
        out = self.ring[len(self.calls) % 3][: stop - start]
        out[...] = super().__call__(start, stop)
        return out


def test_a_source_may_refill_the_array_of_the_chunk_before_last():
    state, info = run(
        MEAN_COLOUR, KEY, RED, DETECTIONS, chunk_frames=2, frames=RefillingFrames(VIDEO, 2)
    )
    expected_state, expected = one_scan()
    _equal(info, expected, rtol=1e-6)
    _equal(state, expected_state)


def test_outputs_match_a_numpy_oracle_per_frame():
    frames = RecordingFrames(VIDEO)
    state, info = run(MEAN_COLOUR, KEY, RED, DETECTIONS, chunk_frames=4, frames=frames)
    for t in range(NUM_FRAMES):
        real = DETECTIONS.mask[t]
        colours = numpy_mean_colours(VIDEO[t], DETECTIONS.boxes[t][real])
        np.testing.assert_allclose(info.colours[t][real], colours, rtol=1e-5, atol=1e-4)
        np.testing.assert_allclose(info.tracks.scores[t][real], colours[:, 0], rtol=1e-5, atol=1e-4)
        assert not info.colours[t][~real].any()
    sums = VIDEO.reshape(NUM_FRAMES, -1).sum(axis=1, dtype=np.uint64)
    np.testing.assert_array_equal(info.checksum, sums % 2**32)
    assert int(state.checksum) == int(sums.sum() % 2**32)
    assert 0 < np.ptp(info.draw) and len(set(info.draw.tolist())) == NUM_FRAMES


def test_frames_with_fit_capacity_follow_the_chunk_plan():
    """A crowded frame runs in a chunk of its own: the frames come in those chunks too."""
    detections = random_detections(2, slots=80)
    detections.mask[:, SLOTS:] = False
    detections.mask[5, :] = True  # 80 > 4 x 16: crowded
    frames = RecordingFrames(VIDEO)
    _, info = run(
        MEAN_COLOUR, KEY, RED, detections, chunk_frames=8, fit_capacity=True, frames=frames
    )
    assert frames.calls == [(0, 5), (5, 6), (6, 11)]
    for t in range(NUM_FRAMES):
        real = detections.mask[t]
        colours = numpy_mean_colours(VIDEO[t], detections.boxes[t][real])
        np.testing.assert_allclose(info.colours[t][: real.sum()], colours, rtol=1e-5, atol=1e-4)


def test_jit_equals_eager_over_frames_in_memory():
    inputs = jax.tree.map(lambda x: jnp.asarray(x[:3]), FrameInputs(DETECTIONS, VIDEO))
    _, jitted = jax.jit(lambda k, p, x: run(MEAN_COLOUR, k, p, x))(KEY, RED, inputs)
    with jax.disable_jit():
        _, eager = run(MEAN_COLOUR, KEY, RED, inputs)
    _equal(jitted, eager, rtol=1e-6)


def test_vmap_over_params_equals_loop():
    inputs = FrameInputs(DETECTIONS, jnp.asarray(VIDEO))
    weights = jnp.array([[1.0, 0.0, 0.0], [0.0, 0.5, 0.5], [1 / 3, 1 / 3, 1 / 3]], jnp.float32)
    single = jax.jit(lambda w: run(MEAN_COLOUR, KEY, MeanColourParams(w), inputs)[1])
    batched = jax.jit(jax.vmap(single))(weights)
    for i, w in enumerate(weights):
        _equal(jax.tree.map(lambda x, i=i: x[i], batched), single(w), rtol=1e-6)
    # The scores are the colour means weighted: grey = mean of the three channels.
    np.testing.assert_allclose(batched.tracks.scores[2], batched.colours[2].mean(-1), rtol=1e-5)


@pytest.mark.parametrize(
    ("images", "message"),
    [
        (lambda s, e: VIDEO[s:e].astype(np.float32), "gave float32 images"),
        (lambda s, e: VIDEO[s : e - 1], r"expected uint8 \[4, height, width, 3\]"),
        (lambda s, e: VIDEO[s:e, ..., :1], r"shape \(4, 24, 32, 1\)"),
        (lambda s, e: random_video(0, e - s, HEIGHT + s // 4), "first chunk's height and width"),
    ],
)
def test_bad_frames_are_named(images, message):
    with pytest.raises(InputError, match=message):
        run(MEAN_COLOUR, KEY, RED, DETECTIONS, chunk_frames=4, frames=images)


def test_frames_need_a_chunked_run_over_detections():
    with pytest.raises(ValueError, match="need chunk_frames"):
        run(MEAN_COLOUR, KEY, RED, DETECTIONS, frames=RecordingFrames(VIDEO))
    with pytest.raises(ValueError, match="takes Detections"):
        run(MEAN_COLOUR, KEY, RED, FrameInputs(DETECTIONS, VIDEO), chunk_frames=4)


def test_one_compile_per_frame_size_and_capacity():
    filt = MEAN_COLOUR._replace(step=lambda *a: MEAN_COLOUR.step(*a))  # a cache of its own
    scan_chunk = _chunk_functions(filt, False, None)[1]
    run_fitted(filt, DETECTIONS, VIDEO)
    # Other frames and detections (counts 0..9, one capacity), the same length: no compile.
    start = len(_compiles)
    run_fitted(filt, random_detections(3, slots=9), random_video(4))
    assert len(_compiles) == start
    # Another length reuses the compiled chunk too (only the key split is per length).
    run_fitted(filt, random_detections(5, num_frames=23), random_video(6, num_frames=23))
    assert scan_chunk._cache_size() == 1
    # Another frame size, or another capacity, compiles the chunk again.
    run_fitted(filt, DETECTIONS, random_video(8, height=HEIGHT + 8))
    run_fitted(filt, random_detections(9, slots=40), VIDEO)
    assert scan_chunk._cache_size() == 3
