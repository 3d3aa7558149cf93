"""Fusion's voting initiation/termination and its calibration (Fusion Sec. 3.1; SPEC section 3).

A detection without a target opens a *hypothesis*; it becomes a target after ``th_init``
consecutive supported frames, and a target ends after ``th_term`` consecutive frames without
support. Both thresholds are calibrated on a training span against the ground truth, and
adjusted per region of the scene (activity mask and entry/exit zones,
:mod:`jaxtrack.context.zones`).

Calibration (host-side NumPy), the choices the paper leaves open:

* **False positives** (:func:`false_positive_runs`). A detection is *matched* when the
  per-frame maximum-IoU one-to-one assignment to the gt boxes (every gt row, the ignored
  ``conf = 0`` ones included: a detection on an ignored person is no false positive) pairs it
  with IoU ``>= match_iou`` (0.5). Unmatched detections are linked from frame ``t`` to frame
  ``t + 1`` by the same assignment with IoU ``>= link_iou`` (0.3); a maximal chain is a
  false-positive *run*, its length the number of frames it spans, its place the foot point
  of its first box.
* **Initiation** (:func:`calibrate_init`). A run of length ``L`` makes a target iff
  ``L >= th_init``; ``th_init`` is the smallest integer with
  ``#{runs: L < th_init} >= reject * #runs`` (``reject = 0.99``: "at least 99% of the FPs
  eliminated").
* **Initiation by cost** (a departure, opt-in: ``FusionConfig.init_rule = "cost"``;
  :func:`initiation_runs`, :func:`calibrate_init_cost`). The 99 % rule looks at the false
  positives alone, so a few long false-positive runs (a blob on half a person, a shadow)
  set a long vote that every true target then waits through. The cost rule also counts
  what a long vote costs: each true target's first detected run of ``S`` frames (matched
  at the tracker's support gate) is missed on its first ``min(S, th_init - 1)`` frames,
  and each false-positive run of ``L`` frames is a false target on ``max(0, L - th_init +
  1)``; ``th_init`` minimises the sum on the training span (per region, with the same
  clamping). Without targets it rejects every run, as the share rule at 100 %.
* **Termination** (:func:`detection_gaps`, :func:`calibrate_term`). The analogue on the true
  targets: a *gap* is a maximal stretch of consecutive gt rows of one trajectory
  (``conf != 0``) that no detection matches (the same one-to-one assignment, at IoU
  ``>= match_iou``: the Fusion tracker calibrates with its own support gate, IoU 0.3, since
  a detection that close supports the target in its vote; see below); a gap of length
  ``g`` ends the target iff
  ``g >= th_term``, so ``th_term`` is the smallest integer with
  ``#{gaps: g < th_term} >= keep * #gaps`` (``keep = 0.99``), the gap's place the foot point of
  its first unmatched gt box. Frames missing from the gt itself are not gaps. Gaps at IoU
  0.5 on background-subtraction blobs (a person's blob with its shadow, or two people's, is
  below 0.5 but inside the gate) counted frames the tracker is supported as unsupported:
  on the development scenes (synthetic video seeds 0-2 and 4-6, blobs), the tracker's gate
  instead of 0.5 raised the Fusion tracker's IDF1 on 3 of the 6 and lowered it on none
  (mean 51.4 -> 52.5 %); on the scenes' simulated detections and on PETS09-S2L1 1:397
  (MOT15 detections and blobs) the thresholds and results were unchanged.
* **Regions** (:func:`point_regions`, :func:`region_thresholds`). A point lies in a ZONE when
  inside an entry/exit zone box, else in the ACTIVE area when the activity mask holds it,
  else in the INACTIVE area. Each region's threshold is the same statistic over the runs
  (gaps) whose place lies in it, a region without any taking the global value; the paper's
  directions are then enforced: ``th_init`` is ``max(own, global)`` in the inactive area and
  ``min(own, global)`` in zones; ``th_term`` is ``min(own, global)`` in both.

The per-frame state machine (:func:`voting_step`) is pure JAX over ``S`` fixed slots.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from jaxtrack.context.activity import foot_points, in_active_area
from jaxtrack.context.zones import SceneZones, zone_distance
from jaxtrack.errors import InputError
from jaxtrack.metrics.matching import assign_frames, box_similarity, build_pairs
from jaxtrack.types import MotTable

#: Regions of the scene (values of :func:`point_regions`, indices of the threshold tables).
ACTIVE, INACTIVE, ZONE = range(3)
#: Slot status codes of :class:`VotingState`; ``STATUS_NAMES[code]`` is the code's name.
EMPTY, TENTATIVE, TARGET, ENDED = range(4)
STATUS_NAMES = ("empty", "tentative", "target", "ended")
#: Smallest IoU of a detection matching a gt box.
MATCH_IOU = 0.5
#: Smallest IoU linking an unmatched detection to one in the next frame.
LINK_IOU = 0.3
#: Share of false-positive runs (gt gaps) shorter than the calibrated threshold.
SHARE = 0.99


class Runs(NamedTuple):
    """Runs of frames (false-positive runs or detection gaps) and where each starts.

    Attributes:
        lengths: ``[num_runs]`` frames spanned by each run (>= 1).
        points: ``[num_runs, 2]`` foot point ``(x, y)`` of each run's first box.
    """

    lengths: np.ndarray
    points: np.ndarray


class Thresholds(NamedTuple):
    """Voting thresholds per region, indexed by ``ACTIVE``, ``INACTIVE``, ``ZONE``.

    Attributes:
        init: ``[3]`` ``th_init`` of each region.
        term: ``[3]`` ``th_term`` of each region.
    """

    init: np.ndarray
    term: np.ndarray


class VotingState(NamedTuple):
    """Voting counters of ``S`` hypothesis slots (the scan carry).

    Attributes:
        status: ``[S]`` ``EMPTY``, ``TENTATIVE``, ``TARGET`` or ``ENDED``.
        support: ``[S]`` consecutive supported frames up to now.
        missed: ``[S]`` consecutive frames without support up to now.
    """

    status: Int[Array, " num_slots"]
    support: Int[Array, " num_slots"]
    missed: Int[Array, " num_slots"]


def _match(
    frame_a: np.ndarray,
    boxes_a: np.ndarray,
    frame_b: np.ndarray,
    boxes_b: np.ndarray,
    min_iou: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame maximum-IoU one-to-one pairs with IoU >= ``min_iou`` of two tables.

    ``frame_a``, ``frame_b`` are 0-based frame indices; rows need not be sorted. Returns the
    paired rows ``(rows_a, rows_b)`` (:func:`~jaxtrack.metrics.matching.assign_frames`).
    """
    if not 0.0 < min_iou <= 1.0:
        raise InputError(f"an IoU threshold must be in (0, 1], got {min_iou}")
    order_a = np.argsort(frame_a, kind="stable")
    order_b = np.argsort(frame_b, kind="stable")
    num_frames = int(max(frame_a.max(initial=-1), frame_b.max(initial=-1))) + 1
    pairs = build_pairs(frame_a[order_a], frame_b[order_b], num_frames)
    score = box_similarity(boxes_a[order_a][pairs.gt_row], boxes_b[order_b][pairs.tracker_row])
    candidate = score >= min_iou
    score = np.where(candidate, score, 0.0)
    matched = assign_frames(pairs, score, candidate, (frame_a.size, frame_b.size))
    return order_a[pairs.gt_row[matched]], order_b[pairs.tracker_row[matched]]


def _matched_rows(det: MotTable, gt: MotTable, gt_rows: np.ndarray, match_iou: float):
    """Boolean masks of the detections and of the rows ``gt_rows`` of gt that are matched."""
    det_rows, matched_gt = _match(
        det.frames - 1, det.boxes, gt.frames[gt_rows] - 1, gt.boxes[gt_rows], match_iou
    )
    det_matched = np.zeros(len(det), bool)
    det_matched[det_rows] = True
    gt_matched = np.zeros(gt_rows.size, bool)
    gt_matched[matched_gt] = True
    return det_matched, gt_matched


def false_positive_runs(
    det: MotTable, gt: MotTable, match_iou: float = MATCH_IOU, link_iou: float = LINK_IOU
) -> Runs:
    """Runs of consecutive frames in which an unmatched detection persists (module doc).

    Args:
        det: the detections of the training span.
        gt: its ground truth (every row, ignored ones included, can match a detection).
        match_iou: smallest IoU of a detection matching a gt box.
        link_iou: smallest IoU linking an unmatched detection to one in the next frame.

    Returns:
        The runs and the foot points of their first boxes, ordered by first frame.

    Raises:
        InputError: an IoU threshold outside ``(0, 1]``.
    """
    det_matched, _ = _matched_rows(det, gt, np.arange(len(gt)), match_iou)
    rows = np.flatnonzero(~det_matched)
    rows = rows[np.argsort(det.frames[rows], kind="stable")]
    frames, boxes = det.frames[rows], det.boxes[rows]
    later = frames >= 2  # a row of frame t + 1 is compared in frame t's block
    earlier_rows, later_rows = _match(frames - 1, boxes, frames[later] - 2, boxes[later], link_iou)
    successor = np.full(rows.size, -1)
    successor[earlier_rows] = np.flatnonzero(later)[later_rows]
    length = np.ones(rows.size, np.int64)
    for row in range(rows.size - 1, -1, -1):  # successors lie later in frame order
        if successor[row] >= 0:
            length[row] += length[successor[row]]
    first = np.ones(rows.size, bool)
    first[successor[successor >= 0]] = False
    return Runs(lengths=length[first], points=foot_points(boxes[first]))


def _target_rows(det: MotTable, gt: MotTable, match_iou: float):
    """The gt target rows (``conf != 0``) by trajectory then frame, their identities, and
    whether a detection matches each (:func:`_matched_rows`, the targets alone)."""
    targets = np.flatnonzero(gt.confs != 0)
    targets = targets[np.lexsort((gt.frames[targets], gt.ids[targets]))]
    _, matched = _matched_rows(det, gt, targets, match_iou)
    return targets, gt.ids[targets], matched


def detection_gaps(det: MotTable, gt: MotTable, match_iou: float = MATCH_IOU) -> Runs:
    """Stretches of consecutive gt rows of one trajectory that no detection matches.

    Only gt rows with ``conf != 0`` (the targets) count; the detections are matched to them
    alone.

    Args:
        det: the detections of the training span.
        gt: its ground truth.
        match_iou: smallest IoU of a detection matching a gt box.

    Returns:
        The gaps and the foot points of their first unmatched gt boxes, by trajectory then
        frame.

    Raises:
        InputError: an IoU threshold outside ``(0, 1]``.
    """
    targets, ids, matched = _target_rows(det, gt, match_iou)
    starts, lengths = _flag_runs(~matched, ids)
    return Runs(lengths=lengths, points=foot_points(gt.boxes[targets[starts]]))


def _flag_runs(flags: np.ndarray, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Maximal runs of True ``flags`` within each identity of ``ids`` (rows ordered by
    identity, then frame): a mask of each run's first row and the runs' lengths, in order."""
    starts = flags & np.concatenate([[True], (ids[1:] != ids[:-1]) | ~flags[:-1]])
    run_index = np.cumsum(starts) - 1
    lengths = np.bincount(run_index[flags], minlength=int(starts.sum()))
    return starts, lengths.astype(np.int64)


def initiation_runs(det: MotTable, gt: MotTable, match_iou: float = MATCH_IOU) -> Runs:
    """Each true target's first run of detected frames: what a vote must accept.

    Per trajectory of the gt targets (``conf != 0``), matched to the detections as in
    :func:`detection_gaps`: the consecutive matched rows from its first matched one. A
    trajectory no detection matches has no run.

    Args:
        det: the detections of the training span.
        gt: its ground truth.
        match_iou: smallest IoU of a detection matching a gt box.

    Returns:
        The runs (lengths in rows) and the foot points of their first matched gt boxes.

    Raises:
        InputError: an IoU threshold outside ``(0, 1]``.
    """
    targets, ids, matched = _target_rows(det, gt, match_iou)
    starts, lengths = _flag_runs(matched, ids)
    run_ids = ids[starts]
    first = np.ones(run_ids.size, bool)  # each identity's first run
    first[1:] = run_ids[1:] != run_ids[:-1]
    boxes = gt.boxes[targets[starts][first]].reshape(-1, 4)
    return Runs(lengths=lengths[first], points=foot_points(boxes))


def calibrate_init_cost(run_lengths: np.ndarray, start_lengths: np.ndarray) -> int:
    """``th_init`` that makes the fewest errors on the training span (a departure).

    A false-positive run of ``L`` frames is a false target on its ``max(0, L - th + 1)``
    frames from the ``th``-th on; a true target whose first detected run lasts ``S`` frames
    is missed on its first ``min(S, th - 1)``. ``th_init`` minimises the sum of both counts
    (the smallest such ``th >= 1``): the false-positive rule of :func:`calibrate_init` with
    the price of a late start set against it.

    Args:
        run_lengths: ``[num_runs]`` false-positive run lengths (:func:`false_positive_runs`).
        start_lengths: ``[num_targets]`` first-run lengths (:func:`initiation_runs`).

    Returns:
        ``th_init >= 1``.

    Raises:
        InputError: no false-positive runs and no targets.
    """
    runs = np.asarray(run_lengths, np.int64).reshape(-1)
    starts = np.asarray(start_lengths, np.int64).reshape(-1)
    if runs.size + starts.size == 0:
        raise InputError("no false-positive runs and no targets to calibrate on")
    candidates = np.arange(1, max(runs.max(initial=0), starts.max(initial=0)) + 2)
    false = np.maximum(runs[None, :] - candidates[:, None] + 1, 0).sum(axis=1)
    late = np.minimum(starts[None, :], candidates[:, None] - 1).sum(axis=1)
    return int(candidates[np.argmin(false + late)])


def _shorter_share_threshold(lengths: np.ndarray, share: float, what: str) -> int:
    """Smallest integer ``th`` with ``#{l < th} >= share * #lengths``."""
    if not 0.0 < share <= 1.0:
        raise InputError(f"the share must be in (0, 1], got {share}")
    lengths = np.sort(np.asarray(lengths, np.int64).reshape(-1))
    if lengths.size == 0:
        raise InputError(f"no {what} to calibrate on; use a longer training span")
    # the k = ceil(share n) shortest runs must lie below th: th = lengths[k - 1] + 1
    needed = int(np.ceil(share * lengths.size - 1e-9))
    return int(lengths[needed - 1]) + 1


def calibrate_init(run_lengths: np.ndarray, reject: float = SHARE) -> int:
    """Smallest ``th_init`` such that a share ``reject`` of the false-positive runs is shorter.

    Fusion Sec. 3.1: "at least 99% of the FPs ... eliminated"; a run of ``L`` frames is
    accepted as a target iff ``L >= th_init``.

    Args:
        run_lengths: ``[num_runs]`` lengths (:func:`false_positive_runs`).
        reject: share of the runs to reject, in ``(0, 1]``.

    Returns:
        ``th_init >= 2`` (every run lasts at least one frame).

    Raises:
        InputError: no runs, or ``reject`` outside ``(0, 1]``.
    """
    return _shorter_share_threshold(run_lengths, reject, "false-positive runs")


def calibrate_term(gap_lengths: np.ndarray, keep: float = SHARE) -> int:
    """Smallest ``th_term`` such that a share ``keep`` of the true targets' gaps is shorter.

    The termination analogue of :func:`calibrate_init` (Fusion Sec. 3.1): a target ends after
    ``th_term`` frames without support, so a gap of ``g`` frames ends it iff ``g >= th_term``.

    Args:
        gap_lengths: ``[num_gaps]`` lengths (:func:`detection_gaps`).
        keep: share of the gaps a target must survive, in ``(0, 1]``.

    Returns:
        ``th_term >= 2``.

    Raises:
        InputError: no gaps, or ``keep`` outside ``(0, 1]``.
    """
    return _shorter_share_threshold(gap_lengths, keep, "detection gaps")


def point_regions(
    zone_boxes: Float[Array, "num_zones 4"],
    activity: Bool[Array, "rows columns"],
    cell_size: float,
    points: Float[Array, "*batch 2"],
) -> Int[Array, "*batch"]:
    """Region of each foot point: ``ZONE`` inside a zone box, else ``ACTIVE`` or ``INACTIVE``.

    Pure JAX (jit- and vmap-able); uses :func:`~jaxtrack.context.zones.zone_distance` and
    :func:`~jaxtrack.context.activity.in_active_area`.

    Args:
        zone_boxes: ``[num_zones, 4]`` entry/exit zones ``(x, y, w, h)``.
        activity: ``[rows, columns]`` activity mask.
        cell_size: its cell side, pixels.
        points: ``[..., 2]`` foot points ``(x, y)``.

    Returns:
        ``[...]`` region codes.
    """
    in_zone = zone_distance(zone_boxes, points) == 0.0
    active = in_active_area(activity, cell_size, points)
    return jnp.where(in_zone, ZONE, jnp.where(active, ACTIVE, INACTIVE))


def _regions(scene: SceneZones, found: Runs) -> np.ndarray:
    """The region of each run's place."""
    return np.asarray(
        point_regions(scene.boxes, scene.activity, scene.cell_size, found.points)
    ).reshape(-1)


def _per_region(
    found: Runs, scene: SceneZones, calibrate: Callable[[np.ndarray, float], int], share: float
) -> tuple[np.ndarray, int]:
    """``([3] own threshold of each region, global threshold)``; a region without runs: global."""
    whole = calibrate(found.lengths, share)
    regions = _regions(scene, found)
    own = [
        calibrate(found.lengths[regions == region], share) if np.any(regions == region) else whole
        for region in (ACTIVE, INACTIVE, ZONE)
    ]
    return np.asarray(own, np.int64), whole


def _per_region_cost(runs: Runs, starts: Runs, scene: SceneZones) -> tuple[np.ndarray, int]:
    """:func:`calibrate_init_cost` per region (both kinds of runs placed in it), and over
    the whole span; a region without either kind: the whole span's."""
    whole = calibrate_init_cost(runs.lengths, starts.lengths)
    run_regions, start_regions = _regions(scene, runs), _regions(scene, starts)
    own = [
        calibrate_init_cost(
            runs.lengths[run_regions == region], starts.lengths[start_regions == region]
        )
        if np.any(run_regions == region) or np.any(start_regions == region)
        else whole
        for region in (ACTIVE, INACTIVE, ZONE)
    ]
    return np.asarray(own, np.int64), whole


def region_thresholds(
    runs: Runs, gaps: Runs, scene: SceneZones, share: float = SHARE, starts: Runs | None = None
) -> Thresholds:
    """``th_init`` and ``th_term`` per region (module doc: own statistic, then clamped).

    Args:
        runs: false-positive runs (:func:`false_positive_runs`).
        gaps: detection gaps (:func:`detection_gaps`).
        scene: zones and activity mask (:func:`~jaxtrack.context.zones.learn_zones`).
        share: the ``reject`` / ``keep`` share of both statistics.
        starts: the true targets' first detected runs (:func:`initiation_runs`): when
            given, ``th_init`` is :func:`calibrate_init_cost`'s instead of the share rule's.

    Returns:
        The thresholds, indexed by ``ACTIVE``, ``INACTIVE``, ``ZONE``.

    Raises:
        InputError: the scene has no activity mask, or no runs or no gaps at all.
    """
    if scene.activity is None:
        raise InputError("per-region thresholds need the scene's activity mask")

    if starts is None:
        init, init_whole = _per_region(runs, scene, calibrate_init, share)
    else:
        init, init_whole = _per_region_cost(runs, starts, scene)
    term, term_whole = _per_region(gaps, scene, calibrate_term, share)
    init[INACTIVE] = max(init[INACTIVE], init_whole)
    init[ZONE] = min(init[ZONE], init_whole)
    term[INACTIVE] = min(term[INACTIVE], term_whole)
    term[ZONE] = min(term[ZONE], term_whole)
    return Thresholds(init=init, term=term)


def voting_init(num_slots: int) -> VotingState:
    """``num_slots`` empty slots with zero counters."""
    zeros = jnp.zeros(num_slots, jnp.int32)
    return VotingState(status=zeros + EMPTY, support=zeros, missed=zeros)


def voting_step(
    state: VotingState,
    supported: Bool[Array, " num_slots"],
    th_init: Int[Array, " num_slots"],
    th_term: Int[Array, " num_slots"],
) -> VotingState:
    """One frame of the accumulative vote (Fusion Sec. 3.1), slot by slot.

    With ``s`` = supported this frame (a detection assigned to the slot), counters
    ``support`` (consecutive supported frames) and ``missed`` (consecutive unsupported):

    * ``EMPTY`` or ``ENDED``: supported -> a new hypothesis, ``TENTATIVE`` with
      ``support = 1`` (``TARGET`` at once when ``th_init <= 1``); else ``EMPTY``
      (``ENDED`` lasts one frame: the frame a target ends);
    * ``TENTATIVE``: supported -> ``support + 1``, ``TARGET`` once ``support >= th_init``;
      else the hypothesis is dropped (``EMPTY``: the detections must be consecutive);
    * ``TARGET``: supported -> ``missed = 0``; else ``missed + 1``, ``ENDED`` once
      ``missed >= th_term``.

    Pure JAX, elementwise (jit-able; the thresholds per slot come from its region,
    :func:`point_regions`).

    Args:
        state: the slots' state after the previous frame.
        supported: ``[S]`` whether each slot has support this frame.
        th_init: ``[S]`` initiation threshold of each slot.
        th_term: ``[S]`` termination threshold of each slot.

    Returns:
        The state after this frame.
    """
    status = state.status
    live = (status == TENTATIVE) | (status == TARGET)
    support = jnp.where(supported, jnp.where(live, state.support + 1, 1), 0)
    missed = jnp.where(supported, 0, jnp.where(status == TARGET, state.missed + 1, 0))
    hypothesis = jnp.where(support >= th_init, TARGET, TENTATIVE)
    supported_status = jnp.where(status == TARGET, TARGET, hypothesis)
    unsupported_status = jnp.where(
        status == TARGET, jnp.where(missed >= th_term, ENDED, TARGET), EMPTY
    )
    new_status = jnp.where(supported, supported_status, unsupported_status)
    return VotingState(status=new_status, support=support, missed=missed)
