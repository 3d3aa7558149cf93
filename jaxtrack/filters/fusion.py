"""The Fusion tracker (Kalafatis et al.; SPEC section 3): a pool of trackers fused per target
by confidence and accordance, voting initiation/termination by region, occlusion reasoning and
re-identification.

One :func:`fusion_step` on frame ``k`` over a fixed table of ``S`` slots, each empty, a
*hypothesis* (``TENTATIVE``: a chain of detections not yet voted in) or a *target*:

1. **Prediction.** Each live slot's Kalman filter (the detection member's own state: the
   constant-velocity box model of the Kalman baseline, :mod:`~jaxtrack.filters.kalman`,
   updated by the slot's detections only) predicts its box.
2. **Pool** (paper Sec. 3.2), each member giving a response box per target (``[S, M, 4]``) and
   whether it has one this frame:

   * ``detection`` (tracking by detection): the frame's detections are assigned one-to-one to
     the targets' predicted boxes (Hungarian on the Gaussian negative log-likelihood
     ``d^2 + log |S|`` plus ``appearance_weight`` times the signature distance between
     the target's stored signature and the detection's; gates ``d^2 <= chi2_gate`` and
     ``IoU >= gate`` with the predicted box or the last fused box), then the detections
     left to the hypotheses (motion alone, IoU with the predicted box); a target's
     response is its detection, which updates its filter;
   * ``classifier`` (tracking by classification): a MOSSE correlation filter per target
     (:mod:`~jaxtrack.filters.fusion_classifier`) searching around the last fused box; it
     responds when its peak-to-sidelobe ratio reaches ``psr_min``;
   * ``predictor`` (motion prediction): the last fused box moved so that its foot point
     lands on the local GP models' prediction from the last ``N_tracklet`` evidence foot
     points (a slot's evidence is the detection where one supported it, else its filter's
     predicted box; :mod:`~jaxtrack.filters.fusion_motion`); it always responds.

   Every member starts from the last *fused* box (late fusion corrects each member's drift).
3. **Fusion** (Sec. 4, :mod:`~jaxtrack.filters.fusion_combine`): per target, the confidence
   ``S_i = (Sim_sp + Sim_app) / 2`` of each response (its speed against the mean speed of the
   last :data:`SPEED_FRAMES` evidence boxes; ``Sim_app = 1 - D``, ``D`` the signature distance
   of the response's box to the target's stored signature), the accordance ``A_ij`` of each
   pair (``Sim_dist = exp(-d / h)``, IoU, ``1 - D`` between the two responses' signatures)
   and the fused box ``R = sum_ij (A_ij / A_sum) (S_i R_i + S_j R_j) / (S_i + S_j)``; or, in
   the ``naive`` fusion, the mean of the responses. A target without any response takes its
   filter's predicted box; a hypothesis's box is its detection.
4. **Voting** (Sec. 3.1, :mod:`~jaxtrack.filters.fusion_voting`): a slot is *supported* when
   a detection is assigned to it. A hypothesis becomes a target after ``th_init`` consecutive
   supported frames; a target ends after ``th_term`` frames without support; both thresholds
   are those of the region (active, inactive, entry/exit zone) of the slot's foot point. A
   detection left unassigned opens a hypothesis in a free slot, with a new identity.
5. **Re-identification** (Sec. 3.1): a hypothesis voted in on this frame is compared with the
   targets occluded on the previous frame within ``reid_radius`` box heights
   (:func:`~jaxtrack.filters.fusion_profile.reidentify`); on a match it takes that target's
   identity and signature, and the occluded target's slot is freed (the hypothesis's own
   frames before it was voted in, under the identity it had then, are left out of the
   output).
6. **Occlusion** (Sec. 2.2, :func:`~jaxtrack.filters.fusion_profile.occlusion_status`):
   targets whose fused boxes overlap (``Q > occlusion_q``) form groups; in each, the target
   closest to its own signature is the occluder, the others are occluded: their classifier
   and signature stop learning (on the next frame for the classifier, which learns as it
   localises). An occluded target stays occluded "until it becomes fully visible again"
   (Sec. 2.2): until a detection supports it while it is no group's occluded member.
7. **Exchanges undone** (beyond the paper; session 53): two targets that were in one
   occlusion group are checked once, on the first frame both are in no group and both
   detected: with ``D(i, j)`` the signature distance of target ``i``'s stored model to
   target ``j``'s detection, the pair swaps identities, signature models and classifier
   filters (not boxes, motion or votes, which follow the places) when
   ``D(i, j) + D(j, i) + exchange_margin < D(i, i) + D(j, j)``: each model is nearer the
   other's detection (:func:`~jaxtrack.filters.hier_exchanges.exchanges`, the Hierarchical
   tracker's check; pairs greedily by gain). The detection assignment weighs appearance
   frame by frame, but while two people overlap their detections' signatures mix, and the
   wrong pairing can win on motion; the check looks again once they are apart.

The output (:class:`FusionInfo`): ``tracks`` are the targets (fused boxes), ``candidates``
the targets and hypotheses (a hypothesis carries the identity it keeps when voted in), so the
offline output (:func:`~jaxtrack.association.offline.finalise_tracks`) starts a target at its
first detection. A row's score is 1 when a detection supports the slot on the frame, else 0
(a coasting target): the offline output drops each target's trailing coasting rows (the
frames after its last detection, before the vote ended it).
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from jaxtrack.appearance.model import AppearanceModel
from jaxtrack.association.assignment import gated_assignment
from jaxtrack.association.track_table import start_tracks
from jaxtrack.boxes import cxcywh_to_xywh, iou_matrix, xywh_to_cxcywh
from jaxtrack.context.motion_models import TRACKLET_LENGTH, MotionModels
from jaxtrack.filters.base import Filter
from jaxtrack.filters.fusion_classifier import (
    CLASSIFIER_PATCH_SHAPE,
    ClassifierParams,
    ClassifierState,
    classifier_step,
    start_targets,
)
from jaxtrack.filters.fusion_combine import (
    accordance,
    confidence,
    fuse,
    fusion_weights,
    naive_weights,
    speed_similarity,
)
from jaxtrack.filters.fusion_motion import predict_motion
from jaxtrack.filters.fusion_profile import (
    occlusion_status,
    reidentify,
    signature_distance,
    signatures,
    start_signatures,
    update_signatures,
)
from jaxtrack.filters.fusion_voting import (
    EMPTY,
    TARGET,
    TENTATIVE,
    VotingState,
    point_regions,
    voting_init,
    voting_step,
)
from jaxtrack.filters.hier_exchanges import exchanges
from jaxtrack.filters.kalman import (
    idle_filters,
    kalman_birth,
    kalman_predict,
    kalman_update,
    mahalanobis_costs,
)
from jaxtrack.models.dynamics import MEASURED
from jaxtrack.types import PAD_BOX, FrameInputs, Tracks

#: The pool's members, in the order of the response table's member axis.
MEMBERS = ("detection", "classifier", "predictor")
#: The fusion rules: the paper's dynamic fusion, and the mean of the responses (its ablation).
FUSIONS = ("proposed", "naive")
#: Samples per box of a signature (rows split into the upper and lower body), the HSV
#: quantisation step (8 bins per channel) and the fewest rows of a part.
SIGNATURE_PATCH, SIGNATURE_STEP, SIGNATURE_MIN_ROWS = (16, 8), 32.0, 3
#: Evidence boxes whose mean speed ``v_mean`` the confidence compares a response's with (the
#: paper's ``N``).
SPEED_FRAMES = 10
#: Boxes of history kept per slot.
HISTORY = max(SPEED_FRAMES + 1, TRACKLET_LENGTH)


class FusionParams(NamedTuple):
    """The Fusion tracker's parameters (a PyTree; built by
    :func:`~jaxtrack.filters.fusion_tracker.fusion_params`).

    Attributes:
        classifier: the correlation filters' parameters.
        motion: the local motion models (per-cell GPs) of the training trajectories.
        zone_boxes: ``[Z, 4]`` entry/exit zones ``(x, y, w, h)`` (``Z`` may be 0).
        activity: ``[rows, columns]`` activity mask.
        activity_cell: its cell side, pixels.
        th_init: ``[3]`` initiation threshold of the active, inactive and zone regions.
        th_term: ``[3]`` termination threshold of the same regions.
        motion_noise_std: the slots' Kalman filters' dynamics noise (``KalmanParams``).
        measurement_noise_std: their detection noise.
        initial_velocity_std: their velocity prior on a new slot.
        chi2_gate: largest squared Mahalanobis distance of a detection from a target's
            predicted box for an assignment.
        gate: smallest IoU of a detection with a slot's predicted box (a target's: or its
            last fused box) for an assignment.
        psr_min: smallest peak-to-sidelobe ratio of a classifier response.
        occlusion_q: ``Q`` above which two targets are occlusion-related (paper: 0.3).
        signature_rate: learning-rate floor of the signature models.
        reid_radius: re-identification vicinity, in new-box heights.
        reid_gate: largest signature distance of a re-identification.
        appearance_weight: weight of a target's signature distance to a detection in the
            assignment cost (0: motion alone).
        exchange_margin: the margin of the exchange check (step 7; ``inf``: never).
    """

    classifier: ClassifierParams
    motion: MotionModels
    zone_boxes: Float[Array, "zones 4"]
    activity: Bool[Array, "rows columns"]
    activity_cell: Float[Array, ""]
    th_init: Int[Array, " 3"]
    th_term: Int[Array, " 3"]
    motion_noise_std: Float[Array, " 4"]
    measurement_noise_std: Float[Array, " 4"]
    initial_velocity_std: Float[Array, " 2"]
    chi2_gate: Float[Array, ""]
    gate: Float[Array, ""]
    psr_min: Float[Array, ""]
    occlusion_q: Float[Array, ""]
    signature_rate: Float[Array, ""]
    reid_radius: Float[Array, ""]
    reid_gate: Float[Array, ""]
    appearance_weight: Float[Array, ""]
    exchange_margin: Float[Array, ""]


class FusionState(NamedTuple):
    """The scan carry: ``S`` slots.

    Attributes:
        ids: identity of each live slot (-1 when empty).
        next_id: identity of the next hypothesis.
        voting: the slots' voting counters and status.
        boxes: ``[S, 4]`` last fused box.
        history: ``[S, HISTORY, 4]`` last evidence boxes (the detection where one
            supported the slot, else its Kalman filter's predicted box), oldest first (the
            first box repeated before the slot had ``HISTORY`` of them).
        count: ``[S]`` evidence boxes seen (capped at ``HISTORY``).
        means: ``[S, 6]`` each slot's Kalman filter's posterior state
            ``(y1, vy1, y2, vy2, w, h)`` (:mod:`~jaxtrack.filters.kalman`).
        covs: ``[S, 6, 6]`` its covariance.
        classifier: the correlation filters.
        signature: the signature models (``histogram`` ``[S, 2, bins]``).
        occluded: ``[S]`` occluded on the last frame.
        met: ``[S, S]`` the two targets were in one occlusion group since they were last
            checked apart (step 7).
    """

    ids: Int[Array, " S"]
    next_id: Int[Array, ""]
    voting: VotingState
    boxes: Float[Array, "S 4"]
    history: Float[Array, "S H 4"]
    count: Int[Array, " S"]
    means: Float[Array, "S 6"]
    covs: Float[Array, "S 6 6"]
    classifier: ClassifierState
    signature: AppearanceModel
    occluded: Bool[Array, " S"]
    met: Bool[Array, "S S"]


class FusionInfo(NamedTuple):
    """One frame's output.

    Attributes:
        tracks: the targets' fused boxes under their identities.
        candidates: the targets and the hypotheses.
        members: ``[S, M, 4]`` each pool member's response box (:data:`MEMBERS` order).
        member_valid: ``[S, M]`` whether the member responded (and is in the pool).
        weights: ``[S, M]`` the members' fusion weights.
        status: ``[S]`` voting status (:data:`~jaxtrack.filters.fusion_voting.STATUS_NAMES`).
        occluded: ``[S]`` occluded targets.
        overflow: a detection found no free slot for its hypothesis.
    """

    tracks: Tracks
    candidates: Tracks
    members: Float[Array, "S M 4"]
    member_valid: Bool[Array, "S M"]
    weights: Float[Array, "S M"]
    status: Int[Array, " S"]
    occluded: Bool[Array, " S"]
    overflow: Bool[Array, ""]


def init_fusion(key: Array, params: FusionParams, *, num_slots: int) -> FusionState:
    """``num_slots`` empty slots."""
    del key
    rows, cols = CLASSIFIER_PATCH_SHAPE
    bins = int(256 // SIGNATURE_STEP) ** 3
    pad = jnp.broadcast_to(jnp.asarray(PAD_BOX, jnp.float32), (num_slots, 4))
    zeros = jnp.zeros((num_slots, 2), jnp.float32)
    means, covs = idle_filters(num_slots, jnp.float32)
    return FusionState(
        ids=jnp.full((num_slots,), -1, jnp.int32),
        next_id=jnp.int32(1),
        voting=voting_init(num_slots),
        boxes=pad,
        history=jnp.broadcast_to(pad[:, None], (num_slots, HISTORY, 4)),
        count=jnp.zeros((num_slots,), jnp.int32),
        means=means,
        covs=covs,
        classifier=ClassifierState(
            jnp.zeros((num_slots, rows, cols), jnp.complex64),
            jnp.zeros((num_slots, rows, cols), jnp.float32),
            pad,
            jnp.zeros((num_slots,), bool),
        ),
        signature=AppearanceModel(
            jnp.zeros((num_slots, 2, bins), jnp.float32), zeros, zeros, zeros
        ),
        occluded=jnp.zeros((num_slots,), bool),
        met=jnp.zeros((num_slots, num_slots), bool),
    )


def centres(boxes: Float[Array, "*shape 4"]) -> Float[Array, "*shape 2"]:
    """Box centres ``(x + w / 2, y + h / 2)``."""
    return boxes[..., :2] + boxes[..., 2:] / 2


def feet(boxes: Float[Array, "*shape 4"]) -> Float[Array, "*shape 2"]:
    """Foot points ``(x + w / 2, y + h)``."""
    return jnp.stack([boxes[..., 0] + boxes[..., 2] / 2, boxes[..., 1] + boxes[..., 3]], -1)


def _assign(cost, allowed, detections, slots, taken):
    """One-to-one assignment of the free detections to ``slots`` (``allowed`` pairs)."""
    allowed = allowed & slots[:, None] & (detections.mask & ~taken)[None, :]
    return gated_assignment(cost, allowed)


def _taken(match: Int[Array, " S"], num_detections: int) -> Bool[Array, " D"]:
    return (
        jnp.zeros((num_detections,), bool)
        .at[jnp.where(match >= 0, match, num_detections)]
        .set(True, mode="drop")
    )


def _speed_history(history, count):
    """``[S, SPEED_FRAMES]`` the fused speeds of the last frames and which exist."""
    points = centres(history[:, -(SPEED_FRAMES + 1) :])
    speeds = jnp.sqrt(jnp.sum(jnp.diff(points, axis=1) ** 2, axis=-1))
    age = jnp.arange(SPEED_FRAMES)[::-1]  # speed k spans boxes ending age k frames ago
    return speeds, age[None, :] < (count[:, None] - 1)


def _fuse_one(members, valid, similarity, pair_similarity, past, past_valid, last, fallback, naive):
    """One target's fused box (module step 3)."""
    speed = jnp.sqrt(jnp.sum((centres(members) - centres(last)) ** 2, axis=-1))
    speed_sim = jax.vmap(speed_similarity, in_axes=(None, None, 0))(past, past_valid, speed)
    if naive:
        weights = naive_weights(valid)
    else:
        scores = confidence(speed_sim, similarity)
        weights = fusion_weights(scores, accordance(members, pair_similarity), valid)
    weights = jnp.where(valid, weights, 0.0)
    fused = fuse(weights, jnp.where(valid[:, None], members, 0.0))
    return jnp.where(jnp.any(valid), fused, fallback), weights


def fusion_step(
    key: Array,
    state: FusionState,
    params: FusionParams,
    inputs: FrameInputs,
    *,
    pool: tuple[bool, bool, bool],
    naive: bool,
) -> tuple[FusionState, FusionInfo]:
    """One frame of the Fusion tracker (the module's steps 1-6)."""
    del key
    detections, frame = inputs.detections, inputs.frame
    num_slots, num_detections = state.ids.shape[0], detections.mask.shape[0]
    status = state.voting.status
    target = status == TARGET
    tentative = status == TENTATIVE
    means, covs = jax.vmap(kalman_predict, in_axes=(0, 0, None))(
        state.means, state.covs, params.motion_noise_std
    )
    predicted = cxcywh_to_xywh(means[:, jnp.array(MEASURED)], jnp)

    # detection member: targets first, then hypotheses; the likelihood cost within the
    # Mahalanobis gate and the IoU gate (a target's: with its predicted or last fused box)
    measurements = xywh_to_cxcywh(detections.boxes, jnp)
    distances, log_dets = mahalanobis_costs(means, covs, measurements, params.measurement_noise_std)
    cost = distances + log_dets[:, None]
    iou = iou_matrix(predicted, detections.boxes, xp=jnp)
    gated = distances <= params.chi2_gate
    near = jnp.maximum(iou, iou_matrix(state.boxes, detections.boxes, xp=jnp)) >= params.gate
    stored = state.signature.histogram
    detection_sig = _signatures(frame, detections.boxes).histograms
    appearance = signature_distance(stored[:, None], detection_sig[None, :])
    target_cost = cost + params.appearance_weight * appearance
    match = _assign(
        target_cost, gated & near, detections, target, jnp.zeros((num_detections,), bool)
    )
    taken = _taken(match, num_detections)
    match_h = _assign(cost, gated & (iou >= params.gate), detections, tentative, taken)
    match = jnp.where(target, match, match_h)
    taken = _taken(match, num_detections)
    supported = match >= 0
    updated_means, updated_covs = jax.vmap(kalman_update, in_axes=(0, 0, 0, None))(
        means, covs, measurements[jnp.clip(match, 0)], params.measurement_noise_std
    )
    means = jnp.where(supported[:, None], updated_means, means)
    covs = jnp.where(supported[:, None, None], updated_covs, covs)
    detected = jnp.where(supported[:, None], detections.boxes[jnp.clip(match, 0)], predicted)

    # classifier member: searches around the last fused box, learns unless occluded
    classifier = state.classifier._replace(
        boxes=jnp.where(target[:, None], state.boxes, jnp.asarray(PAD_BOX))
    )
    classifier = classifier._replace(alive=target)
    classifier, response = classifier_step(
        classifier, frame, params.classifier, target & ~state.occluded
    )
    classified = classifier.boxes
    classified_valid = target & (response.psr >= params.psr_min)

    # predictor member: the GP's next foot point
    tracklets = feet(state.history[:, -TRACKLET_LENGTH:])
    next_feet, _ = predict_motion(
        params.motion, tracklets, target & (state.count >= TRACKLET_LENGTH)
    )
    moved = next_feet - feet(state.boxes)
    predictor = state.boxes.at[:, :2].add(moved)

    members = jnp.stack([detected, classified, predictor], axis=1)
    in_pool = jnp.asarray(pool)
    valid = jnp.stack([supported, classified_valid, target], axis=1) & in_pool[None, :]
    valid = valid & target[:, None]

    # appearance of every response against the stored signature and against each other
    # the detection member's response, where valid, is its detection, already described
    others = _signatures(frame, members[:, 1:].reshape(-1, 4)).histograms
    others = others.reshape(num_slots, len(MEMBERS) - 1, 2, -1)
    assigned_sig = detection_sig[jnp.clip(match, 0)]
    member_sig = jnp.concatenate([assigned_sig[:, None], others], axis=1)
    similarity = 1.0 - signature_distance(stored[:, None], member_sig)
    pair_similarity = 1.0 - signature_distance(member_sig[:, :, None], member_sig[:, None, :])
    past, past_valid = _speed_history(state.history, state.count)
    fused, weights = jax.vmap(functools.partial(_fuse_one, naive=naive))(
        members, valid, similarity, pair_similarity, past, past_valid, state.boxes, predicted
    )
    boxes = jnp.where(target[:, None], fused, jnp.where(tentative[:, None], detected, state.boxes))

    # voting by region of the foot point
    region = point_regions(params.zone_boxes, params.activity, params.activity_cell, feet(boxes))
    voting = voting_step(state.voting, supported, params.th_init[region], params.th_term[region])
    live = (voting.status == TENTATIVE) | (voting.status == TARGET)
    ids = jnp.where(live, state.ids, -1)

    # new hypotheses from the detections left over
    starts = detections.mask & ~taken
    new = start_tracks(live, starts, state.next_id)
    source = jnp.clip(new.source, 0, num_detections - 1)
    new_boxes = detections.boxes[source]
    new_region = point_regions(
        params.zone_boxes, params.activity, params.activity_cell, feet(new_boxes)
    )
    new_status = jnp.where(params.th_init[new_region] <= 1, TARGET, TENTATIVE)
    voting = VotingState(
        status=jnp.where(new.born, new_status, voting.status),
        support=jnp.where(new.born, 1, voting.support),
        missed=jnp.where(new.born, 0, voting.missed),
    )
    boxes = jnp.where(new.born[:, None], new_boxes, boxes)
    ids = jnp.where(new.born, new.ids, ids)
    born_means, born_covs = jax.vmap(kalman_birth, in_axes=(0, None, None))(
        measurements[source], params.measurement_noise_std, params.initial_velocity_std
    )
    means = jnp.where(new.born[:, None], born_means, means)
    covs = jnp.where(new.born[:, None, None], born_covs, covs)

    # signatures at the fused boxes; re-identification of the targets voted in now
    observed = _signatures(frame, boxes).histograms
    now_target = voting.status == TARGET
    initiated = now_target & ~target
    candidates_for_reid = state.occluded & target & now_target & ~initiated
    picked = jax.vmap(reidentify, in_axes=(0, 0, None, None, None, None, None))(
        observed,
        boxes,
        candidates_for_reid,
        state.boxes,
        stored,
        params.reid_radius,
        params.reid_gate,
    )
    picked = jnp.where(initiated, picked, -1)
    first_pick = (
        jnp.full((num_slots,), num_slots, jnp.int32)
        .at[jnp.where(picked >= 0, picked, num_slots)]
        .min(jnp.arange(num_slots, dtype=jnp.int32), mode="drop")
    )
    picked = jnp.where(
        (picked >= 0) & (first_pick[jnp.clip(picked, 0)] == jnp.arange(num_slots)), picked, -1
    )
    reid = picked >= 0
    freed = _taken(picked, num_slots)
    ids = jnp.where(reid, state.ids[jnp.clip(picked, 0)], ids)
    ids = jnp.where(freed, -1, ids)
    voting = VotingState(
        status=jnp.where(freed, EMPTY, voting.status),
        support=jnp.where(freed, 0, voting.support),
        missed=jnp.where(freed, 0, voting.missed),
    )
    now_target = voting.status == TARGET

    # signature models: fresh for new targets, taken over on re-identification
    taken_over = jax.tree.map(lambda leaf: leaf[jnp.clip(picked, 0)], state.signature)
    signature = jax.tree.map(
        lambda own, other: jnp.where(reid.reshape(reid.shape + (1,) * (own.ndim - 1)), other, own),
        state.signature,
        taken_over,
    )
    signature = start_signatures(signature, observed, initiated & ~reid)
    status_now = occlusion_status(
        boxes, now_target, signature.histogram, observed, params.occlusion_q
    )
    # occluded until fully visible again: re-detected, and the occluder of its group or alone
    hidden = status_now.occluded | (state.occluded & ~supported)
    occluded = hidden & now_target

    # exchanges undone: two targets that met, apart again and both detected, swap their
    # identities (and appearance models) when each one's model is nearer the other's
    # detection
    continuing = now_target & target & ~reid
    together = (
        status_now.related[:, None]
        & (status_now.occluder[:, None] == status_now.occluder[None, :])
        & ~jnp.eye(num_slots, dtype=bool)
    )
    pair = continuing[:, None] & continuing[None, :]
    met = (state.met | together) & pair
    clear = ~status_now.related & supported & continuing & (signature.count[:, 0] > 0)
    ready = met & clear[:, None] & clear[None, :]
    distances = signature_distance(signature.histogram[:, None], assigned_sig[None, :])
    partner = exchanges(distances, ready, params.exchange_margin)
    swapped = partner >= 0
    source = jnp.where(swapped, partner, jnp.arange(num_slots))
    ids = ids[source]
    signature = jax.tree.map(lambda leaf: leaf[source], signature)
    classifier = classifier._replace(
        numerator=classifier.numerator[source], denominator=classifier.denominator[source]
    )
    met = met & ~ready
    signature = update_signatures(
        signature, observed, occluded | ~now_target | initiated, params.signature_rate
    )
    classifier = start_targets(classifier, frame, boxes, initiated, params.classifier)
    classifier = classifier._replace(alive=now_target)

    # evidence history: the detection where one supported the slot, else (a target) its
    # filter's predicted box
    fresh = new.born
    evidence = jnp.where(((supported | now_target) & ~new.born)[:, None], detected, boxes)
    history = jnp.concatenate([state.history[:, 1:], evidence[:, None]], axis=1)
    history = jnp.where(fresh[:, None, None], boxes[:, None], history)
    count = jnp.where(fresh, 1, jnp.minimum(state.count + 1, HISTORY))
    live = (voting.status == TENTATIVE) | now_target
    count = jnp.where(live, count, 0)

    state = FusionState(
        ids=ids,
        next_id=new.next_id,
        voting=voting,
        boxes=jnp.where(live[:, None], boxes, jnp.asarray(PAD_BOX)),
        history=history,
        count=count,
        means=means,
        covs=covs,
        classifier=classifier,
        signature=signature,
        occluded=occluded,
        met=met,
    )
    evidence = (supported | new.born).astype(jnp.float32)
    info = FusionInfo(
        tracks=_tracks(boxes, ids, now_target, evidence),
        candidates=_tracks(boxes, ids, live, evidence),
        members=members,
        member_valid=valid,
        weights=weights,
        status=voting.status,
        occluded=occluded,
        overflow=new.overflow,
    )
    return state, info


def _signatures(frame, boxes):
    return signatures(frame, boxes, SIGNATURE_PATCH, SIGNATURE_STEP, SIGNATURE_MIN_ROWS)


def _tracks(boxes, ids, shown, scores) -> Tracks:
    return Tracks(
        boxes=jnp.where(shown[:, None], boxes, jnp.asarray(PAD_BOX)),
        ids=jnp.where(shown, ids, -1),
        scores=jnp.where(shown, scores, 0.0),
        mask=shown,
    )


def fusion_filter(pool: tuple[str, ...], fusion: str, num_slots: int) -> Filter:
    """Builds the Fusion tracker; all arguments are static.

    Args:
        pool: the members used (a non-empty subset of :data:`MEMBERS`); a pool of one is that
            member alone (with the voting, occlusion reasoning and re-identification).
        fusion: ``"proposed"`` or ``"naive"`` (:data:`FUSIONS`).
        num_slots: slots for targets and hypotheses (> 0).

    Raises:
        ValueError: an unknown member or fusion, an empty pool or a non-positive size.
    """
    unknown = [name for name in pool if name not in MEMBERS]
    if unknown or not pool:
        raise ValueError(f"the pool must be a non-empty subset of {', '.join(MEMBERS)}, got {pool}")
    if fusion not in FUSIONS:
        raise ValueError(f"fusion must be one of {', '.join(FUSIONS)}, got {fusion!r}")
    if num_slots <= 0:
        raise ValueError(f"slots must be positive, got {num_slots}")
    mask = tuple(name in pool for name in MEMBERS)
    init = functools.partial(init_fusion, num_slots=num_slots)
    step = functools.partial(fusion_step, pool=mask, naive=fusion == "naive")
    return Filter(init=init, step=step)
