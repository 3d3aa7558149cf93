"""The Hierarchical tracker (Rowe et al.; SPEC section 4): a managed Kalman bank below,
appearance trackers above, events from a collision map.

One :func:`hierarchical_step` on frame ``k`` (the paper's Fig. 1, top to bottom):

1. **Low level** (Sec. 4, :mod:`~jaxtrack.filters.hier_low`): the frame's blobs (detections)
   are measurements of a constant-velocity Kalman bank; each goes to the nearest track whose
   Mahalanobis gate holds it, orphans start tentative tracks, tracks are confirmed and
   removed by ``|S_k|^1/2`` (and the MSD of their measurements). Beyond the paper, whose
   blobs have no score: a track is confirmed only once it has held a detection scoring at
   least ``confirm_score`` (the PHD tracker's and CMT's rule), and the association cost
   falls by ``2 score_weight logit(score)`` (the detection's log-odds of being a target).
2. **Tracker matching** (Sec. 5.1): a high-level tracker follows one low-level track. When its
   track is removed (a long occlusion, a group), the high-level tracker is *lost*: it keeps
   its appearance model and is propagated by its motion model (constant velocity, the last
   estimate of its track) for at most ``max_lost`` frames.
2b. **Resumption check** (beyond the paper): a track that takes a measurement after coasting
   ``resume_frames`` or more frames may have taken someone else's (a person stepping out
   from behind an occluder where another went in). Its tracker checks the measurement's box
   against its own appearance model with the Sec. 5.4 gate; when no trained pooled feature
   is within the gate, the tracker lets the track go and is lost (propagated from where it
   was), and the track is renamed (a new low-level identity) and treated as confirmed on this
   frame: offered to the lost trackers (except the one that let it go), else a new tracker.
   With ``drift_check`` (off by default) the same check runs for a tracker that is single
   again after colliding, while its collision episode is open (a track the low level moved
   onto a neighbour where people met).
3. **Appearance association** (Sec. 5.4, :mod:`~jaxtrack.filters.hier_appearance`): a
   low-level track confirmed on this frame is first offered to the lost trackers: gated on
   the coincident features' Bhattacharyya distances, it goes to the nearest lost tracker
   within the gate, which keeps its identity. A lost tracker with no candidate in its gate
   tries again on the next frames. A re-association made with a fallback model (step 5) is
   flagged (``unfilled``): the offline output does not interpolate across it.
4. **New trackers**: a confirmed track no lost tracker takes starts a high-level tracker with
   a new identity (the low-level track's); it is a *group* tracker when it is born colliding
   with two or more trackers (Sec. 5.1). Its appearance starts from the frame's histograms.
4b. **Exchanges undone** (beyond the paper, :mod:`~jaxtrack.filters.hier_exchanges`): two
   trackers that collided since they were last both single, and are single again, swap
   their tracks when each one's appearance model is nearer the other's box by
   ``exchange_margin`` (the low level's nearest-measurement association may have exchanged
   two people where they met; no track was lost, so step 3 cannot see it).
5. **Appearance update** (Sec. 5.2-5.3): a tracker whose track is confirmed and measured on
   the frame, that is single (it collides with no other tracker) and not a group tracker,
   re-ranks its 49 colour features against the background model and updates its pool and
   its mean histograms; otherwise its appearance is frozen. Beyond the paper, with
   ``fallback_appearance``: a tracker that has never been single (``HighState.single_model``
   False) updates a *fallback* model while colliding (group trackers only at level 2), used
   only by step 3; steps 2b and 4b never read it, and the tracker's first single frame
   restarts its model.
6. **Events** (Sec. 5.5, :mod:`~jaxtrack.filters.hier_events`): each tracker's state
   (single, grouping, grouped, splitting, entering) from the collision map of the
   estimates, in which a lost tracker's extrapolated box collides with no one (a group
   birth still counts it); entries and exits are labelled offline at learned zones
   (:func:`~jaxtrack.filters.hier_events.label_exits`).

Steps 2b to 5 read the colour histograms of the low-level tracks' boxes on the frame and on
the background image, and only those of live tracks (every read is of a track a tracker
follows, or of a candidate, under masks that discard the others): they are computed for the
live low-level slots only (:func:`~jaxtrack.filters.hier_appearance.live_box_histograms`,
zero in the free slots), at a cost that follows the number of live tracks, not of slots.

The output (:class:`HierarchicalInfo`) is that of the other trackers: ``tracks`` are the
high-level trackers whose low-level track is confirmed and measured on the frame (posterior
boxes), under the high-level identity; ``candidates`` are every measured low-level track,
under its high-level tracker's identity when it has one, else its own. The offline output
(:func:`~jaxtrack.association.offline.finalise_tracks`) therefore keeps a tracker's tentative
frames and interpolates over its occlusions (``max_gap``).

Variants (:data:`VARIANTS`): ``"managed"`` is the low level alone (its confirmed tracks,
their own identities); ``"full"`` is both levels. ``"kalman"``, the Kalman bank of the
baseline (:mod:`~jaxtrack.filters.kalman`), is built by
:mod:`~jaxtrack.filters.hierarchical_tracker`.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int, UInt8

from jaxtrack.appearance.variance_ratio import variance_ratio
from jaxtrack.association.labelling import score_log_odds
from jaxtrack.association.track_table import start_tracks
from jaxtrack.boxes import xywh_to_cxcywh
from jaxtrack.filters.base import Filter
from jaxtrack.filters.hier_appearance import (
    PATCH_SHAPE,
    AppearanceParams,
    AppearanceTable,
    init_table,
    live_box_histograms,
    reset_slots,
    update_appearance,
)
from jaxtrack.filters.hier_events import (
    EventParams,
    collision_map,
    event_step,
    is_group_birth,
)
from jaxtrack.filters.hier_exchanges import exchanges, model_distances, trained_features
from jaxtrack.filters.hier_low import (
    LowInfo,
    LowParams,
    LowState,
    init_low,
    low_boxes,
    low_step,
    low_velocity,
)
from jaxtrack.filters.hier_low_model import box_to_ellipse
from jaxtrack.filters.hier_reassociation import (
    association_distances,
    own_track_gate,
    reassociate,
)
from jaxtrack.filters.score_quantile import confident_score, count_scores, init_counts
from jaxtrack.types import PAD_BOX, FrameInputs, Tracks

#: The variants this module steps (``"kalman"`` is the Kalman baseline's filter).
STEPPED_VARIANTS = ("managed", "full")
#: Features in a tracker's pool: the ``M`` best of the frame and the ``N`` best long-run
#: ones (the paper's ``M = N = 3``).
NUM_CURRENT, NUM_LONGRUN = 3, 3
#: Detection scores are read as probabilities within ``[SCORE_CLIP, 1 - SCORE_CLIP]`` in the
#: low level's association cost (a detector's 1.0 is not certainty).
SCORE_CLIP = 1e-3


def measurements_of(boxes: Float[Array, "D 4"], measurement: str) -> Float[Array, "D m"]:
    """The low level's measurements of detection boxes ``(x, y, w, h)``: ``(cx, cy, w, h)``,
    or the moment-equivalent ellipse ``(cx, cy, major, minor, angle)``
    (:func:`~jaxtrack.filters.hier_low.box_to_ellipse`)."""
    centred = xywh_to_cxcywh(boxes, jnp)
    return box_to_ellipse(centred) if measurement == "ellipse" else centred


def fresh_pool(
    histograms: Float[Array, "T 49 64"], background: Float[Array, "T 49 64"], delta
) -> Int[Array, "T P"]:
    """The pool of a track seen once: its ``M + N`` best features by variance ratio
    (eq. 2-3; with no history the long-run ranking is the current one)."""
    ratios = variance_ratio(histograms, background, delta)
    return jnp.argsort(-ratios, axis=-1)[:, : NUM_CURRENT + NUM_LONGRUN].astype(jnp.int32)


class HierarchicalParams(NamedTuple):
    """The Hierarchical tracker's parameters (a PyTree: vmap over parameter sets).

    Attributes:
        low: the low level's (:class:`~jaxtrack.filters.hier_low.LowParams`).
        appearance: the appearance trackers' (ranking, gating).
        events: the event module's (collision overlap, entering frames).
        max_lost: frames a lost high-level tracker is propagated and offered new tracks
            before it is dropped.
        max_newborn: frames after its start during which a tracker is new-born: a lost
            tracker may still take its track (and merge its identity).
        search_rate: growth per frame lost of the radius, in box heights, within which a
            new track may be a lost tracker's target (the radius is ``h (1 + search_rate *
            lost)``).
        background: the background model's image, RGB ``uint8`` ``[height, width, 3]``
            (:func:`~jaxtrack.pipelines.background.median_background`).
        min_score: detections scoring below this are ignored.
        resume_frames: a followed track that takes a measurement after coasting at least
            this many frames is checked against its tracker's appearance (the module's step
            2b); ``inf``: never.
        confirm_score: a low-level track is confirmed only once it has held a detection
            scoring at least this (0: every track, the paper's rule).
        score_weight: weight of the detections' score log-odds
            (:func:`~jaxtrack.association.labelling.score_log_odds`, clipped at
            :data:`SCORE_CLIP`) in the low level's association cost (0: the paper's cost).
        confirm_quantile: a track is also confirmed by a detection scoring at least this
            quantile of the scores read so far (:mod:`~jaxtrack.filters.score_quantile`).
        exchange_margin: the margin of the exchange check (step 4b; ``inf``: never).
        drift_check: > 0: the drift check of step 2b (0: only tracks resuming after
            coasting are checked).
        fallback_appearance: > 0: a tracker never single learns while colliding (step 5's
            fallback model), used only by the re-association of step 3; > 1: group trackers
            too.
    """

    low: LowParams
    appearance: AppearanceParams
    events: EventParams
    max_lost: Float[Array, ""]
    max_newborn: Float[Array, ""]
    search_rate: Float[Array, ""]
    background: UInt8[Array, "height width 3"]
    min_score: Float[Array, ""]
    resume_frames: Float[Array, ""]
    confirm_score: Float[Array, ""]
    confirm_quantile: Float[Array, ""]
    score_weight: Float[Array, ""]
    exchange_margin: Float[Array, ""]
    drift_check: Float[Array, ""]
    fallback_appearance: Float[Array, ""]


class HighState(NamedTuple):
    """The high-level trackers (``S`` slots).

    Attributes:
        ids: output identity (-1: free slot); the identity of the low-level track that
            started the tracker.
        low_slot: the low-level slot it follows (-1 while lost).
        low_id: that track's identity (a slot re-used by a new track is not followed).
        boxes: the estimate ``(x, y, w, h)``: its track's, propagated while lost.
        velocity: the centre's velocity, pixels per frame.
        lost: frames since it lost its track (0 while it follows one).
        group: a group tracker (born colliding with two or more trackers).
        age: frames since it was started.
        reassociated: it took a new track after being lost (not a new target).
        event: its event state (:data:`~jaxtrack.filters.hier_events.EVENT_NAMES`).
        partners: ``[S, S]``, the followed trackers it collided with since they were last
            both single (:mod:`~jaxtrack.filters.hier_exchanges`).
        single_model: its appearance model was learned while single (it has been checkable
            once since its start); False while it has none or only a fallback model.
    """

    ids: Int[Array, " S"]
    low_slot: Int[Array, " S"]
    low_id: Int[Array, " S"]
    boxes: Float[Array, "S 4"]
    velocity: Float[Array, "S 2"]
    lost: Int[Array, " S"]
    group: Bool[Array, " S"]
    age: Int[Array, " S"]
    reassociated: Bool[Array, " S"]
    event: Int[Array, " S"]
    partners: Bool[Array, "S S"]
    single_model: Bool[Array, " S"]


class HierarchicalState(NamedTuple):
    """The low-level bank, the high-level trackers and their appearance; ``score_counts``,
    the histogram of every detection score read so far
    (:func:`~jaxtrack.filters.score_quantile.confident_score`)."""

    low: LowState
    high: HighState
    appearance: AppearanceTable
    score_counts: Float[Array, " score_bins"]


class HierarchicalInfo(NamedTuple):
    """One frame's output.

    Attributes:
        tracks: the high-level trackers whose track is confirmed and measured on the frame
            (``managed``: the confirmed, measured low-level tracks).
        candidates: every measured low-level track, under its high-level identity when it
            has one.
        events: the event state of each high-level slot (``managed``: all single).
        event_ids: the identity of each high-level slot (-1: free).
        low_boxes: the low-level estimates ``[T, 4]``; ``low_confirmed``, ``low_alive``.
        high_boxes: the high-level estimates ``[S, 4]``, ``high_lost`` while lost.
        pool: each high-level slot's feature pool (feature indices, ``[S, M + N]``).
        distances: the Bhattacharyya distance of each feature's last update ``[S, 49]``.
        low: the low level's info (overflow, assignments).
        overflow: a confirmed track found no free high-level slot.
        merged: per high-level slot, the identity merged into it on the frame by a
            re-association (-1: none): the rows of that identity, before and after, are the
            tracker's (:func:`~jaxtrack.pipelines.events.merge_identities`).
        unfilled: per high-level slot, it was re-associated on the frame by a fallback model
            (``fallback_appearance``): the offline output does not interpolate its identity's
            gap before the frame (:func:`~jaxtrack.association.offline.finalise_tracks`).
    """

    tracks: Tracks
    candidates: Tracks
    events: Int[Array, " S"]
    event_ids: Int[Array, " S"]
    low_boxes: Float[Array, "T 4"]
    low_confirmed: Bool[Array, " T"]
    low_alive: Bool[Array, " T"]
    high_boxes: Float[Array, "S 4"]
    high_lost: Bool[Array, " S"]
    pool: Int[Array, "S P"]
    distances: Float[Array, "S F"]
    low: LowInfo
    overflow: Bool[Array, ""]
    merged: Int[Array, " S"]
    unfilled: Bool[Array, " S"]


def init_high(num_slots: int) -> HighState:
    """``num_slots`` free high-level slots."""
    minus = jnp.full((num_slots,), -1, jnp.int32)
    zeros = jnp.zeros((num_slots,), jnp.int32)
    false = jnp.zeros((num_slots,), bool)
    return HighState(
        ids=minus,
        low_slot=minus,
        low_id=minus,
        boxes=jnp.tile(jnp.asarray(PAD_BOX, jnp.float32), (num_slots, 1)),
        velocity=jnp.zeros((num_slots, 2), jnp.float32),
        lost=zeros,
        group=false,
        age=zeros,
        reassociated=false,
        event=zeros,
        partners=jnp.zeros((num_slots, num_slots), bool),
        single_model=false,
    )


def init_hierarchical(
    key: Array, params: HierarchicalParams, *, num_tracks: int, num_trackers: int, measurement: str
) -> HierarchicalState:
    """Empty tables: ``num_tracks`` low-level slots, ``num_trackers`` high-level ones."""
    del key, params
    return HierarchicalState(
        low=init_low(num_tracks, measurement),
        high=init_high(num_trackers),
        appearance=init_table(num_trackers, NUM_CURRENT, NUM_LONGRUN),
        score_counts=init_counts(),
    )


def _tracks(boxes, ids, selected, scores) -> Tracks:
    """One frame of output boxes of the selected slots."""
    return Tracks(
        boxes=jnp.where(selected[:, None], boxes, jnp.asarray(PAD_BOX, boxes.dtype)),
        ids=jnp.where(selected, ids, -1).astype(jnp.int32),
        scores=jnp.where(selected, scores, 0.0).astype(boxes.dtype),
        mask=selected,
    )


def _measured(info: LowInfo, num_tracks: int) -> Bool[Array, " T"]:
    """The low-level slots that took a measurement on the frame (a birth's slot is its
    measurement's assignment)."""
    slot = jnp.where(info.assignment >= 0, info.assignment, num_tracks)
    return jnp.zeros((num_tracks,), bool).at[slot].set(True, mode="drop")


def _propagated(high: HighState) -> Float[Array, "S 4"]:
    """The trackers' boxes moved one frame at their constant velocity (a lost tracker's
    motion model)."""
    return high.boxes + jnp.concatenate([high.velocity, jnp.zeros_like(high.velocity)], axis=-1)


def _follow(high: HighState, low: LowState, boxes, velocity, max_lost, size) -> HighState:
    """Tracker matching (Sec. 5.1): a tracker follows its track while the track lives;
    a lost one is propagated at constant velocity, and dropped after ``max_lost`` frames or
    when its centre leaves the image (``size`` = ``(width, height)``: it has exited)."""
    slot = jnp.clip(high.low_slot, 0)
    alive = high.ids >= 0
    followed = alive & (high.low_slot >= 0) & low.alive[slot] & (low.ids[slot] == high.low_id)
    moved = jnp.where(followed[:, None], boxes[slot], _propagated(high))
    centre = moved[:, :2] + moved[:, 2:] / 2
    inside = jnp.all((centre >= 0) & (centre < jnp.asarray(size, centre.dtype)), axis=-1)
    lost = jnp.where(followed, 0, high.lost + alive)
    keep = alive & (followed | ((lost <= max_lost) & inside))
    return high._replace(
        ids=jnp.where(keep, high.ids, -1),
        low_slot=jnp.where(followed, high.low_slot, -1),
        low_id=jnp.where(followed, high.low_id, -1),
        boxes=moved,
        velocity=jnp.where(followed[:, None], velocity[slot], high.velocity),
        lost=jnp.where(keep, lost, 0),
        age=jnp.where(keep, high.age + 1, 0),
    )


def _within_reach(high: HighState, boxes, search_rate) -> Bool[Array, "S T"]:
    """Lost trackers and tracks close enough to be the same target: the track's centre within
    ``h (1 + search_rate * lost)`` of the tracker's propagated centre (``h`` its box height,
    ``lost`` the frames it has been lost: the uncertainty of the constant-velocity
    propagation grows with the time lost)."""
    centre = high.boxes[:, :2] + high.boxes[:, 2:] / 2
    track_centre = boxes[:, :2] + boxes[:, 2:] / 2
    distance = jnp.linalg.norm(centre[:, None] - track_centre[None], axis=-1)
    reach = high.boxes[:, 3] * (1.0 + search_rate * high.lost)
    return distance <= reach[:, None]


def _owners(high: HighState, num_tracks: int) -> Int[Array, " T"]:
    """The high-level slot following each low-level slot (-1: none)."""
    following = (high.ids >= 0) & (high.low_slot >= 0)
    slots = jnp.arange(high.ids.shape[0], dtype=jnp.int32)
    return (
        jnp.full((num_tracks,), -1, jnp.int32)
        .at[jnp.where(following, high.low_slot, num_tracks)]
        .set(slots, mode="drop")
    )


def _newborn(high: HighState, max_newborn) -> Bool[Array, " S"]:
    """Trackers still new-born: started on a track confirmed less than ``max_newborn``
    frames ago, not by a re-association. A lost tracker may yet take a new-born tracker's
    track (Sec. 5.4: the new-born trackers are its candidates); the new-born identity is
    then merged into the lost one's."""
    following = (high.ids >= 0) & (high.low_slot >= 0)
    return following & (high.age < max_newborn) & ~high.reassociated


def _take(high: HighState, match, owner, low: LowState, boxes, velocity):
    """Lost trackers take the tracks they were re-associated with (``match`` [S]); a
    new-born tracker whose track is taken is merged into the taker (freed). Returns the
    trackers and, per slot, the identity merged into it on this frame (-1: none): the
    new-born tracker's, or the taken track's own (``low id + 1``) for a track confirmed on
    this frame, so that the output rows of the track before it was taken can be relabelled."""
    took = match >= 0
    slot = jnp.clip(match, 0)
    absorbed_slot = owner[slot]
    has_owner = took & (absorbed_slot >= 0)
    absorbed_id = jnp.where(has_owner, high.ids[jnp.clip(absorbed_slot, 0)], low.ids[slot] + 1)
    freed = (
        jnp.zeros_like(took)
        .at[jnp.where(has_owner, absorbed_slot, took.shape[0])]
        .set(True, mode="drop")
    )
    high = high._replace(
        ids=jnp.where(freed, -1, high.ids),
        low_slot=jnp.where(took, match, jnp.where(freed, -1, high.low_slot)),
        low_id=jnp.where(took, low.ids[slot], jnp.where(freed, -1, high.low_id)),
        boxes=jnp.where(took[:, None], boxes[slot], high.boxes),
        velocity=jnp.where(took[:, None], velocity[slot], high.velocity),
        lost=jnp.where(took, 0, high.lost),
        reassociated=high.reassociated | took,
    )
    return high, jnp.where(took, absorbed_id, -1).astype(jnp.int32)


def _start(high: HighState, starts, low: LowState, boxes, velocity, group_of):
    """New high-level trackers on the confirmed tracks ``starts`` [T] no lost tracker took;
    ``group_of(born)`` marks those born colliding with two or more trackers."""
    new = start_tracks(high.ids >= 0, starts, jnp.int32(0))
    source = jnp.clip(new.source, 0, starts.shape[0] - 1)
    born = new.born
    high = high._replace(
        ids=jnp.where(born, low.ids[source] + 1, high.ids),
        low_slot=jnp.where(born, source, high.low_slot),
        low_id=jnp.where(born, low.ids[source], high.low_id),
        boxes=jnp.where(born[:, None], boxes[source], high.boxes),
        velocity=jnp.where(born[:, None], velocity[source], high.velocity),
        lost=jnp.where(born, 0, high.lost),
        age=jnp.where(born, 0, high.age),
        reassociated=jnp.where(born, False, high.reassociated),
        event=jnp.where(born, 0, high.event),
        single_model=jnp.where(born, False, high.single_model),
    )
    return high._replace(group=jnp.where(born, group_of(born, high), high.group)), new


def _check_resumed(
    previous: HierarchicalState,
    high: HighState,
    low: LowState,
    measured: Bool[Array, " T"],
    histograms: Float[Array, "T 49 64"],
    params: HierarchicalParams,
) -> tuple[HighState, LowState, Bool[Array, " T"], Bool[Array, "S T"]]:
    """Step 2b: trackers whose track resumed after coasting ``resume_frames`` frames and
    whose appearance model does not gate the track's measured box let the track go. With
    ``drift_check`` so do trackers that are single on this frame (measured, confirmed, not
    group trackers) while they still have partners from a collision episode
    (``HighState.partners``, closed once both of a pair are checkable: see
    :func:`_undo_exchanges`): a track the low level moved onto a neighbour where people met.

    Args:
        previous: the state before the frame (the tracks' coasting counts, the trackers'
            boxes, velocities and appearance models).
        high: the trackers after :func:`_follow` on this frame.
        low: the low level after this frame's step.
        measured: the low-level slots measured on the frame.
        histograms: each low-level slot's box histograms on the frame.
        params: ``resume_frames`` and the appearance gate's parameters.

    Returns:
        The trackers (those that let go are lost, at their propagated box and velocity),
        the low level (the released tracks renamed), the released slots ``[T]`` and the
        released (tracker, slot) pairs ``[S, T]`` (not to be re-associated on this frame).
    """
    num_tracks = low.alive.shape[0]
    slot = jnp.clip(high.low_slot, 0)
    following = (high.ids >= 0) & (high.low_slot >= 0)
    resumed = following & measured[slot] & (previous.low.misses[slot] >= params.resume_frames)
    # Drift check: a tracker single again after a collision episode checks its track too.
    apart = ~jnp.any(collision_map(high.boxes, following, params.events.min_overlap), axis=1)
    separated = (
        following
        & measured[slot]
        & low.confirmed[slot]
        & apart
        & ~high.group
        & jnp.any(previous.high.partners, axis=1)
        & (params.drift_check > 0)
    )
    resumed = resumed | separated
    gated, testable = own_track_gate(previous.appearance, histograms[slot], params.appearance)
    # A fallback model (learned while colliding) only re-associates; it refuses nothing.
    release = resumed & testable & ~gated & high.single_model
    released = (
        jnp.zeros((num_tracks,), bool)
        .at[jnp.where(release, slot, num_tracks)]
        .set(True, mode="drop")
    )
    order = jnp.cumsum(released) - 1
    low = low._replace(
        ids=jnp.where(released, low.next_id + order, low.ids).astype(low.ids.dtype),
        next_id=(low.next_id + jnp.sum(released)).astype(low.next_id.dtype),
    )
    old = previous.high
    high = high._replace(
        low_slot=jnp.where(release, -1, high.low_slot),
        low_id=jnp.where(release, -1, high.low_id),
        boxes=jnp.where(release[:, None], _propagated(old), high.boxes),
        velocity=jnp.where(release[:, None], old.velocity, high.velocity),
        lost=jnp.where(release, old.lost + 1, high.lost),
    )
    pairs = release[:, None] & (jnp.arange(num_tracks)[None, :] == slot[:, None])
    return high, low, released, pairs


def _undo_exchanges(
    high: HighState,
    collisions: Bool[Array, "S S"],
    following: Bool[Array, " S"],
    checkable: Bool[Array, " S"],
    table: AppearanceTable,
    histograms: Float[Array, "T 49 64"],
    params: HierarchicalParams,
) -> HighState:
    """Two trackers that collided and are single again swap their tracks when each one's
    appearance model is nearer the other's box (:mod:`~jaxtrack.filters.hier_exchanges`).

    Args:
        high: the trackers after this frame's births.
        collisions: this frame's collision map of ``high.boxes``.
        following: the trackers that follow a low-level track (not born on this frame: a
            slot's partners are those of its tracker).
        checkable: those measured, confirmed, single and not group trackers on the frame.
        table: the appearance models (frozen since the trackers last were single).
        histograms: each low-level slot's histograms on the frame.
        params: ``exchange_margin`` and the appearance's ``min_updates``.

    Returns:
        The trackers, swapped pairs exchanged (track, identity of the track, box, velocity),
        every pair of checkable trackers' episode closed.
    """
    both = following[:, None] & following[None, :]
    partners = (high.partners | collisions) & both
    trained = trained_features(table, params.appearance.min_updates)
    able = checkable & jnp.any(trained, axis=-1)
    ready = partners & able[:, None] & able[None, :]

    def check(_):
        boxes = histograms[jnp.clip(high.low_slot, 0)]
        distances = model_distances(table, boxes, trained)
        return exchanges(distances, ready, params.exchange_margin)

    # The [S, S, 49] distances only on frames where a pair is to be checked (most have none).
    unswapped = jnp.full(high.ids.shape, -1, jnp.int32)
    partner = jax.lax.cond(jnp.any(ready), check, lambda _: unswapped, None)
    swap = partner >= 0
    source = jnp.where(swap, partner, jnp.arange(partner.shape[0]))
    closed = checkable[:, None] & checkable[None, :]
    return high._replace(
        low_slot=high.low_slot[source],
        low_id=high.low_id[source],
        boxes=high.boxes[source],
        velocity=high.velocity[source],
        partners=partners & ~closed,
    )


def hierarchical_step(
    key: Array,
    state: HierarchicalState,
    params: HierarchicalParams,
    inputs: FrameInputs,
    *,
    variant: str,
    measurement: str,
    patch_shape: tuple[int, int],
) -> tuple[HierarchicalState, HierarchicalInfo]:
    """One frame of the Hierarchical tracker (the module's steps 1-6)."""
    del key
    detections = inputs.detections
    num_tracks = state.low.alive.shape[0]
    readable = detections.mask & (detections.scores >= params.min_score)
    counts = count_scores(state.score_counts, detections._replace(mask=readable))
    threshold = confident_score(counts, params.confirm_score, params.confirm_quantile)
    low, low_info = low_step(
        state.low,
        params.low,
        measurements_of(detections.boxes, measurement),
        readable,
        detections.scores >= threshold,
        params.score_weight * score_log_odds(detections.scores, SCORE_CLIP),
        measurement=measurement,
    )
    boxes = low_boxes(low, measurement)
    velocity = low_velocity(low)
    measured = _measured(low_info, num_tracks) & low.alive
    ones = jnp.ones((num_tracks,), boxes.dtype)
    own_ids = low.ids + 1
    if variant == "managed":
        state = state._replace(low=low, score_counts=counts)
        info = _info(
            _tracks(boxes, own_ids, measured & low.confirmed, ones),
            _tracks(boxes, own_ids, measured, ones),
            state,
            low_info,
            jnp.array(False),
            boxes,
            jnp.full_like(state.high.ids, -1),
            jnp.zeros_like(state.high.ids, bool),
        )
        return state, info

    height, width = params.background.shape[:2]
    high = _follow(state.high, low, boxes, velocity, params.max_lost, (width, height))
    # Only live tracks' histograms are read (every read below is masked by slots that follow
    # a live track, or by candidates, which are live): dead slots get zeros, at no cost.
    histograms = live_box_histograms(inputs.frame, boxes, low.alive, patch_shape)
    background = live_box_histograms(params.background, boxes, low.alive, patch_shape)
    high, low, released, released_pairs = _check_resumed(
        state, high, low, measured, histograms, params
    )
    lost = (high.ids >= 0) & (high.low_slot < 0)
    confirmed_now = (low_info.newly_confirmed & low.alive) | released
    owner = _owners(high, num_tracks)
    newborn = _newborn(high, params.max_newborn)
    owned = owner >= 0
    candidate = confirmed_now | (owned & newborn[jnp.clip(owner, 0)])
    pools = jnp.where(
        owned[:, None],
        state.appearance.features[jnp.clip(owner, 0)],
        fresh_pool(histograms, background, params.appearance.delta),
    )
    distance, gated = association_distances(
        state.appearance, lost, histograms, pools, candidate, params.appearance
    )
    reachable = _within_reach(high, boxes, params.search_rate) & ~released_pairs
    match = reassociate(distance, gated & reachable)
    # A fallback model (learned while colliding) is weaker evidence: no gap filled across it.
    unfilled = (match >= 0) & ~high.single_model
    high, merged = _take(high, match, owner, low, boxes, velocity)
    taken = (
        jnp.zeros((num_tracks,), bool)
        .at[jnp.where(match >= 0, match, num_tracks)]
        .set(True, mode="drop")
    )

    def group_of(born, current):
        collisions = collision_map(current.boxes, current.ids >= 0, params.events.min_overlap)
        return is_group_birth(collisions, born)

    high, new = _start(high, confirmed_now & ~taken, low, boxes, velocity, group_of)
    alive = high.ids >= 0
    following = alive & (high.low_slot >= 0)
    slot = jnp.clip(high.low_slot, 0)
    collisions = collision_map(high.boxes, alive, params.events.min_overlap)
    single = ~jnp.any(collisions, axis=1)
    checkable = following & measured[slot] & low.confirmed[slot] & single & ~high.group
    # A tracker's first single frame restarts its model (dropping a fallback model learned
    # while colliding; without the fallback the model is still empty then: no change).
    restart = checkable & ~high.single_model
    table = reset_slots(state.appearance, new.born | restart)
    fallback = (
        (params.fallback_appearance > 0)
        & following
        & measured[slot]
        & low.confirmed[slot]
        & ~single
        & (~high.group | (params.fallback_appearance > 1))
        & ~high.single_model
    )
    fresh = following & ~new.born
    high = _undo_exchanges(high, collisions, fresh, checkable, table, histograms, params)
    slot = jnp.clip(high.low_slot, 0)
    # A swap exchanges two checkable trackers' tracks: the set to update is unchanged. A
    # fallback update never meets a checkable tracker's (one is single, the other not).
    update = checkable | fallback
    high = high._replace(single_model=high.single_model | checkable)
    table = update_appearance(
        table,
        histograms[slot],
        background[slot],
        update,
        params.appearance,
        num_current=NUM_CURRENT,
    )
    # A lost tracker's box is its motion model's extrapolation (up to `max_lost` frames):
    # the others do not collide with it in the event machine (hier_events, "Lost trackers").
    events = event_step(
        high.event,
        collisions & following[None, :],
        high.group,
        alive,
        high.age,
        high.reassociated,
        params.events,
    )
    high = high._replace(event=jnp.where(alive, events, 0))
    shown = following & measured[slot] & low.confirmed[slot]
    label = (
        jnp.full((num_tracks,), -1, jnp.int32)
        .at[jnp.where(following, slot, num_tracks)]
        .set(high.ids, mode="drop")
    )
    state = HierarchicalState(low, high, table, counts)
    info = _info(
        _tracks(high.boxes, high.ids, shown, jnp.ones_like(high.boxes[:, 0])),
        _tracks(boxes, jnp.where(label >= 0, label, own_ids), measured, ones),
        state,
        low_info,
        new.overflow,
        boxes,
        merged,
        unfilled,
    )
    return state, info


def _info(tracks, candidates, state, low_info, overflow, boxes, merged, unfilled):
    """The frame's :class:`HierarchicalInfo` (after the frame's ``state``; ``boxes``: its
    low-level estimates, :func:`~jaxtrack.filters.hier_low.low_boxes`)."""
    high, low = state.high, state.low
    return HierarchicalInfo(
        tracks=tracks,
        candidates=candidates,
        events=high.event,
        event_ids=high.ids,
        low_boxes=boxes,
        low_confirmed=low.confirmed & low.alive,
        low_alive=low.alive,
        high_boxes=high.boxes,
        high_lost=(high.ids >= 0) & (high.low_slot < 0),
        pool=state.appearance.features,
        distances=state.appearance.last_distance,
        low=low_info,
        overflow=overflow | (low_info.overflow > 0),
        merged=merged,
        unfilled=unfilled,
    )


def hierarchical_filter(
    variant: str,
    num_tracks: int,
    num_trackers: int,
    measurement: str = "box",
    patch_shape: tuple[int, int] = PATCH_SHAPE,
) -> Filter:
    """Builds the Hierarchical tracker; all arguments are static.

    Args:
        variant: ``"managed"`` (low level alone) or ``"full"`` (:data:`STEPPED_VARIANTS`).
        num_tracks: low-level slots (> 0).
        num_trackers: high-level slots (> 0).
        measurement: ``"box"`` or ``"ellipse"`` (:mod:`~jaxtrack.filters.hier_low`).
        patch_shape: samples per box of the colour histograms.

    Returns:
        The :class:`~jaxtrack.filters.base.Filter` (steps on
        :class:`~jaxtrack.types.FrameInputs`).

    Raises:
        ValueError: an unknown variant or a non-positive size.
    """
    if variant not in STEPPED_VARIANTS:
        raise ValueError(f"variant must be one of {', '.join(STEPPED_VARIANTS)}, got {variant!r}")
    if num_tracks <= 0 or num_trackers <= 0:
        raise ValueError(f"slots must be positive, got {num_tracks} and {num_trackers}")
    init = functools.partial(
        init_hierarchical,
        num_tracks=num_tracks,
        num_trackers=num_trackers,
        measurement=measurement,
    )
    step = functools.partial(
        hierarchical_step, variant=variant, measurement=measurement, patch_shape=patch_shape
    )
    return Filter(init=init, step=step)
