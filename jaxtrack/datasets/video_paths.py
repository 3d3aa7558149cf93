"""Walking people on the ground of a video scene: perspective speed, gait, routes, visibility.

Host NumPy. Positions are **foot points** ``(column, row)`` in pixels: the bottom centre of a
person's box. With the nominal height ``h(y_f) = a (y_f - r0)`` of a person whose feet are on
row ``y_f`` (:meth:`~jaxtrack.datasets.video_config.VideoSceneConfig.person_height`):

* a walker covers ``v = pace h(y_f) / fps`` pixels per frame (``pace`` in body heights per
  second), so people slow down in the image as they walk away from the camera;
* the gait phase advances by ``2 pi d / (STRIDE h(y_f))`` for a step of ``d`` pixels (one gait
  cycle, two steps, per ``STRIDE`` body heights walked), so the legs move in step with the
  ground covered and stop when the walker stands;
* a person's box is ``(y1 - rho s h / 2, y_f - s h, rho s h, s h)`` for foot point
  ``(y1, y_f)``, own height scale ``s`` and aspect ratio ``rho``.
"""

from __future__ import annotations

import numpy as np

from jaxtrack.datasets.video_config import VideoSceneConfig

#: Body heights walked per gait cycle (two steps; about 1.4 m for a 1.75 m person).
STRIDE = 0.8
#: Sample points per box side of :func:`box_visibility` (the visible fraction is a multiple
#: of ``1 / VISIBILITY_GRID^2``).
VISIBILITY_GRID = 16


def nominal_height(rows, config: VideoSceneConfig) -> np.ndarray:
    """``h(y_f) = a (y_f - r0 H)``: nominal height in pixels of people with feet on ``rows``."""
    horizon = config.horizon_row * config.image_height
    return config.height_per_row * (np.asarray(rows, np.float64) - horizon)


def walk(
    waypoints: np.ndarray,
    pace: float,
    config: VideoSceneConfig,
    stops: dict[int, int] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Foot points, frame by frame, of a person walking a piecewise-linear path.

    Each frame the walker moves ``v = pace h(y_f) / fps`` pixels towards the next waypoint
    (``y_f`` its current row); a step never runs past a waypoint, so every waypoint is reached
    exactly. The walker walks on from each waypoint at the next frame, except that it stands
    ``stops[k]`` frames on waypoint ``k`` (its arrival frame included), and the walk ends on
    arrival at the last waypoint.

    Args:
        waypoints: ``[K, 2]`` foot points (pixels), the first one where the walk starts.
        pace: body heights per second.
        config: the scene (perspective law, frame rate).
        stops: waypoint index (below ``K - 1``) -> frames (>= 1) spent standing on it.

    Returns:
        ``feet [n, 2]`` and ``arrivals [K]`` (frame index of the arrival at each waypoint;
        ``arrivals[0] = 0``).
    """
    waypoints = np.asarray(waypoints, np.float64)
    position = waypoints[0].copy()
    feet = [position]
    arrivals = [0]
    stops = stops or {}
    for index, target in enumerate(waypoints[1:]):
        feet += [position] * (stops.get(index, 1) - 1)
        while True:
            step = pace * float(nominal_height(position[1], config)) / config.frame_rate
            offset = target - position
            distance = float(np.hypot(*offset))
            position = target.copy() if distance <= step else position + offset * step / distance
            feet.append(position)
            if distance <= step:
                break
        arrivals.append(len(feet) - 1)
    return np.array(feet), np.array(arrivals)


def gait_phase(feet: np.ndarray, config: VideoSceneConfig) -> np.ndarray:
    """Gait phase along a track of foot points, from 0 at the first one (radians).

    ``phase_i = phase_{i-1} + 2 pi d_i / (STRIDE h(y_i))`` with ``d_i`` the step from foot point
    ``i - 1`` to ``i`` and ``h(y_i)`` the nominal height where it lands: one gait cycle per
    ``STRIDE`` body heights walked, none while standing.

    Args:
        feet: ``[n, 2]`` foot points, pixels.
        config: the scene.

    Returns:
        ``[n]`` phases.
    """
    steps = np.hypot(*np.diff(feet, axis=0).T)
    advance = 2 * np.pi * steps / (STRIDE * nominal_height(feet[1:, 1], config))
    return np.concatenate([[0.0], np.cumsum(advance)])


def person_boxes(feet: np.ndarray, heights: np.ndarray, aspect_ratio: float) -> np.ndarray:
    """``(x, y, w, h)`` boxes of people standing on foot points ``feet [n, 2]`` with heights
    ``heights [n]`` (pixels) and width ``aspect_ratio * height``."""
    widths = aspect_ratio * heights
    return np.stack(
        [feet[:, 0] - widths / 2, feet[:, 1] - heights, widths, heights], axis=-1
    ).reshape(-1, 4)


def crosses_occluder(points: np.ndarray, config: VideoSceneConfig) -> bool:
    """Whether a path walks through the occluder's base (the billboard's foot on the ground).

    The occluder is a flat board standing on its bottom edge (row ``y_b``): a path may pass
    behind it (rows above ``y_b``) or in front of it, but no segment may cross row ``y_b``
    within the board's columns widened by half a person's width on each side.

    Args:
        points: ``[K, 2]`` foot points of a piecewise-linear path, pixels.
        config: the scene.

    Returns:
        True when some segment crosses the base.
    """
    x, y, w, h = config.pixels(config.occluder)
    base = y + h
    margin = config.aspect_ratio * float(nominal_height(base, config)) / 2
    starts, ends = points[:-1], points[1:]
    for (x0, y0), (x1, y1) in zip(starts, ends, strict=True):
        if (y0 - base) * (y1 - base) > 0 or y0 == y1:
            continue
        column = x0 + (x1 - x0) * (base - y0) / (y1 - y0)
        if x - margin <= column <= x + w + margin:
            return True
    return False


def box_visibility(
    boxes: np.ndarray, occluder: np.ndarray, image_size: tuple[int, int]
) -> np.ndarray:
    """Visible fraction of each person's box (the MOT16/17 ground-truth visibility).

    A box's area is sampled at the centres of a ``G x G`` grid of equal cells
    (``G = VISIBILITY_GRID``); a sample is hidden when it lies outside the image, inside the
    occluder box while the person's foot row ``y + h`` is above the occluder's bottom row (the
    person is behind it), or inside the box of a person whose foot row is below (nearer the
    camera). The visibility is the share of samples not hidden.

    Args:
        boxes: ``(x, y, w, h)`` of the people in one frame, ``[n, 4]`` pixels.
        occluder: ``(x, y, w, h)`` of the occluder, pixels.
        image_size: ``(W, H)``.

    Returns:
        ``[n]`` fractions in ``[0, 1]``.
    """
    cells = (np.arange(VISIBILITY_GRID) + 0.5) / VISIBILITY_GRID
    u, v = (grid.reshape(-1) for grid in np.meshgrid(cells, cells))
    sx = boxes[:, None, 0] + u[None] * boxes[:, None, 2]  # [n, G^2]
    sy = boxes[:, None, 1] + v[None] * boxes[:, None, 3]
    width, height = image_size
    hidden = (sx < 0) | (sx >= width) | (sy < 0) | (sy >= height)
    ox, oy, ow, oh = occluder
    foot = boxes[:, 1] + boxes[:, 3]
    behind = (foot < oy + oh)[:, None]
    hidden |= behind & (sx >= ox) & (sx < ox + ow) & (sy >= oy) & (sy < oy + oh)
    x0, y0 = boxes[:, 0], boxes[:, 1]
    x1, y1 = x0 + boxes[:, 2], y0 + boxes[:, 3]
    inside = (
        (sx[:, :, None] >= x0[None, None])
        & (sx[:, :, None] < x1[None, None])
        & (sy[:, :, None] >= y0[None, None])
        & (sy[:, :, None] < y1[None, None])
    )  # [n, G^2, n]: sample of box i inside box j
    nearer = foot[None, :] > foot[:, None]  # [n, n]: j nearer than i
    hidden |= np.any(inside & nearer[:, None, :], axis=2)
    return 1.0 - hidden.mean(axis=1)
