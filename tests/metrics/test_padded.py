"""Scoring padded Tracks (single and batched) equals scoring the equivalent tables."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.errors import InputError
from jaxtrack.io import MotTable
from jaxtrack.metrics import evaluate_sequence, evaluate_tracks, table_from_tracks
from jaxtrack.metrics.synthetic import SCENARIOS, corrupt
from jaxtrack.types import Tracks


def pad(table: MotTable, num_frames: int, capacity: int) -> Tracks:
    """Fills slots frame by frame in row order (float32 boxes, as a filter would output)."""
    boxes = np.tile(np.array([0, 0, 1, 1], np.float32), (num_frames, capacity, 1))
    ids = np.full((num_frames, capacity), -1, np.int32)
    scores = np.zeros((num_frames, capacity), np.float32)
    mask = np.zeros((num_frames, capacity), bool)
    used = np.zeros(num_frames, int)
    for frame, track, box in zip(table.frames, table.ids, table.boxes, strict=True):
        t = frame - 1
        boxes[t, used[t]], ids[t, used[t]], mask[t, used[t]], scores[t, used[t]] = (
            box,
            track,
            True,
            1,
        )
        used[t] += 1
    return Tracks(jnp.asarray(boxes), jnp.asarray(ids), jnp.asarray(scores), jnp.asarray(mask))


def float32_boxes(table: MotTable) -> MotTable:
    return MotTable.from_arrays(table.frames, table.ids, table.boxes.astype(np.float32))


def test_batched_tracks_equal_tables(mot15_gt):
    gt, seq_length = mot15_gt["TUD-Stadtmitte"]
    outputs = [
        corrupt(gt, SCENARIOS[name], seed=3) for name in ("perturbed", "noisy", "fragmented")
    ]
    capacity = max(int(np.bincount(o.frames).max()) for o in outputs)
    padded = [pad(o, seq_length, capacity) for o in outputs]
    batch = Tracks(*(jnp.stack(leaves) for leaves in zip(*padded, strict=True)))
    evaluations = evaluate_tracks(gt, batch)
    assert len(evaluations) == 3
    for output, evaluation in zip(outputs, evaluations, strict=True):
        expected = evaluate_sequence(gt, float32_boxes(output), (1, seq_length))
        assert evaluation.scores() == expected.scores()
    single = evaluate_tracks(gt, padded[1])
    assert single.scores() == evaluations[1].scores()
    table = table_from_tracks(padded[0])
    assert len(table) == len(outputs[0]) and table.boxes.dtype == np.float64


def test_repeated_id_in_a_frame_is_an_error(mot15_gt):
    gt, _ = mot15_gt["TUD-Campus"]
    result = gt.select(gt.frames <= 3)
    duplicate = MotTable.from_arrays(
        np.r_[result.frames, 2], np.r_[result.ids, result.ids[result.frames == 2][0]],
        np.vstack([result.boxes, result.boxes[:1]]),
    )  # fmt: skip
    tracks = pad(duplicate, 3, 16)
    with pytest.raises(InputError, match="appears twice in frame 2"):
        evaluate_tracks(gt.select(gt.frames <= 3), tracks)
