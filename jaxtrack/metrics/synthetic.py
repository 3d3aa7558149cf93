"""Seeded corrupted copies of ground truth: tracker outputs with known kinds of errors.

Used to test the metrics against TrackEval and to benchmark them: each scenario starts from
every gt row (ignored ones included, so that boxes on them become false positives) and
applies a mix of box jitter, missed boxes, dropped segments (fragmentation), identity
switches, track splits, false-positive tracks and a random relabelling of identities.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from jaxtrack.types import MotTable


@dataclasses.dataclass(frozen=True)
class Corruption:
    """How to corrupt a ground-truth table (rates are per row or per track).

    Attributes:
        jitter: std of box noise, relative to box width/height.
        miss_rate: probability of dropping each row.
        gap_rate: probability that a track loses one contiguous segment of its frames.
        switch_rate: per track, probability of swapping identities with another track that
            is present in the same frame, from that frame on.
        split_rate: probability that a track takes a new identity from a random frame on.
        false_tracks: false-positive tracks per 100 frames (random boxes, drifting).
        keep: fraction of rows kept before anything else (0 gives an empty output).
    """

    jitter: float = 0.0
    miss_rate: float = 0.0
    gap_rate: float = 0.0
    switch_rate: float = 0.0
    split_rate: float = 0.0
    false_tracks: float = 0.0
    keep: float = 1.0


#: Named scenarios for tests and benchmarks.
SCENARIOS = {
    "perfect": Corruption(),
    "perturbed": Corruption(jitter=0.08, miss_rate=0.05, false_tracks=5.0),
    "fragmented": Corruption(jitter=0.04, gap_rate=0.6, split_rate=0.3),
    "id_swapped": Corruption(jitter=0.04, switch_rate=0.4),
    "noisy": Corruption(
        jitter=0.15, miss_rate=0.2, gap_rate=0.4, switch_rate=0.3, split_rate=0.3, false_tracks=20.0
    ),
    "empty": Corruption(keep=0.0),
}


def corrupt(gt: MotTable, corruption: Corruption, seed: int) -> MotTable:
    """A tracker output derived from ``gt`` by the given corruption.

    Args:
        gt: ground truth, all rows.
        corruption: what to apply.
        seed: seed of the NumPy generator.

    Returns:
        A result table (ids unique per frame, positive box sizes, rows in frame order).
    """
    rng = np.random.default_rng(seed)
    keep = rng.random(len(gt)) < corruption.keep
    frames, ids, boxes = gt.frames[keep], gt.ids[keep].copy(), gt.boxes[keep].copy()
    if corruption.jitter > 0:
        scale = np.repeat(boxes[:, 2:4], 2, axis=1)[:, [0, 2, 1, 3]]
        boxes += rng.normal(0.0, corruption.jitter, boxes.shape) * scale
        boxes[:, 2:4] = np.abs(boxes[:, 2:4]) + 1.0
    drop = rng.random(frames.shape[0]) < corruption.miss_rate
    drop |= _gaps(frames, ids, corruption.gap_rate, rng)
    frames, ids, boxes = frames[~drop], ids[~drop], boxes[~drop]
    ids = _switch(frames, ids, corruption.switch_rate, rng)
    ids = _split(frames, ids, corruption.split_rate, rng)
    frames, ids, boxes = _add_false_tracks(frames, ids, boxes, gt, corruption.false_tracks, rng)
    labels = np.unique(ids)
    relabel = rng.permutation(labels.size) + 1
    ids = relabel[np.searchsorted(labels, ids)]
    order = np.argsort(frames, kind="stable")
    return MotTable.from_arrays(frames[order], ids[order], boxes[order])


def _gaps(frames, ids, rate, rng) -> np.ndarray:
    drop = np.zeros(frames.shape[0], dtype=bool)
    for track in np.unique(ids):
        if rng.random() >= rate:
            continue
        rows = np.flatnonzero(ids == track)
        first, last = frames[rows].min(), frames[rows].max()
        start = rng.integers(first, last + 1)
        length = rng.integers(1, max(2, (last - first) // 3 + 1))
        drop[rows] |= (frames[rows] >= start) & (frames[rows] < start + length)
    return drop


def _switch(frames, ids, rate, rng) -> np.ndarray:
    ids = ids.copy()
    for track in np.unique(ids):
        if rng.random() >= rate:
            continue
        rows = np.flatnonzero(ids == track)
        if rows.size == 0:
            continue
        frame = frames[rng.choice(rows)]
        others = np.unique(ids[(frames == frame) & (ids != track)])
        if others.size == 0:
            continue
        other = rng.choice(others)
        later = frames >= frame
        a, b = later & (ids == track), later & (ids == other)
        ids[a], ids[b] = other, track
    return ids


def _split(frames, ids, rate, rng) -> np.ndarray:
    ids = ids.copy()
    next_id = int(ids.max(initial=0)) + 1
    for track in np.unique(ids):
        if rng.random() >= rate:
            continue
        rows = np.flatnonzero(ids == track)
        frame = frames[rng.choice(rows)]
        ids[rows[frames[rows] >= frame]] = next_id
        next_id += 1
    return ids


def _add_false_tracks(frames, ids, boxes, gt, per_100_frames, rng):
    if per_100_frames <= 0 or len(gt) == 0:
        return frames, ids, boxes
    first, last = int(gt.frames.min()), int(gt.frames.max())
    num_tracks = rng.poisson(per_100_frames * (last - first + 1) / 100)
    extent = gt.boxes[:, :2].max(axis=0) + gt.boxes[:, 2:].max(axis=0)
    next_id = int(ids.max(initial=0)) + 1
    new_frames, new_ids, new_boxes = [frames], [ids], [boxes]
    for track in range(num_tracks):
        start = rng.integers(first, last + 1)
        span = np.arange(start, min(last, start + rng.integers(1, 30)) + 1)
        size = gt.boxes[rng.integers(len(gt)), 2:]
        corner = rng.random(2) * extent + np.cumsum(rng.normal(0, 3, (span.size, 2)), axis=0)
        new_frames.append(span)
        new_ids.append(np.full(span.size, next_id + track))
        new_boxes.append(np.column_stack([corner, np.tile(size, (span.size, 1))]))
    return np.concatenate(new_frames), np.concatenate(new_ids), np.concatenate(new_boxes)
