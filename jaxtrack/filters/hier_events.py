"""The Hierarchical tracker's event management (Hierarchical Sec. 5.1 and 5.5; SPEC section 4).

Six per-tracker states (Sec. 5.5): single target, grouping, grouped, splitting, entering and
exiting the scene, driven by a **collision map** of the current estimates.

* **Collision** (:func:`collision_map`): two live trackers ``i != j`` with boxes ``b_i, b_j``
  collide when their boxes intersect and the intersection covers at least ``min_overlap`` of
  the smaller box: ``|b_i ^ b_j| > 0`` and ``|b_i ^ b_j| / min(|b_i|, |b_j|) >= min_overlap``
  (the paper does not say how a collision is measured; the smaller box's area makes a person
  half hidden by a larger group box collide with it).
* **Group birth** (Sec. 5.1, :func:`is_group_birth`): a new-born tracker colliding with two or
  more existing trackers is a group tracker.
* **State machine** (Sec. 5.5, :func:`event_step`), with ``c_i`` "collides with some tracker"
  and ``g_i`` "collides with a confirmed group tracker":

  - ``not c_i``: ``ENTERING`` during a new tracker's first ``entering_frames`` frames while
    it has been entering since its birth (not a re-associated tracker, nor one that has
    collided since: a tracker enters once), else ``SINGLE`` ("if they stop colliding at any
    state, they become single again");
  - ``c_i and g_i``: ``GROUPED`` ("if they also collide with a confirmed group tracker");
  - ``c_i and not g_i``: ``SPLITTING`` when the previous state was ``GROUPED`` or
    ``SPLITTING`` ("once they no longer collide with a confirmed group tracker"), else
    ``GROUPING`` ("when two single targets are colliding").

  A group tracker goes through the same machine (it collides with the trackers of its
  members, so it is ``GROUPING`` while they are alive).
* **Lost trackers** (a departure; in :func:`~jaxtrack.filters.hierarchical.hierarchical_step`):
  a tracker whose low-level track is lost is propagated by its motion model for up to
  ``max_lost`` frames, and that extrapolated box drifts. In the collision map the event
  machine reads, the other trackers do not collide with a lost one (a group *birth* still
  counts it: a blob that swallowed two trackers is a group). Development scenes (synthetic
  video seeds 0-2), event precision / recall over the four kinds: detections 0.65 / 0.81 ->
  0.66 / 0.82, blobs 0.24 / 0.54 -> 0.27 / 0.70. (A group tracker whose members are all
  lost therefore reads ``SINGLE``; letting confirmed group trackers still collide with lost
  ones, their members, gave 0.29 / 0.64 on the blobs with the zones below, against 0.30 /
  0.70.)
* **Exiting** is known only once a track has ended: :func:`label_exits` relabels the end of
  each track that stops before the sequence's end, host-side, after tracking.
* **Zones** (a departure, host-side like the exits): a track that ends away from every
  entry/exit zone was lost, not gone; one that starts away from every zone was found
  again, not born. The zones are learned from the run's own output rows
  (:func:`rows_at_zones`: :func:`~jaxtrack.context.zones.learn_zones` on the tracks' start
  and end foot points, the clusters inside the hull of the others dropped, as the fusion
  tracker's zones); only a track ending in a zone is labelled exiting, and a track starting
  outside every zone loses its online ``ENTERING`` rows (:func:`unlabel_entries`). Without
  zones (too few track ends) every end is an exit, as before. Development scenes, with the
  lost-tracker change: detections 0.66 / 0.82 -> 0.75 / 0.81 (exit precision 0.69 -> 0.91),
  blobs 0.27 / 0.70 -> 0.30 / 0.70 (0.26 -> 0.34); a foot point within 3 % of the image
  diagonal of a zone instead of inside it: 0.74 / 0.82 and 0.29 / 0.70.
* **Passages** (a departure, host-side like the zones, :func:`moving_ends`): a person who
  enters or leaves the scene walks. A track whose foot point moves less than
  :data:`MIN_PASSAGE_SPEED` (a quarter of its box height) per second over its first second
  does not enter (its ``ENTERING`` rows become ``SINGLE``), and one that moves less over its
  last second does not exit. A quarter of a height a second is about 0.4 m/s for a 1.7 m
  person, well below walking pace (1.2-1.4 m/s, 0.7-0.8 heights a second); the threshold
  was not searched. What stops in place is clutter (a swaying tree's blob), a group blob
  that split, or a person who stood: none enters or exits. Development scenes (synthetic
  video seeds 0-2, 4-6 and 168-173, session 47), event precision / recall over the four
  kinds: detections 0.835 / 0.782 -> 0.839 / 0.782, blobs 0.376 / 0.661 -> 0.404 / 0.649
  (exit precision 0.40 -> 0.49; of the blobs' unmatched exits 61 % moved less than 0.3
  heights in their last second, of the matched ones 8 %); 0.15 and 0.4 heights a second
  gave 0.393 / 0.657 and 0.419 / 0.646 on the blobs.
* **Short episodes** (a departure from the paper, host-side like the exits,
  :func:`drop_short_groups`): the collision map of jittering estimates flickers, and every
  flicker is a group and a split the paper's machine reports. In the written events, a run
  of ``grouping`` / ``grouped`` rows shorter than :data:`MIN_GROUP_SECONDS` takes the state
  of the row before it (``single`` at a track's start), and a shorter run of other rows
  between two such runs takes the group's state. A short episode at a track's end is
  dropped too, so that the track may then be labelled exiting. Chosen on the development
  scenes (synthetic video seeds 0-2, 25 fps; event precision / recall over the four kinds,
  25 frames tolerance). A prototype applied to the labelled rows, runs shorter than 1 / 3 /
  5 / 8 / 12 / 16 / 25 frames dropped: on the scenes' detections 0.37 / 0.53 / 0.58 / 0.62
  / 0.66 / 0.70 / 0.73 and 0.86 / 0.83 / 0.81 / 0.81 / 0.80 / 0.78 / 0.76; on their
  background-subtraction blobs 0.19 / 0.20 / 0.21 / 0.23 / 0.27 / 0.31 / 0.35 and 0.54 /
  0.53 / 0.51 / 0.49 / 0.49 / 0.49 / 0.45. Half a second (12 frames at 25 fps) is the
  longest that kept the detections' recall at 0.8. As implemented (before the exits are
  labelled), at 12 frames: detections 0.37 / 0.86 -> 0.65 / 0.81, blobs 0.19 / 0.54 ->
  0.24 / 0.54; keeping a short episode at a track's end instead gave 0.65 / 0.80 and 0.22
  / 0.49.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from jaxtrack.context.activity import foot_points
from jaxtrack.context.zones import learn_zones, zone_distance
from jaxtrack.errors import InputError

#: Event codes (values of the per-tracker state); ``EVENT_NAMES[code]`` is the code's name.
SINGLE, GROUPING, GROUPED, SPLITTING, ENTERING, EXITING = range(6)
EVENT_NAMES = ("single", "grouping", "grouped", "splitting", "entering", "exiting")
#: Default smallest collision overlap (fraction of the smaller box). Chosen on the dev video
#: seeds 0-2 with ground-truth boxes: the scripted group onsets are all found at 0.1, 60% at
#: 0.3, 40% at 0.7 (people overlap only partly while crossing).
DEFAULT_MIN_OVERLAP = 0.1
#: Default frames a new tracker is ``ENTERING`` and a leaving one ``EXITING``: 1 s at 25 fps.
DEFAULT_ENTERING_FRAMES = 25
DEFAULT_EXITING_FRAMES = 25
#: Slowest entry or exit, box heights per second, over a track's first or last
#: :data:`PASSAGE_SECONDS` (:func:`moving_ends`; module docstring, "Passages").
MIN_PASSAGE_SPEED = 0.25
PASSAGE_SECONDS = 1.0
#: Shortest group episode (and shortest break inside one) reported, seconds
#: (:func:`drop_short_groups`; module docstring).
MIN_GROUP_SECONDS = 0.5


class EventParams(NamedTuple):
    """Parameters of the event machine (a PyTree of scalar arrays).

    Attributes:
        min_overlap: smallest ``intersection / smaller box area`` of a collision, in ``(0, 1]``.
        entering_frames: frames (from a tracker's birth) during which a non-colliding new
            tracker is ``ENTERING``; integer.
    """

    min_overlap: Float[Array, ""]
    entering_frames: Int[Array, ""]


def default_event_params() -> EventParams:
    """:data:`DEFAULT_MIN_OVERLAP` and :data:`DEFAULT_ENTERING_FRAMES` as arrays."""
    return EventParams(
        min_overlap=jnp.asarray(DEFAULT_MIN_OVERLAP, jnp.float32),
        entering_frames=jnp.asarray(DEFAULT_ENTERING_FRAMES, jnp.int32),
    )


def collision_map(
    boxes: Float[Array, "max_trackers 4"],
    alive: Bool[Array, " max_trackers"],
    min_overlap: Float[Array, ""],
) -> Bool[Array, "max_trackers max_trackers"]:
    """Which pairs of live trackers collide (module docstring; Hierarchical Sec. 5.5).

    Args:
        boxes: ``(x, y, w, h)`` of each slot; dead slots may hold anything finite.
        alive: True for a live tracker.
        min_overlap: smallest ``|b_i ^ b_j| / min(|b_i|, |b_j|)`` of a collision.

    Returns:
        Symmetric ``[S, S]`` map, False on the diagonal and in rows / columns of dead slots.
    """
    low, high = boxes[:, :2], boxes[:, :2] + boxes[:, 2:]
    sides = jnp.minimum(high[:, None], high[None]) - jnp.maximum(low[:, None], low[None])
    intersection = jnp.prod(jnp.clip(sides, 0.0), axis=-1)
    area = jnp.prod(jnp.abs(boxes[:, 2:]), axis=-1)
    smaller = jnp.maximum(jnp.minimum(area[:, None], area[None]), jnp.finfo(boxes.dtype).tiny)
    overlap = (intersection > 0) & (intersection >= min_overlap * smaller)
    both = alive[:, None] & alive[None]
    return overlap & both & ~jnp.eye(boxes.shape[0], dtype=bool)


def is_group_birth(
    collisions: Bool[Array, "max_trackers max_trackers"],
    born: Bool[Array, " max_trackers"],
) -> Bool[Array, " max_trackers"]:
    """Whether each new-born tracker represents a group (Hierarchical Sec. 5.1).

    A tracker born on this frame that collides with two or more existing (not new-born)
    trackers is a group tracker.

    Args:
        collisions: the frame's :func:`collision_map`.
        born: True for the trackers born on this frame.

    Returns:
        ``[S]``, True for a group birth.
    """
    existing = jnp.sum(collisions & ~born[None], axis=1)
    return born & (existing >= 2)


def event_step(
    previous: Int[Array, " max_trackers"],
    collisions: Bool[Array, "max_trackers max_trackers"],
    group: Bool[Array, " max_trackers"],
    alive: Bool[Array, " max_trackers"],
    age: Int[Array, " max_trackers"],
    reassociated: Bool[Array, " max_trackers"],
    params: EventParams,
) -> Int[Array, " max_trackers"]:
    """One frame of the event machine (module docstring; Hierarchical Sec. 5.5).

    Args:
        previous: each slot's state on the previous frame (any value for a new-born slot).
        collisions: this frame's :func:`collision_map`.
        group: True for a confirmed group tracker.
        alive: True for a live tracker.
        age: frames since the tracker's birth (0 on its birth frame, where ``previous`` is
            not read).
        reassociated: True for a tracker re-associated with a lost one (it is not entering).
        params: the machine's parameters.

    Returns:
        ``[S]`` state codes; ``SINGLE`` in dead slots.
    """
    colliding = jnp.any(collisions, axis=1)
    with_group = jnp.any(collisions & group[None], axis=1)
    was_grouped = (previous == GROUPED) | (previous == SPLITTING)
    since_birth = (age == 0) | (previous == ENTERING)
    entering = (age < params.entering_frames) & since_birth & ~reassociated
    alone = jnp.where(entering, ENTERING, SINGLE)
    together = jnp.where(was_grouped, SPLITTING, GROUPING)
    state = jnp.where(colliding, jnp.where(with_group, GROUPED, together), alone)
    return jnp.where(alive, state, SINGLE).astype(jnp.int32)


def label_exits(
    frames: np.ndarray,
    ids: np.ndarray,
    events: np.ndarray,
    last_frame: int,
    exiting_frames: int = DEFAULT_EXITING_FRAMES,
    at_zone: np.ndarray | None = None,
) -> np.ndarray:
    """Marks the end of each track that leaves before the sequence's end as ``EXITING``.

    Host-side, after tracking. For each identity whose last row is on frame ``L <
    last_frame`` and is ``SINGLE`` or ``ENTERING`` there (and, with ``at_zone``, lies in an
    entry/exit zone), the trailing run of its ``SINGLE`` / ``ENTERING`` rows with frames in
    ``L - exiting_frames < f <= L`` becomes ``EXITING``. A track that ends in a group
    (grouping, grouped, splitting) is not exiting, nor one lost away from every zone.

    Args:
        frames: ``[N]`` 1-based frame of each output row.
        ids: ``[N]`` identity of each row (one row per identity and frame).
        events: ``[N]`` state code of each row.
        last_frame: the sequence's last frame.
        exiting_frames: length of the exit window, frames (>= 1).
        at_zone: ``[N]`` whether each row's foot point lies in an entry/exit zone
            (:func:`rows_at_zones`); None: every row does.

    Returns:
        A relabelled copy of ``events``.
    """
    out = np.array(events, copy=True)
    frames, ids = np.asarray(frames), np.asarray(ids)
    alone = np.isin(out, (SINGLE, ENTERING))
    for rows in _identity_rows(frames, ids):
        end = frames[rows[-1]]
        if end >= last_frame or (at_zone is not None and not at_zone[rows[-1]]):
            continue
        for row in rows[::-1]:
            if not alone[row] or frames[row] <= end - exiting_frames:
                break
            out[row] = EXITING
    return out


def unlabel_entries(
    frames: np.ndarray, ids: np.ndarray, events: np.ndarray, at_zone: np.ndarray
) -> np.ndarray:
    """Turns the ``ENTERING`` rows of each track that starts away from every entry/exit
    zone into ``SINGLE`` (host-side, after tracking; module docstring, "Zones").

    Args:
        frames: ``[N]`` 1-based frame of each row (one row per identity and frame).
        ids: ``[N]`` identity of each row.
        events: ``[N]`` state codes.
        at_zone: ``[N]`` whether each row's foot point lies in an entry/exit zone
            (:func:`rows_at_zones`).

    Returns:
        A relabelled copy of ``events``.
    """
    out = np.array(events, copy=True)
    for rows in _identity_rows(np.asarray(frames), np.asarray(ids)):
        if not at_zone[rows[0]]:
            out[rows[out[rows] == ENTERING]] = SINGLE
    return out


def moving_ends(
    frames: np.ndarray,
    ids: np.ndarray,
    boxes: np.ndarray,
    frame_rate: float,
    min_speed: float = MIN_PASSAGE_SPEED,
    window_seconds: float = PASSAGE_SECONDS,
) -> np.ndarray:
    """Whether each output row may be a track's entry or exit by its motion (module
    docstring, "Passages"): False on a track's first row when its foot point moves less than
    ``min_speed`` box heights per second over the track's first ``window_seconds`` (its
    whole length if shorter), False on its last row likewise over its last ones, True on
    every other row. A track of one row neither enters nor exits.

    Args:
        frames: ``[N]`` 1-based frame of each row (one row per identity and frame).
        ids: ``[N]`` identity of each row.
        boxes: ``[N, 4]`` ``(x, y, w, h)`` of each row.
        frame_rate: frames per second (> 0).
        min_speed: slowest passage, box heights per second.
        window_seconds: length of the measured start and end of a track, seconds.
    """
    frames, ids = np.asarray(frames), np.asarray(ids)
    boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
    feet = foot_points(boxes)
    window = max(1.0, window_seconds * frame_rate)
    moving = np.ones(len(frames), bool)
    for rows in _identity_rows(frames, ids):
        for end, part in (
            (rows[0], rows[frames[rows] - frames[rows[0]] <= window]),
            (rows[-1], rows[frames[rows[-1]] - frames[rows] <= window]),
        ):
            elapsed = (frames[part[-1]] - frames[part[0]]) / frame_rate
            height = float(np.median(boxes[part, 3]))
            shift = float(np.linalg.norm(feet[part[-1]] - feet[part[0]]))
            fast = elapsed > 0 and height > 0 and shift >= min_speed * height * elapsed
            moving[end] &= fast
    return moving


def rows_at_zones(
    frames: np.ndarray,
    ids: np.ndarray,
    boxes: np.ndarray,
    span: tuple[int, int],
    image_size: tuple[float, float],
) -> np.ndarray | None:
    """Whether each output row's foot point lies in an entry/exit zone learned from the
    output itself (module docstring, "Zones").

    The zones are :func:`~jaxtrack.context.zones.learn_zones`'s (default parameters) on the
    rows' own trajectories over ``span``: clusters of at least three track starts and ends,
    those inside the hull of the others dropped (a person cannot come or go in the middle of
    the scene).

    Args:
        frames: ``[N]`` 1-based frame of each row.
        ids: ``[N]`` identity of each row.
        boxes: ``[N, 4]`` ``(x, y, w, h)``.
        span: ``(first, last)`` frames of the run.
        image_size: ``(width, height)`` in pixels.

    Returns:
        ``[N]`` booleans, or None when no zone was found (too few track ends to cluster):
        then every place counts as a zone.
    """
    boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
    try:
        zones = learn_zones(frames, ids, boxes, span, *image_size).scene.boxes
    except InputError:  # no track starts or ends inside the span
        return None
    if not len(zones):
        return None
    # in a zone as the fusion tracker's regions read it (fusion_voting.point_regions)
    return np.asarray(zone_distance(zones, foot_points(boxes))) == 0.0


def drop_short_groups(
    frames: np.ndarray, ids: np.ndarray, events: np.ndarray, min_frames: int
) -> np.ndarray:
    """Removes group episodes and breaks shorter than ``min_frames`` from written events.

    Host-side, after tracking (module docstring, "Short episodes"). For each identity, in
    frame order: a run of fewer than ``min_frames`` rows that are not ``GROUPING`` /
    ``GROUPED``, between two runs that are, takes the state of the row before it; then a
    run of fewer than ``min_frames`` ``GROUPING`` / ``GROUPED`` rows takes the state of the
    row before it (``SINGLE`` when the run starts the track).

    Args:
        frames: ``[N]`` 1-based frame of each row (one row per identity and frame).
        ids: ``[N]`` identity of each row.
        events: ``[N]`` state codes.
        min_frames: shortest run kept; 1 or less keeps every run.

    Returns:
        A relabelled copy of ``events``.
    """
    out = np.array(events, copy=True)
    if min_frames <= 1:
        return out
    frames, ids = np.asarray(frames), np.asarray(ids)
    for rows in _identity_rows(frames, ids):
        for inside in (False, True):  # first fill short breaks, then drop short groups
            grouped = np.isin(out[rows], (GROUPING, GROUPED))
            edges = np.flatnonzero(np.diff(grouped.astype(np.int8))) + 1
            starts, stops = np.r_[0, edges], np.r_[edges, len(rows)]
            for start, stop in zip(starts, stops, strict=True):
                if grouped[start] != inside or stop - start >= min_frames:
                    continue
                if not inside and (start == 0 or stop == len(rows)):
                    continue  # a break must lie between two group runs
                out[rows[start:stop]] = out[rows[start - 1]] if start > 0 else SINGLE
    return out


def _identity_rows(frames: np.ndarray, ids: np.ndarray):
    """Each identity's row indices, in frame order (identities in increasing order)."""
    for identity in np.unique(ids):
        rows = np.flatnonzero(ids == identity)
        yield rows[np.argsort(frames[rows], kind="stable")]
