"""Sweeps of trackers that look at the images (``sweep_frames``) and the batched chunked
runner under them (``run_batch``): every configuration gives what its own run gives."""

from __future__ import annotations

import dataclasses

import jax
import numpy as np
import pytest

from jaxtrack.detect.sequence import video_sequence
from jaxtrack.errors import InputError
from jaxtrack.filters.base import run, run_batch
from jaxtrack.filters.cmt_tracker import CMTConfig
from jaxtrack.filters.fusion_tracker import FusionConfig
from jaxtrack.filters.hierarchical_tracker import HierarchicalConfig
from jaxtrack.filters.kalman_tracker import KalmanConfig
from jaxtrack.filters.phd_tracker import PHDConfig
from jaxtrack.filters.registry import build_tracker
from jaxtrack.io.video import VideoReader
from jaxtrack.pipelines.frame_context import streamed_params
from jaxtrack.pipelines.stream import track_streamed, track_streamed_events
from jaxtrack.pipelines.sweep import batch_params, sweep_frames
from jaxtrack.pipelines.tracking import track_outputs
from jaxtrack.types import Detections, MotTable, SequenceInfo
from tests.synthetic_video import NUM_FRAMES, SIZE, person_box, write_synthetic_folder

SMALL_CMT = {"max_components": 4, "particles_per_component": 16}


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    """The walking rectangle (img1/), its box and a false box as detections, frames 3..38."""
    folder = write_synthetic_folder(tmp_path_factory.mktemp("walk") / "img1")
    frames = np.arange(1, NUM_FRAMES + 1)
    boxes = [person_box(k) for k in frames] + [(200, 10, 12, 30)] * 6
    table = MotTable.from_arrays(
        np.concatenate([frames, np.arange(10, 16)]), -np.ones(NUM_FRAMES + 6), boxes
    )
    gt = MotTable.from_arrays(frames, np.ones(NUM_FRAMES), [person_box(k) for k in frames])
    info = SequenceInfo("walk", NUM_FRAMES, *SIZE, 25.0)
    return folder, video_sequence(folder, table, (3, 38), info, gt)


def assert_same_rows(a: MotTable, b: MotTable) -> None:
    np.testing.assert_array_equal(a.frames, b.frames)
    np.testing.assert_array_equal(a.ids, b.ids)
    np.testing.assert_allclose(a.boxes, b.boxes, rtol=1e-5, atol=1e-3)


def random_detections(seed: int, frames: int = 23, slots: int = 5) -> Detections:
    rng = np.random.default_rng(seed)
    xy = rng.uniform(20, 200, (frames, slots, 2))
    boxes = np.concatenate([xy, np.broadcast_to([12.0, 30.0], (frames, slots, 2))], axis=-1)
    return Detections(
        boxes=boxes.astype(np.float32),
        scores=np.ones((frames, slots), np.float32),
        mask=rng.uniform(size=(frames, slots)) < 0.6,
    )


def test_run_batch_gives_each_configurations_own_chunked_run():
    """Three configurations with their own keys, in groups of two (the last padded), over
    chunks of 8 frames (the last one short): each equals its chunked ``run`` (identities and
    masks exactly, boxes up to float32 rounding)."""
    info = SequenceInfo("drawn", 23, 240, 240, 25.0)
    filt, params = build_tracker(PHDConfig(num_particles=256), info)
    batched = batch_params(params, {"clutter_rate": np.array([0.2, 1.0, 5.0], np.float32)})
    keys = jax.vmap(jax.random.PRNGKey)(np.arange(3))
    detections = random_detections(0)
    done = []
    outputs = run_batch(
        filt,
        keys,
        batched,
        detections,
        chunk_frames=8,
        group_size=2,
        frame_output=track_outputs,
        progress=done.append,
    )
    assert done == [8, 8, 7]
    for b in range(3):
        own = jax.tree.map(lambda x, b=b: x[b], batched)
        _, expected = run(
            filt,
            keys[b],
            own,
            detections,
            chunk_frames=8,
            fit_capacity=True,
            frame_output=track_outputs,
        )
        for got, want in zip(
            jax.tree.leaves(jax.tree.map(lambda x, b=b: x[b], outputs)),
            jax.tree.leaves(expected),
            strict=True,
        ):
            if np.issubdtype(want.dtype, np.floating):  # a batched program rounds differently
                np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-3)
            else:
                np.testing.assert_array_equal(got, want)
    # the clutter rate matters: the configurations' outputs are not all the same
    assert not np.array_equal(outputs.tracks.boxes[0], outputs.tracks.boxes[2])


def test_run_batch_refuses_mismatched_batches():
    info = SequenceInfo("drawn", 23, 240, 240, 25.0)
    filt, params = build_tracker(PHDConfig(num_particles=64), info)
    batched = batch_params(params, {"clutter_rate": np.array([0.2, 1.0], np.float32)})
    keys = jax.vmap(jax.random.PRNGKey)(np.arange(3))
    with pytest.raises(InputError, match="3 keys but parameters with batch sizes \\[2\\]"):
        run_batch(filt, keys, batched, random_detections(1), chunk_frames=8)
    with pytest.raises(ValueError, match="must be positive"):
        run_batch(filt, keys[:2], batched, random_detections(1), chunk_frames=0)


def test_cmt_sweep_gives_what_track_gives_with_each_configuration(walk):
    folder, seq = walk
    config = CMTConfig(variant="cmt", **SMALL_CMT)
    weights = np.array([0.0, 1.0, 3.0], np.float32)
    with VideoReader(folder) as reader:
        params, _ = streamed_params(config, seq, reader)
        result = sweep_frames(
            seq, reader, config, {"appearance_weight": weights}, chunk_size=2, chunk_frames=8
        )
        for b, weight in enumerate(weights):
            own = batch_params(params, {"appearance_weight": weight[None]})
            rows = track_streamed(
                seq, reader, config, 0, jax.tree.map(lambda x: x[0], own), chunk_frames=8
            )
            assert_same_rows(result.rows[b], rows)
    np.testing.assert_array_equal(result.updates["appearance_weight"], weights)
    assert result.scores["MOTA"].shape == (3,)
    # one true walker tracked over most of the span: the scores read the rows
    assert np.all(result.scores["Recall"] > 0.5)
    assert np.all(np.isnan(result.log_likelihood))


def test_hierarchical_sweep_by_name_merges_identities_as_track_does(walk):
    """A named parameter of the hierarchical tracker: ``min_score`` 0 is ``jaxtrack
    track``'s run (identities merged as it merges them), 2 ignores every detection."""
    folder, seq = walk
    config = HierarchicalConfig()
    with VideoReader(folder) as reader:
        result = sweep_frames(
            seq, reader, config, {"min_score": np.array([0.0, 2.0], np.float32)}, chunk_frames=16
        )
        rows, events = track_streamed_events(seq, reader, config, 0, chunk_frames=16)
    assert len(rows.frames) > 20
    assert_same_rows(result.rows[0], rows)
    assert len(result.rows[1].frames) == 0
    # the event rows RES.events.csv would hold, per configuration
    for got, want in zip(result.events[0], events, strict=True):
        np.testing.assert_array_equal(got, want)
    assert len(result.events[1].frames) == 0


def test_fusion_sweep_takes_a_batched_pytree(walk):
    """Without ``updates``, ``params`` is the batch: the fusion tracker's default gate (as
    ``jaxtrack track`` learns and builds it) and a gate no IoU passes (nothing voted in)."""
    folder, seq = walk
    config = FusionConfig(max_targets=8)
    with VideoReader(folder) as reader:
        params, _ = streamed_params(config, seq, reader)
        batched = batch_params(params, {"gate": np.array([params.gate, 1.5], np.float32)})
        result = sweep_frames(seq, reader, config, params=batched, chunk_frames=16)
        rows = track_streamed(seq, reader, config, 0, params, chunk_frames=16)
    assert len(rows.frames) > 20
    assert_same_rows(result.rows[0], rows)
    assert len(result.rows[1].frames) == 0
    assert result.updates == {}
    assert result.events is None


def test_sweep_frames_refuses_what_it_cannot_run(walk):
    folder, seq = walk
    with VideoReader(folder) as reader:
        with pytest.raises(InputError, match="kalman tracker reads no frames; use sweep"):
            sweep_frames(seq, reader, KalmanConfig(), {"x": np.zeros(2)})
        with pytest.raises(InputError, match="chunk_size and chunk_frames must be positive"):
            sweep_frames(seq, reader, CMTConfig(**SMALL_CMT), chunk_size=0)
        small = dataclasses.replace(seq, info=SequenceInfo("s", 40, 200, 120, 25.0))
        with pytest.raises(InputError, match="frames are 240x120 but s is 200x120"):
            sweep_frames(small, reader, CMTConfig(**SMALL_CMT))
