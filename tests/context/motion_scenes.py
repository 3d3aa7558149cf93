"""Synthetic walkers for the motion-model tests: a road that turns, with known dynamics."""

from __future__ import annotations

import numpy as np

from jaxtrack.types import MotTable

#: The turn: a quarter circle of this radius centred at TURN_CENTRE (pixels), between a
#: road going right along y = 100 and one going down along x = 380.
TURN_CENTRE = np.array([300.0, 180.0])
TURN_RADIUS = 80.0


def road_point(distance: np.ndarray) -> np.ndarray:
    """Foot point at a walked ``distance`` along the road: right, quarter turn, down."""
    arc = np.pi / 2 * TURN_RADIUS
    straight = np.c_[distance, np.full_like(distance, 100.0)]
    angle = np.clip(distance - 300.0, 0, arc) / TURN_RADIUS
    turning = TURN_CENTRE + TURN_RADIUS * np.c_[np.sin(angle), -np.cos(angle)]
    down = np.c_[np.full_like(distance, 380.0), 180.0 + (distance - 300.0 - arc)]
    where = np.where(distance < 300.0, 0, np.where(distance < 300.0 + arc, 1, 2))
    return np.choose(where[:, None], [straight, turning, down])


def road_walkers(seed: int, num_walkers: int, noise: float = 0.2) -> MotTable:
    """Walkers on the road at 3-5 px/frame from distance 0 to 560, foot noise ``noise``."""
    rng = np.random.default_rng(seed)
    frames, ids, boxes = [], [], []
    for walker in range(num_walkers):
        speed = rng.uniform(3.0, 5.0)
        distance = np.arange(0.0, 560.0, speed)
        feet = road_point(distance) + noise * rng.standard_normal((distance.size, 2))
        start = rng.integers(1, 50)
        frames.append(start + np.arange(distance.size))
        ids.append(np.full(distance.size, walker + 1))
        boxes.append(np.c_[feet[:, 0] - 5, feet[:, 1] - 20, np.full((distance.size, 2), [10, 20])])
    return MotTable.from_arrays(np.concatenate(frames), np.concatenate(ids), np.concatenate(boxes))
