"""Small synthetic scenes for the PHD tests: straight-line targets, padded detections."""

from __future__ import annotations

import numpy as np

from jaxtrack.types import PAD_BOX, Detections


def padded_detections(frames: list[list[tuple[float, ...]]], capacity: int, score=0.99):
    """Detections from per-frame lists of top-left ``(x, y, w, h)`` boxes."""
    num_frames = len(frames)
    boxes = np.tile(np.asarray(PAD_BOX, np.float32), (num_frames, capacity, 1))
    scores = np.zeros((num_frames, capacity), np.float32)
    mask = np.zeros((num_frames, capacity), bool)
    for t, frame in enumerate(frames):
        for j, box in enumerate(frame):
            boxes[t, j] = box
            scores[t, j] = score
            mask[t, j] = True
    return Detections(boxes=boxes, scores=scores, mask=mask)


def walking_scene(
    num_frames: int,
    starts: list[tuple[float, float]],
    velocities: list[tuple[float, float]],
    size=(40.0, 100.0),
    noise=2.0,
    missed: dict[int, set[int]] | None = None,
    capacity: int = 6,
    seed: int = 0,
):
    """Targets moving in straight lines; ``missed[t]`` lists targets not detected at frame t.

    Returns:
        The padded detections and the true top-left boxes ``[num_frames, num_targets, 4]``.
    """
    rng = np.random.default_rng(seed)
    missed = missed or {}
    truth = np.zeros((num_frames, len(starts), 4))
    frames = []
    for t in range(num_frames):
        frame = []
        for i, ((x0, y0), (vx, vy)) in enumerate(zip(starts, velocities, strict=True)):
            truth[t, i] = (x0 + vx * t, y0 + vy * t, *size)
            if i not in missed.get(t, set()):
                frame.append(tuple(truth[t, i] + np.r_[rng.normal(0, noise, 2), 0, 0]))
        frames.append(frame)
    return padded_detections(frames, capacity), truth
