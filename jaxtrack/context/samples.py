"""Training samples for scene-context learning: birth and clutter events (PHD-context Sec. IV-B).

The learned intensities ``gamma(x) = lambda_s p(x | b)`` and ``kappa(z) = lambda_r p(z | c)``
(PHD-context eq. 12-13) are estimated from *events* seen on a training frame span:

* **Birth events** are the first states ``x = (y1, vy1, y2, vy2, w, h)`` of trajectories:
  the first box's centre and size, and the centre velocity (pixels/frame) fitted by least
  squares to the centres of the trajectory's first ``velocity_frames`` boxes (frame gaps
  included, so a missed frame does not double the speed). Trajectories come from the
  tracker run with uniform intensities (the paper's source) or from the ground truth (rows
  with ``conf == 0`` ignored). Two filters the paper leaves implicit: trajectories that
  start in the first ``warmup_frames`` frames of the span are the population already in
  view (or still being picked up by the tracker), not births, and are dropped; so are
  trajectories shorter than ``min_length`` boxes (their velocity cannot be measured).
* **Clutter events** are detections ``z = (y1, y2, w, h)`` that are not objects of
  interest: detections left unmatched by the per-frame one-to-one mapping to the ground
  truth at IoU 0.5 (:func:`jaxtrack.metrics.vace.detection_mapping`: most pairs, then the
  largest summed IoU; every gt row takes part, so a detection of an ignored object is not
  clutter), detections whose best IoU with the same frame's tracker output is below 0.5
  (never associated with a confirmed track), or detections a user labelled as clutter
  (:mod:`jaxtrack.context.clutter_labels`).
* **Occupancy events** are the states of the targets in view (every
  :data:`OCCUPANCY_STRIDE`-th box of each trajectory, from the same source as the births):
  what the first frame of a run meets, when targets are already in the scene
  (:func:`occupancy_samples`; not in the paper, which starts every run from the birth
  intensity).
* **Badly placed detections of objects are not clutter.** A detection left unmatched that
  still overlaps an object of its frame (a gt box, or a tracker box, by IoU >=
  :data:`OBJECT_OVERLAP`) is that object's detection, placed or sized badly (a part of a
  person, two people in one box, a second box on one person). In the PHD model it is a
  target-generated measurement, not a false alarm of the scene: counting it as clutter puts
  the clutter density (and its magnitude) on the objects' paths, where it then explains the
  detections of real targets away. Such detections are left out of the clutter events (their
  number is recorded, ``EventSamples.object_overlaps``); ``object_overlap=None`` keeps them
  (the rule before issue 15's learner). Measured on the training halves: 73 % of the
  unmatched MOT15 detections of PETS09-S2L1 1:397 overlap a gt box by IoU >= 0.2, 75 % of
  TUD-Stadtmitte 1:89's. True clutter that happens to land on an object is left out too, so
  the clutter magnitude divides by the coverage ``1 - p``, where ``p`` is the chance that a
  clutter box overlaps an object: the share of the kept events that overlap an object of
  other frames of the span (:func:`chance_overlap`; about 4 % on the default synthetic
  scene).

Magnitudes are averages over the frames the events were counted on (PHD-context Sec. IV-B,
:func:`~jaxtrack.context.map_em.estimate_magnitude`): births per frame after the warm-up,
clutter per training frame, or labelled clutter per labelled frame.

Everything here is host-side NumPy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from jaxtrack.boxes import iou_matrix, xywh_to_cxcywh
from jaxtrack.context.map_em import estimate_magnitude
from jaxtrack.metrics.preprocess import prepare_sequence
from jaxtrack.metrics.vace import detection_mapping
from jaxtrack.types import MotTable

if TYPE_CHECKING:
    from jaxtrack.context.clutter_labels import ClutterLabels

#: Default number of first boxes whose centres give a birth event's velocity.
VELOCITY_FRAMES = 5
#: Default number of frames at the start of a span whose trajectory starts are not births.
WARMUP_FRAMES = 5
#: Default minimum number of boxes of a trajectory that yields a birth event.
MIN_LENGTH = 2
#: Default spacing, in boxes of a trajectory, of the occupancy events (the targets in view).
OCCUPANCY_STRIDE = 10
#: IoU at which a detection belongs to a ground-truth object or a track.
IOU_THRESHOLD = 0.5
#: IoU with an object from which an unmatched detection is the object's badly placed
#: detection, not clutter (two equal boxes at IoU 0.2 share a third of their areas).
OBJECT_OVERLAP = 0.2


class EventSamples(NamedTuple):
    """Birth or clutter events of a training span.

    Attributes:
        values: ``[num_events, 6]`` birth states ``(y1, vy1, y2, vy2, w, h)`` or
            ``[num_events, 4]`` clutter measurements ``(y1, y2, w, h)``, in frame order.
        frames: ``[num_events]`` 1-based frame of each event.
        num_frames: frames the events were counted on (the magnitude's denominator).
        source: where the events come from (``"gt"``, ``"tracks"`` or a labels file).
        left_out: ``[len(det_table)]`` booleans over the source's detection table, the
            detections left out because they overlap an object of their frame (badly placed
            detections of objects, see the module docstring; what
            :mod:`jaxtrack.context.target_clutter` learns from); None for a source that
            knows no objects.
        coverage: the share of the scene's events that the source could count: 1, or for
            clutter with objects left out, ``1 - p`` with ``p`` the chance that a clutter
            box overlaps an object (:func:`chance_overlap`), or for occupancy events the
            share of the boxes taken as events (:func:`occupancy_samples`).
    """

    values: np.ndarray
    frames: np.ndarray
    num_frames: int
    source: str
    left_out: np.ndarray | None = None
    coverage: float = 1.0

    @property
    def object_overlaps(self) -> int:
        """Number of detections left out as objects' badly placed detections."""
        return 0 if self.left_out is None else int(np.sum(self.left_out))

    @property
    def count(self) -> int:
        """Number of events."""
        return int(self.values.shape[0])

    @property
    def magnitude(self) -> float:
        """Events per frame, ``lambda = count / (coverage num_frames)`` (0 when no frame was
        counted)."""
        if self.num_frames <= 0:
            return 0.0
        return estimate_magnitude(self.count / self.coverage, self.num_frames)


def first_states(
    frames: np.ndarray,
    ids: np.ndarray,
    boxes: np.ndarray,
    *,
    velocity_frames: int = VELOCITY_FRAMES,
    min_length: int = MIN_LENGTH,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First state of each trajectory: first box centre and size, initial centre velocity.

    The velocity is the least-squares slope of the centre against the frame number over the
    first ``min(velocity_frames, length)`` boxes (exact for constant-velocity motion, gaps
    allowed); a trajectory with one box (``min_length = 1``) gets velocity 0.

    Args:
        frames: ``[num_rows]`` 1-based frame of each box.
        ids: ``[num_rows]`` trajectory identity of each box (unique within a frame).
        boxes: ``[num_rows, 4]`` top-left ``(x, y, w, h)``.
        velocity_frames: boxes used for the velocity (>= 2).
        min_length: trajectories with fewer boxes are skipped (>= 1).

    Returns:
        ``(states, first_frames, track_ids)``: ``[n, 6]`` states ``(y1, vy1, y2, vy2, w,
        h)``, the first frame and identity of each kept trajectory, sorted by first frame
        then identity.

    Raises:
        ValueError: ``velocity_frames < 2`` or ``min_length < 1``.
    """
    if velocity_frames < 2:
        raise ValueError(f"velocity_frames must be >= 2, got {velocity_frames}")
    if min_length < 1:
        raise ValueError(f"min_length must be >= 1, got {min_length}")
    frames, ids, centres = _trajectory_arrays(frames, ids, boxes)
    states, first_frames, track_ids = [], [], []
    for identity, rows in _trajectories(frames, ids):
        if rows.size < min_length:
            continue
        states.append(_state(frames, centres, rows[0], rows[:velocity_frames]))
        first_frames.append(frames[rows[0]])
        track_ids.append(identity)
    states = np.asarray(states, np.float64).reshape(-1, 6)
    first_frames = np.asarray(first_frames, np.int64)
    track_ids = np.asarray(track_ids, np.int64)
    chronological = np.lexsort((track_ids, first_frames))
    return states[chronological], first_frames[chronological], track_ids[chronological]


def birth_samples(
    frames: np.ndarray,
    ids: np.ndarray,
    boxes: np.ndarray,
    span: tuple[int, int],
    source: str,
    *,
    warmup_frames: int = WARMUP_FRAMES,
    velocity_frames: int = VELOCITY_FRAMES,
    min_length: int = MIN_LENGTH,
) -> EventSamples:
    """Birth events: first states of the trajectories that start after the warm-up.

    Args:
        frames: ``[num_rows]`` 1-based frame of each box (all inside ``span``).
        ids: ``[num_rows]`` trajectory identity of each box.
        boxes: ``[num_rows, 4]`` top-left ``(x, y, w, h)``.
        span: ``(first, last)`` training frames, 1-based inclusive.
        source: recorded in the result.
        warmup_frames: trajectories starting in frames ``first .. first + warmup_frames - 1``
            are not births (the population already in view); ``0`` keeps all.
        velocity_frames: see :func:`first_states`.
        min_length: see :func:`first_states`.

    Returns:
        The events; ``num_frames = last - first + 1 - warmup_frames`` (at least 0).

    Raises:
        ValueError: a negative ``warmup_frames``.
    """
    if warmup_frames < 0:
        raise ValueError(f"warmup_frames must be >= 0, got {warmup_frames}")
    first, last = span
    states, first_frames, _ = first_states(
        frames, ids, boxes, velocity_frames=velocity_frames, min_length=min_length
    )
    keep = first_frames >= first + warmup_frames
    return EventSamples(
        values=states[keep],
        frames=first_frames[keep],
        num_frames=max(last - first + 1 - warmup_frames, 0),
        source=source,
    )


def birth_samples_from_gt(gt_table: MotTable, span: tuple[int, int], **options) -> EventSamples:
    """Birth events from ground-truth trajectories (rows with ``conf == 0`` ignored).

    Args:
        gt_table: ground truth of the span.
        span: ``(first, last)`` training frames.
        **options: ``warmup_frames``, ``velocity_frames``, ``min_length`` of
            :func:`birth_samples`.

    Returns:
        The events, source ``"gt"``.
    """
    kept = gt_table.select(~gt_table.ignored)
    return birth_samples(kept.frames, kept.ids, kept.boxes, span, "gt", **options)


def birth_samples_from_tracks(rows: MotTable, span: tuple[int, int], **options) -> EventSamples:
    """Birth events from a tracker's output trajectories.

    Args:
        rows: tracker output (e.g. :func:`jaxtrack.association.offline.finalise_tracks`,
            which keeps each confirmed track from its first estimate on).
        span: ``(first, last)`` training frames.
        **options: ``warmup_frames``, ``velocity_frames``, ``min_length`` of
            :func:`birth_samples`.

    Returns:
        The events, source ``"tracks"``.
    """
    return birth_samples(rows.frames, rows.ids, rows.boxes, span, "tracks", **options)


def occupancy_samples(
    frames: np.ndarray,
    ids: np.ndarray,
    boxes: np.ndarray,
    span: tuple[int, int],
    source: str,
    *,
    stride: int = OCCUPANCY_STRIDE,
    velocity_frames: int = VELOCITY_FRAMES,
) -> EventSamples:
    """Occupancy events: the states of the targets in view, every ``stride``-th box of each
    trajectory (the learned first-frame intensity's events, :mod:`jaxtrack.context.learn`).

    A trajectory's boxes are taken in frame order, its 1st, ``(stride + 1)``-th, ... box
    gives the state ``(y1, vy1, y2, vy2, w, h)``: the box's centre and size, and the centre
    velocity fitted by least squares (as :func:`first_states`) to the ``velocity_frames``
    boxes around it (centred, cut at the trajectory's ends; frame gaps allowed). A
    trajectory of one box gives velocity 0. Taking every box would give the learner hundreds
    of near-copies of each trajectory; ``stride`` boxes apart they are about as many as the
    birth and clutter events.

    Every box counts towards the magnitude: ``coverage`` is the share of the boxes taken as
    events, so that :attr:`EventSamples.magnitude` is the mean number of targets in view per
    frame, ``num_boxes / num_frames``.

    Args:
        frames: ``[num_rows]`` 1-based frame of each box (all inside ``span``).
        ids: ``[num_rows]`` trajectory identity of each box (unique within a frame).
        boxes: ``[num_rows, 4]`` top-left ``(x, y, w, h)``.
        span: ``(first, last)`` training frames, 1-based inclusive.
        source: recorded in the result.
        stride: every ``stride``-th box of a trajectory is an event (>= 1).
        velocity_frames: boxes the velocity is fitted to (>= 2).

    Returns:
        The events in frame order (ties by identity), ``num_frames = last - first + 1``.

    Raises:
        ValueError: ``stride < 1`` or ``velocity_frames < 2``.
    """
    if stride < 1:
        raise ValueError(f"stride must be >= 1, got {stride}")
    if velocity_frames < 2:
        raise ValueError(f"velocity_frames must be >= 2, got {velocity_frames}")
    frames, ids, centres = _trajectory_arrays(frames, ids, boxes)
    before = (velocity_frames - 1) // 2
    states, event_frames, event_ids = [], [], []
    for identity, rows in _trajectories(frames, ids):
        for k in range(0, rows.size, stride):
            low = min(max(k - before, 0), max(rows.size - velocity_frames, 0))
            states.append(_state(frames, centres, rows[k], rows[low : low + velocity_frames]))
            event_frames.append(frames[rows[k]])
            event_ids.append(identity)
    states = np.asarray(states, np.float64).reshape(-1, 6)
    event_frames = np.asarray(event_frames, np.int64)
    chronological = np.lexsort((np.asarray(event_ids, np.int64), event_frames))
    return EventSamples(
        values=states[chronological],
        frames=event_frames[chronological],
        num_frames=span[1] - span[0] + 1,
        source=source,
        coverage=len(states) / len(frames) if len(frames) else 1.0,
    )


def occupancy_samples_from(
    table: MotTable, span: tuple[int, int], source: str, **options
) -> EventSamples:
    """Occupancy events from the trajectories the births come from.

    Args:
        table: the ground truth of the span (``source="gt"``: rows with ``conf == 0``
            ignored) or a tracker's output (``"tracks"``).
        span: ``(first, last)`` training frames.
        source: ``"gt"`` or ``"tracks"``.
        **options: ``stride`` and ``velocity_frames`` of :func:`occupancy_samples`.

    Returns:
        The events, with ``source``.
    """
    kept = table.select(~table.ignored) if source == "gt" else table
    return occupancy_samples(kept.frames, kept.ids, kept.boxes, span, source, **options)


def clutter_samples_from_gt(
    det_table: MotTable,
    gt_table: MotTable,
    span: tuple[int, int],
    iou_threshold: float = IOU_THRESHOLD,
    object_overlap: float | None = OBJECT_OVERLAP,
) -> EventSamples:
    """Clutter events: detections the one-to-one per-frame mapping leaves without a gt box.

    The mapping is :func:`jaxtrack.metrics.vace.detection_mapping` (most pairs with IoU >=
    ``iou_threshold``, then the largest summed IoU). Every gt row takes part, ``conf == 0``
    rows included: a detection of an ignored object is not an object of interest, but not
    a detector error either. An unmatched detection overlapping any gt box of its frame by
    IoU >= ``object_overlap`` is that object's badly placed detection, not clutter.

    Args:
        det_table: detections of the span.
        gt_table: ground truth of the span.
        span: ``(first, last)`` training frames (every row of both tables inside it).
        iou_threshold: minimum IoU of a match.
        object_overlap: IoU with a gt box from which an unmatched detection is left out;
            None keeps every unmatched detection.

    Returns:
        The unmatched detections as ``(y1, y2, w, h)``, source ``"gt"``.
    """

    matched = matched_detections(det_table, gt_table, span, iou_threshold)
    overlapping = _overlaps_objects(det_table, gt_table, object_overlap)
    kept = ~matched & ~overlapping
    return _detection_events(
        det_table,
        kept,
        span,
        "gt",
        ~matched & overlapping,
        _coverage(det_table, kept, gt_table, span, object_overlap),
    )


def matched_detections(
    det_table: MotTable,
    gt_table: MotTable,
    span: tuple[int, int],
    iou_threshold: float = IOU_THRESHOLD,
) -> np.ndarray:
    """Which detections the per-frame one-to-one mapping to the ground truth matches.

    The mapping is :func:`jaxtrack.metrics.vace.detection_mapping` (most pairs with IoU >=
    ``iou_threshold``, then the largest summed IoU), every gt row taking part (``conf == 0``
    rows included).

    Returns:
        ``[len(det_table)]`` booleans.
    """
    every_gt = MotTable.from_arrays(gt_table.frames, gt_table.ids, gt_table.boxes)
    numbered = MotTable.from_arrays(det_table.frames, np.arange(len(det_table)), det_table.boxes)
    data = prepare_sequence(every_gt, numbered, span)
    mapped = detection_mapping(data, iou_threshold)
    # tracker ids are the row numbers 0..n-1, relabelled in increasing order: id == row
    matched = np.zeros(len(det_table), bool)
    matched[data.tracker_id[data.pairs.tracker_row[mapped]]] = True
    return matched


def clutter_samples_from_tracks(
    det_table: MotTable,
    rows: MotTable,
    span: tuple[int, int],
    iou_threshold: float = IOU_THRESHOLD,
    object_overlap: float | None = OBJECT_OVERLAP,
) -> EventSamples:
    """Clutter events: detections whose best IoU with the same frame's tracker boxes is low.

    A detection overlapping no output box by ``iou_threshold`` or more was never
    associated with a confirmed track; one that still overlaps a track's box by IoU >=
    ``object_overlap`` is that object's badly placed detection, not clutter.

    Args:
        det_table: detections of the span.
        rows: tracker output of the span (confirmed tracks).
        span: ``(first, last)`` training frames.
        iou_threshold: IoU from which a detection belongs to a track.
        object_overlap: IoU with a track's box from which an unassociated detection is
            left out; None keeps every unassociated detection.

    Returns:
        The unassociated detections as ``(y1, y2, w, h)``, source ``"tracks"``.
    """
    best = _best_overlaps(det_table, rows)
    unassociated = best < iou_threshold
    overlapping = _overlaps_objects(det_table, rows, object_overlap, best)
    kept = unassociated & ~overlapping
    return _detection_events(
        det_table,
        kept,
        span,
        "tracks",
        unassociated & overlapping,
        _coverage(det_table, kept, rows, span, object_overlap),
    )


def _best_overlaps(det_table: MotTable, objects: MotTable) -> np.ndarray:
    """Each detection's best IoU with the boxes of ``objects`` in its frame (0 if none)."""
    det_frames = np.asarray(det_table.frames)
    object_frames = np.asarray(objects.frames)
    object_boxes = np.asarray(objects.boxes, np.float64)
    best = np.zeros(len(det_table))
    for frame in np.intersect1d(det_frames, object_frames):
        det_rows = np.flatnonzero(det_frames == frame)
        overlaps = iou_matrix(det_table.boxes[det_rows], object_boxes[object_frames == frame])
        best[det_rows] = overlaps.max(axis=1)
    return best


#: Frame shifts (fractions of the span) at which :func:`chance_overlap` looks for objects.
CHANCE_SHIFTS = (0.2, 0.4, 0.6, 0.8)
#: Smallest coverage a clutter magnitude is divided by (objects covering most of the image
#: would otherwise blow the estimate up).
MIN_COVERAGE = 0.5


def chance_overlap(
    boxes: np.ndarray,
    frames: np.ndarray,
    objects: MotTable,
    span: tuple[int, int],
    object_overlap: float,
) -> float:
    """The chance ``p`` that a clutter box lands on an object by IoU >= ``object_overlap``.

    Clutter does not move with the objects, so its boxes overlap an object of an unrelated
    frame as often as they overlap one of their own frame by chance. Each box is compared
    with the objects of the frames :data:`CHANCE_SHIFTS` of the span later (cyclically), and
    ``p`` is the share of (box, shift) pairs that overlap. The boxes given are the clutter
    kept (none of them overlaps an object of its own frame), so a clutter source where
    objects often pass counts as often as where they do not.

    Args:
        boxes: ``[n, 4]`` top-left ``(x, y, w, h)`` clutter boxes.
        frames: ``[n]`` their frames, inside ``span``.
        objects: the objects' boxes (gt rows or tracker output).
        span: ``(first, last)`` frames.
        object_overlap: the IoU from which a box overlaps an object.

    Returns:
        ``p`` in ``[0, 1]`` (0 without boxes).
    """
    if len(frames) == 0:
        return 0.0
    first, last = span
    length = last - first + 1
    hits = []
    for fraction in CHANCE_SHIFTS:
        shifted = first + (np.asarray(frames) - first + round(fraction * length)) % length
        moved = MotTable.from_arrays(shifted, np.arange(len(shifted)), boxes)
        hits.append(_best_overlaps(moved, objects) >= object_overlap)
    return float(np.mean(np.concatenate(hits)))


def _coverage(det_table, kept, objects, span, object_overlap) -> float:
    """``max(1 - chance_overlap, MIN_COVERAGE)`` of the kept detections (1 without the rule)."""
    if object_overlap is None:
        return 1.0
    boxes = np.asarray(det_table.boxes, np.float64)[kept]
    p = chance_overlap(boxes, np.asarray(det_table.frames)[kept], objects, span, object_overlap)
    return max(1.0 - p, MIN_COVERAGE)


def _overlaps_objects(
    det_table: MotTable,
    objects: MotTable,
    object_overlap: float | None,
    best: np.ndarray | None = None,
) -> np.ndarray:
    """Detections overlapping a box of ``objects`` in their frame by IoU >= ``object_overlap``."""
    if object_overlap is None:
        return np.zeros(len(det_table), bool)
    best = _best_overlaps(det_table, objects) if best is None else best
    return best >= object_overlap


def clutter_samples_from_labels(
    labels: ClutterLabels, span: tuple[int, int], source: str
) -> EventSamples:
    """Clutter events labelled by a user (:mod:`jaxtrack.context.clutter_labels`).

    Only labels and labelled frames inside ``span`` count; the magnitude is the clutter
    count per labelled frame (frames the user looked at, whether or not they held clutter).

    Args:
        labels: the labels (``frames``, ``boxes`` top-left, ``labelled_frames``).
        span: ``(first, last)`` training frames.
        source: recorded in the result (e.g. the labels file).

    Returns:
        The labelled detections as ``(y1, y2, w, h)``, ``num_frames`` = labelled frames in
        the span.
    """
    first, last = span
    frames = np.asarray(labels.frames, np.int64).reshape(-1)
    boxes = np.asarray(labels.boxes, np.float64).reshape(-1, 4)
    inside = (frames >= first) & (frames <= last)
    looked_at = np.unique(np.asarray(labels.labelled_frames, np.int64))
    num_frames = int(np.sum((looked_at >= first) & (looked_at <= last)))
    order = np.argsort(frames[inside], kind="stable")
    return EventSamples(
        values=xywh_to_cxcywh(boxes[inside][order]),
        frames=frames[inside][order],
        num_frames=num_frames,
        source=source,
    )


def _detection_events(
    table: MotTable,
    keep: np.ndarray,
    span: tuple[int, int],
    source: str,
    left_out: np.ndarray,
    coverage: float,
):
    """The kept detections of ``table`` as clutter events in frame order."""
    order = np.argsort(table.frames[keep], kind="stable")
    return EventSamples(
        values=xywh_to_cxcywh(np.asarray(table.boxes, np.float64)[keep][order]),
        frames=np.asarray(table.frames, np.int64)[keep][order],
        num_frames=span[1] - span[0] + 1,
        source=source,
        left_out=left_out,
        coverage=coverage,
    )


def _trajectory_arrays(frames, ids, boxes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(frames, ids, centres)``: int64 frames and identities, ``(cx, cy, w, h)`` boxes."""
    return (
        np.asarray(frames, np.int64).reshape(-1),
        np.asarray(ids, np.int64).reshape(-1),
        xywh_to_cxcywh(np.asarray(boxes, np.float64).reshape(-1, 4)),
    )


def _trajectories(frames: np.ndarray, ids: np.ndarray) -> list[tuple[int, np.ndarray]]:
    """``(identity, rows)`` of each trajectory, identities increasing, rows in frame order."""
    order = np.lexsort((frames, ids))
    unique_ids, starts, lengths = np.unique(ids[order], return_index=True, return_counts=True)
    return [
        (int(identity), order[start : start + length])
        for identity, start, length in zip(unique_ids, starts, lengths, strict=True)
    ]


def _state(frames: np.ndarray, centres: np.ndarray, row: int, window: np.ndarray) -> list:
    """The state ``(y1, vy1, y2, vy2, w, h)`` of box ``row``, its velocity the centres' slope
    over the boxes ``window`` (0 for a single box)."""
    velocity = _slope(frames[window], centres[window, :2]) if window.size > 1 else np.zeros(2)
    cx, cy, w, h = centres[row]
    return [cx, velocity[0], cy, velocity[1], w, h]


def _slope(frames: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """Least-squares slope of ``centres[:, i]`` against ``frames`` (distinct frames)."""
    offsets = frames - frames.mean()
    return offsets @ (centres - centres.mean(axis=0)) / np.sum(offsets**2)
