"""CMT, contextual mixture tracking (Cui et al.; SPEC section 2): the compiled step.

A :mod:`mixture particle filter <jaxtrack.filters.mixture>` whose proposal and observation
model look at the scene's context. One :func:`cmt_step` on
:class:`~jaxtrack.types.FrameInputs` (the frame's detections are CMT's foreground blobs):

1. **propose** (eq. 5): the plain mixture tracker (``"mtb"``) draws from the
   constant-velocity transition
   (:func:`~jaxtrack.filters.mixture_models.bootstrap_proposal`); ``"cpd"`` and ``"cmt"``
   draw a motion condition per particle, then its state (the contextual proposal,
   :func:`~jaxtrack.filters.cmt_proposal.contextual_proposal`, eqs. 5-10; an exit
   invalidates the particle);
2. **observe**: ``log p(z | x) = log p_box(z~ | x) + a log sum_k rho_k N(f_k(x); m_k,
   sigma^2)``: the box likelihood of the nearest blob the component may use (its own, matched
   greedily to its prediction, or a free one: :func:`blob_owners`,
   :func:`owned_log_likelihood`) times the
   feature mixture of eq. 11 (:mod:`~jaxtrack.filters.cmt_observation`) raised to
   ``a = appearance_weight``; the weights ``rho_k`` are uniform (EWOM, ``"mtb"`` and
   ``"cpd"``) or the mutual information of each feature with the identities in the
   component's field of context (COM, eqs. 13-17, ``"cmt"``); with group blobs on
   (``CPDParams.group_area_ratio`` > 0, off by default), a member of a group blob may
   instead score that blob on the edges it accounts for (:func:`grouped_log_likelihood`);
3. reweight (eq. 3), mixture weights (eq. 4), local decisions (heaviest cluster), as in
   :func:`~jaxtrack.filters.mixture.mixture_step`;
4. **verify**: a component whose likelihood support stays below ``min_log_support`` (no blob
   explains it) for more than ``max_misses`` frames (four times as many under the contextual
   proposal while another component is in its field of context: a *merge*, the target
   hidden behind another), or whose ``pi_m`` falls below ``min_mixture_weight``, is deleted
   (CMT Algorithm 1); with ``box_support`` (not in the paper) the support is summed under
   the box likelihood alone, so the appearance exponent does not move it;
5. resample per component; **merge velocity** (``velocity_rate`` > 0, contextual
   proposal only): a component whose predicted centre shares a blob with another's
   (:func:`~jaxtrack.filters.cmt_conditions.sharing_blob`: one box over two targets) keeps
   its long-run velocity (:func:`held_velocities`); **enter**: a blob that no component
   explains starts one (the dispelling rule: a blob explained by another component's
   hypothesis starts none; nor does a group blob); with ``free_blob_frames`` > 0 (not in
   the paper), a blob no component has owned (:func:`blob_owners`) for that many frames in
   a row starts one anyway (:func:`free_runs`: a person walking out of a crossing beside
   the component that followed the other one), a component is confirmed only once apart
   from older ones (:func:`_crowded`), and re-identification also lets an unconfirmed
   component take over the identity of a confirmed one that died (a *handover*: the new
   component is often born before the lost one dies);
6. **update** the appearance models and decayed histograms at the local decisions, except
   for components whose particles mostly drew *merge* (appearance frozen, Sec. IV-B).

With ``exchange`` (``exchange_margin`` >= 0 in the configuration; not in the paper), two
components whose decisions overlapped settle their identities by the observation model on
the first frame their blobs are apart (:mod:`~jaxtrack.filters.cmt_exchanges`: between steps 2
and 3 they swap identities and appearance models when each model explains the other's blob
better by the margin), and a component overlapping another learns no appearance.

A component is output (``tracks``) once a *confident* blob has explained it, on the frames a
blob supports it (confident: scoring at least ``confirm_score``, or at least the
``confirm_quantile`` of the scores of every blob seen so far when that is lower:
:func:`~jaxtrack.filters.score_quantile.confident_score`, not in the paper); ``candidates``
are every supported component. The mixture weights ``pi_m`` are kept (eq. 4, reported as
track scores) but the default deletion threshold on them is 0: with one component per
target, ``pi_m`` mostly measures the box likelihood's density scale (bigger boxes have lower
densities) and would delete every large target within a few frames.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from jaxtrack.appearance import DEFAULT_PATCH_SHAPE, bhattacharyya_coefficient, num_bins
from jaxtrack.boxes import cxcywh_to_xywh, iou_matrix, xywh_to_cxcywh
from jaxtrack.context.zones import zone_distance
from jaxtrack.filters.base import Filter
from jaxtrack.filters.births import LOG_ZERO
from jaxtrack.filters.cmt_conditions import group_members, predicted_mean, sharing_blob
from jaxtrack.filters.cmt_exchanges import (
    exchange_rows,
    next_episodes,
    overlaps,
    split_exchanges,
)
from jaxtrack.filters.cmt_observation import (
    NUM_LEVELS,
    NUM_VALUES,
    STEP,
    AppearanceState,
    COMParams,
    appearance_log_likelihood,
    box_features,
    init_appearance,
    num_features,
    observation_weights,
    update_appearance,
)
from jaxtrack.filters.cmt_proposal import (
    MERGE,
    NORMAL,
    CPDParams,
    contextual_proposal,
)
from jaxtrack.filters.mixture import (
    PARTICLES_PER_COMPONENT,
    local_estimate,
    mixture_weights,
    normalise_weights,
    resample_components,
    reweight,
)
from jaxtrack.filters.mixture_components import add_unexplained
from jaxtrack.filters.mixture_models import (
    bootstrap_proposal,
    log_transition,
    nearest_detection_log_likelihood,
)
from jaxtrack.filters.mixture_state import MixtureParams, MixtureState, init_mixture
from jaxtrack.filters.score_quantile import confident_score, count_scores, init_counts
from jaxtrack.models.dynamics import MEASURED, POSITION, SIZE, VELOCITY
from jaxtrack.models.likelihood import log_likelihood
from jaxtrack.models.noise import state_dependent_std
from jaxtrack.types import PAD_BOX, Detections, FrameInputs, Tracks

#: The variants of the ablation (CMT Sec. VII): plain mixture tracker, + contextual
#: proposal, + contextual observation model.
VARIANTS = ("mtb", "cpd", "cmt")
#: Zone slots of :class:`CMTParams` (padded).
MAX_ZONES = 16
#: Re-identification (``reidentify`` > 0, :func:`reidentified`): a new component takes back
#: the identity of a confirmed component deleted at most ``reidentify`` frames before when
#: its box centre lies within ``min(REID_GATE + REID_GATE_RATE * age, REID_MAX_GATE)`` of the
#: dead component's box heights from where its last velocity would have carried it, its
#: height within a factor ``REID_SIZE_RATIO`` of the dead one's, and the Bhattacharyya
#: distance between their colour histograms (:func:`colour_distance`) at most
#: ``REID_MAX_DISTANCE``, each the other's best such match. On the development scenes
#: (synthetic video seeds 0-2, ground-truth boxes 30 frames apart, every 10th frame) 56 % of
#: the same person's pairs and 0.7 % of two people's lie within 0.3 (within 0.4: 79 % and
#: 3.6 %, and CMT's exchanges there rose with it: 36 -> 44 a run, against 36 at 0.3).
REID_GATE = 1.0
REID_GATE_RATE = 0.1
REID_MAX_GATE = 3.0
REID_SIZE_RATIO = 1.5
REID_MAX_DISTANCE = 0.3


class CMTParams(NamedTuple):
    """Everything tunable in CMT (a PyTree: vmap to sweep, grad to tune).

    Attributes:
        mixture: the mixture filter's parameters (noise, thresholds).
        proposal: the contextual proposal's (:class:`~jaxtrack.filters.cmt_proposal.CPDParams`).
        observation: the observation model's
            (:class:`~jaxtrack.filters.cmt_observation.COMParams`).
        appearance_weight: exponent ``a`` of the feature mixture in the likelihood (>= 0).
        duplicate_iou: a component whose local decision overlaps an older component's by
            more than this IoU is unsupported on the frame (a second tracker on one target;
            deleted at once while unconfirmed).
        confirm_score: a component is output once a blob of at least this score explains its
            local decision (the PHD tracker's rule, :mod:`~jaxtrack.filters.phd_defaults`).
        confirm_quantile: ... or a blob scoring at least this quantile of the scores of
            every blob seen so far, when that is lower
            (:func:`~jaxtrack.filters.score_quantile.confident_score`; 1 or more:
            ``confirm_score`` alone).
        enter_distance: with the contextual proposal and known zones, a blob starts a
            component (*enter*) only within this many box heights of a zone (foot point to
            zone), or on the run's first frame (CMT initialises from every blob, Sec. VI).
        zone_boxes: ``[MAX_ZONES, 4]`` entry/exit zones ``(x, y, w, h)`` (padded).
        zone_mask: ``[MAX_ZONES]`` True for the real zones.
        velocity_rate: rate ``alpha`` of each component's long-run velocity ``v_bar <- (1 -
            alpha) v_bar + alpha v`` (:func:`held_velocities`; read only when the step is
            built with ``hold_velocity``).
        exchange_margin: the appearance gain (nats) a split exchange needs
            (:mod:`~jaxtrack.filters.cmt_exchanges`; read only when the step is built with
            ``exchange``).
    """

    mixture: MixtureParams
    proposal: CPDParams
    observation: COMParams
    appearance_weight: Float[Array, ""]
    duplicate_iou: Float[Array, ""]
    confirm_score: Float[Array, ""]
    confirm_quantile: Float[Array, ""]
    enter_distance: Float[Array, ""]
    zone_boxes: Float[Array, "max_zones 4"]
    zone_mask: Bool[Array, " max_zones"]
    velocity_rate: Float[Array, ""]
    exchange_margin: Float[Array, ""]


class Graveyard(NamedTuple):
    """Per slot, the last confirmed component deleted there (re-identification).

    Attributes:
        ids: its identity (-1: none, or taken back by a new component).
        estimates: its local decision on the frame it was deleted.
        frames: that frame (:attr:`CMTState.frame`).
        appearance: its appearance model then.
    """

    ids: Int[Array, " max_components"]
    estimates: Float[Array, "max_components 6"]
    frames: Int[Array, " max_components"]
    appearance: AppearanceState


class FreeBlobs(NamedTuple):
    """The blobs no component owned on the last frame, and for how long (:func:`free_runs`).

    Attributes:
        boxes: ``[max_components, 4]`` their boxes ``(x, y, w, h)``.
        runs: consecutive frames each has been free (0: an empty slot).
    """

    boxes: Float[Array, "max_components 4"]
    runs: Int[Array, " max_components"]


class CMTState(NamedTuple):
    """The scan carry.

    Attributes:
        mixture: the components' particles, weights, identities.
        appearance: their appearance models and decayed feature histograms.
        estimates: the last local decision of every slot (zeros for dead ones).
        confirmed: True once a confident blob explained the slot's component.
        misses: consecutive frames each component went unsupported.
        frame: frames stepped on.
        mean_velocity: ``[max_components, 2]`` each component's long-run velocity average
            (exponential, not yet corrected for its start at zero; :func:`held_velocities`).
        averaged: the frames that average holds.
        merged_frames: consecutive frames each component has shared a blob with another.
        graveyard: the last confirmed component that died in each slot
            (:class:`Graveyard`; read only when the step is built with ``reidentify`` > 0).
        free: the last frame's unowned blobs (:class:`FreeBlobs`; read only when the step is
            built with ``free_blob_frames`` > 0).
        score_counts: ``[SCORE_BINS]`` histogram of the scores of every blob seen so far
            (:func:`~jaxtrack.filters.score_quantile.confident_score`).
        episodes: ``[max_components, max_components]`` each pair's split-exchange episode
            (:func:`~jaxtrack.filters.cmt_exchanges.next_episodes`; read only when the step
            is built with ``exchange``).
    """

    mixture: MixtureState
    appearance: AppearanceState
    estimates: Float[Array, "max_components 6"]
    confirmed: Bool[Array, " max_components"]
    misses: Int[Array, " max_components"]
    frame: Int[Array, ""]
    mean_velocity: Float[Array, "max_components 2"]
    averaged: Float[Array, " max_components"]
    merged_frames: Float[Array, " max_components"]
    graveyard: Graveyard
    free: FreeBlobs
    score_counts: Float[Array, " score_bins"]
    episodes: Int[Array, "max_components max_components"]


class CMTInfo(NamedTuple):
    """Per-frame outputs.

    Attributes:
        tracks: the confirmed, supported components' local decisions (scores ``pi_m``).
        candidates: every supported component's local decision.
        particles: ``[max_components, num_particles, 6]`` the proposed particles.
        log_weights: their normalised log-weights.
        conditions: ``[max_components, num_particles]`` each particle's motion condition
            (:data:`~jaxtrack.filters.cmt_proposal.NORMAL` for ``"mtb"``).
        alive: the slots alive during the frame (before deletions and births).
        feature_weights: ``[max_components, num_features]`` the weights ``rho_k``.
        log_support: ``log w_m`` of every slot.
        overflow: True when a blob found no free slot for a new component.
    """

    tracks: Tracks
    candidates: Tracks
    particles: Float[Array, "max_components num_particles 6"]
    log_weights: Float[Array, "max_components num_particles"]
    conditions: Int[Array, "max_components num_particles"]
    alive: Bool[Array, " max_components"]
    feature_weights: Float[Array, "max_components num_features"]
    log_support: Float[Array, " max_components"]
    overflow: Bool[Array, ""]


def particle_boxes(particles: Float[Array, "*batch 6"]) -> Float[Array, "*batch 4"]:
    """The ``(x, y, w, h)`` boxes of states."""
    return cxcywh_to_xywh(particles[..., MEASURED], jnp)


def frame_features(
    frame: Array, boxes: Float[Array, "*batch 4"], step: float, patch_shape: tuple[int, int]
) -> Float[Array, "*batch num_features"]:
    """CMT's feature pool (:func:`~jaxtrack.filters.cmt_observation.box_features`) of every
    box, one flat vmap."""
    flat = boxes.reshape(-1, 4)
    features = jax.vmap(box_features, (None, 0, None, None))(frame, flat, step, patch_shape)
    return features.reshape(*boxes.shape[:-1], features.shape[-1])


def context_radius(
    estimates: Float[Array, "max_components 6"], params: CMTParams
) -> Float[Array, " max_components"]:
    """The field-of-context radius of each component: ``d_thr`` box heights (Sec. V-A)."""
    return params.proposal.context_distance * estimates[:, SIZE[1]]


def cmt_step(
    key: Array,
    state: CMTState,
    params: CMTParams,
    inputs_t: FrameInputs,
    *,
    variant: str,
    max_misses: int,
    group_blobs: bool = True,
    hold_velocity: bool = False,
    reidentify: int = 0,
    free_blob_frames: int = 0,
    box_support: bool = False,
    exchange: bool = False,
    step: float = STEP,
    patch_shape: tuple[int, int] = DEFAULT_PATCH_SHAPE,
    num_levels: int = NUM_LEVELS,
) -> tuple[CMTState, CMTInfo]:
    """One frame of CMT (the module's steps 1-6).

    Args:
        key: PRNG key of the frame.
        state: the carry after the previous frame.
        params: the tracker's parameters.
        inputs_t: the frame's blobs (detections) and image.
        variant: ``"mtb"``, ``"cpd"`` or ``"cmt"`` (static).
        max_misses: unsupported frames a component survives (static).
        group_blobs: compile the group-blob rule in (static; with False the step skips its
            membership test and grouped likelihood and never reads
            ``params.proposal.group_area_ratio``: 10-14 % faster, the same outputs as a
            ratio of 0).
        hold_velocity: with the contextual proposal, hold a merged component's long-run
            velocity (static; :func:`held_velocities`).
        reidentify: frames a deleted confirmed component's identity can be taken back by
            a new one (static; 0: never, the paper's tracker; :func:`reidentified`).
        free_blob_frames: a blob no component has owned for this many frames in a row
            starts one even where another component's particles explain it, a component is
            not confirmed while it overlaps an older one, and with ``reidentify`` > 0 an
            unconfirmed component, not only a newborn, may take back a dead one's identity
            (static; 0: never, the paper's dispelling rule; :func:`free_runs`,
            :func:`_crowded`).
        box_support: a component's support ``log w_m`` (verification, step 4) sums its
            particles' weights under the box likelihood alone, not times the appearance
            likelihood (static; False: the full likelihood, as eq. 4's ``pi_m`` always is).
            With the full likelihood the appearance exponent moves every support, so the
            threshold set for ``appearance_weight`` 1 deletes components at 2.
        exchange: with the contextual proposal, two components that collided exchange
            identities and appearance models when they separate if the observation model
            says each explains the other's blob better (static; False: never, the paper's
            tracker; :mod:`~jaxtrack.filters.cmt_exchanges`).
        step: colour quantisation step ``lambda`` (static).
        patch_shape: samples per box (static).
        num_levels: quantisation levels of eq. 17 (static).

    Returns:
        The new state and the frame's :class:`CMTInfo`.
    """
    key_propose, key_resample, key_add = jax.random.split(key, 3)
    mixture, blobs, frame = state.mixture, inputs_t.detections, inputs_t.frame
    alive = mixture.alive
    predictions = predicted_mean(state.estimates)
    holding = variant != "mtb" and hold_velocity  # the merge velocity is compiled in
    merged = jnp.zeros_like(alive)
    if holding:
        merged = sharing_blob(predictions, alive, blobs)
    groups = jnp.zeros((alive.shape[0], blobs.mask.shape[0]), bool)
    if variant != "mtb" and group_blobs:
        groups = group_members(predictions, alive, blobs, params.proposal.group_area_ratio)
    if variant == "mtb":
        particles, log_q = bootstrap_proposal(key_propose, mixture.particles, params.mixture, blobs)
        conditions = jnp.full(log_q.shape, NORMAL, jnp.int32)
        exited = jnp.zeros(log_q.shape, bool)
    else:
        draw = contextual_proposal(
            key_propose,
            mixture.particles,
            state.estimates,
            alive,
            params.proposal,
            params.mixture.motion_noise_std,
            blobs,
            params.zone_boxes,
            params.zone_mask,
            groups=groups,
        )
        particles, log_q, conditions, exited = (
            draw.particles,
            draw.log_q,
            draw.conditions,
            draw.exited,
        )
    features = frame_features(frame, particle_boxes(particles), step, patch_shape)
    radius = context_radius(state.estimates, params)
    rho = observation_weights(
        state.appearance.counts,
        state.estimates[:, (0, 2)],
        alive,
        radius,
        params.observation,
        num_levels,
        variant == "cmt",
    )
    log_appearance = appearance_log_likelihood(features, state.appearance, rho, params.observation)
    blob_features = frame_features(frame, blobs.boxes, step, patch_shape)
    blob_appearance = appearance_log_likelihood(
        jnp.broadcast_to(blob_features, (alive.shape[0], *blob_features.shape)),
        state.appearance,
        rho,
        params.observation,
    )
    owner = blob_owners(
        predictions,
        alive,
        blobs,
        params.appearance_weight * blob_appearance,
        params,
    )
    exchanging = exchange and variant != "mtb"
    appearance_before = state.appearance
    if exchanging:
        # Identities settled by the observation model when collided components separate;
        # the particles (this frame's weights included) stay with their clouds.
        partner, checked = split_exchanges(
            state.episodes,
            owner,
            blobs,
            blob_appearance,
            alive & state.confirmed,
            params.exchange_margin,
        )
        mixture = mixture._replace(ids=mixture.ids[partner])
        appearance_before = exchange_rows(partner, state.appearance)
    log_box = owned_log_likelihood(particles, params, blobs, owner)
    if group_blobs:
        log_box = jnp.maximum(
            log_box, grouped_log_likelihood(particles, predictions, params, blobs, groups)
        )
    log_likelihood = log_box + params.appearance_weight * log_appearance
    log_likelihood = jnp.where(exited, LOG_ZERO, log_likelihood)
    log_prior = log_transition(particles, mixture.particles, params.mixture)
    log_weights = reweight(mixture.log_weights, log_likelihood, log_prior, log_q)
    log_pi, log_support, _ = mixture_weights(mixture.log_mixture_weights, log_weights, alive)
    if box_support:  # the blobs' evidence alone, whatever the appearance exponent
        box_likelihood = jnp.where(exited, LOG_ZERO, log_box)
        box_weights = reweight(mixture.log_weights, box_likelihood, log_prior, log_q)
        log_support = jax.nn.logsumexp(box_weights, axis=-1)
    log_weights = normalise_weights(log_weights)
    estimates = jax.vmap(local_estimate)(particles, log_weights)

    # Verification: unsupported (no blob, or on an older component's target) for too long,
    # an unconfirmed duplicate, or a negligible mixture weight.
    duplicate = _duplicates(estimates, alive, mixture.ids, params)
    supported = (log_support >= params.mixture.min_log_support) & ~duplicate
    misses = jnp.where(alive & ~supported, state.misses + 1, 0)
    patience = max_misses
    if variant != "mtb":
        # Merge (Sec. IV-B): a component close to another may hide behind it.
        patience = jnp.where(_merging(state.estimates, alive, params), 4 * max_misses, max_misses)
    weak = (misses > patience) | (log_pi < jnp.log(params.mixture.min_mixture_weight))
    weak = weak | (duplicate & ~state.confirmed)
    survivors = alive & ~jax.lax.stop_gradient(weak)
    kept_pi = jnp.where(survivors, log_pi, LOG_ZERO)
    log_total = jnp.where(jnp.any(survivors), jax.nn.logsumexp(kept_pi), 0.0)
    log_pi = jnp.where(survivors, kept_pi - log_total, LOG_ZERO)
    local = estimates
    estimates = jnp.where(survivors[:, None], estimates, 0.0)

    score_counts = count_scores(state.score_counts, blobs)
    threshold = confident_score(score_counts, params.confirm_score, params.confirm_quantile)
    confirms = _confirms(estimates, blobs, params, threshold)
    if free_blob_frames > 0:
        confirms = confirms & ~_crowded(estimates, survivors, mixture.ids)
    confirmed = survivors & (state.confirmed | confirms)
    shown = survivors & supported
    candidates = _tracks(estimates, mixture.ids, shown, log_pi)
    tracks = _tracks(estimates, mixture.ids, shown & confirmed, log_pi)

    new_particles, new_log_weights = resample_components(key_resample, particles, log_weights)
    mean_velocity, averaged, merged_frames = (
        state.mean_velocity,
        state.averaged,
        state.merged_frames,
    )
    if holding:
        new_particles, estimates, mean_velocity, averaged, merged_frames = held_velocities(
            new_particles, estimates, state, merged, survivors, params.velocity_rate
        )
    resampled = MixtureState(
        particles=new_particles,
        log_weights=new_log_weights,
        log_mixture_weights=log_pi,
        alive=survivors,
        ids=jnp.where(survivors, mixture.ids, -1),
        next_id=mixture.next_id,
    )
    entering = blobs
    if variant != "mtb":
        entering = blobs._replace(
            mask=blobs.mask & _may_enter(blobs, state.frame, params) & ~jnp.any(groups, axis=0)
        )
    free = state.free
    forced = None
    if free_blob_frames > 0:
        free, runs = free_runs(state.free, blobs, owner)
        forced = entering.mask & (runs >= free_blob_frames)
    new_mixture, overflow = add_unexplained(
        key_add, resampled, entering, params.mixture, forced=forced
    )
    born = new_mixture.alive & ~survivors

    # Appearance: features at the local decisions (a newborn's at its particles' mean).
    decisions = jnp.where(born[:, None], jnp.mean(new_mixture.particles, axis=1), estimates)
    decision_features = frame_features(frame, particle_boxes(decisions), step, patch_shape)
    merge_share = jnp.sum(jnp.exp(log_weights) * (conditions == MERGE), axis=-1)
    frozen = merge_share > 0.5
    if exchanging:  # a component overlapping another learns nothing (cmt_exchanges)
        close = overlaps(particle_boxes(estimates), survivors)
        frozen = frozen | jnp.any(close, axis=1)
    appearance = update_appearance(
        appearance_before,
        decision_features,
        survivors & supported,
        frozen,
        born,
        params.observation,
    )
    confirmed = confirmed & ~born
    graveyard = state.graveyard
    if reidentify > 0:
        heirs = born
        if free_blob_frames > 0:
            # Handover: a free blob's component is often born before the component that
            # lost its target dies; an unconfirmed one may take that identity back too
            # (newborns are unconfirmed: ``confirmed`` excludes them).
            heirs = new_mixture.alive & ~confirmed
        entry = reidentified(
            graveyard, heirs, decisions, decision_features, state.frame, reidentify, step
        )
        revived = entry >= 0
        entry = jnp.maximum(entry, 0)
        new_mixture = new_mixture._replace(
            ids=jnp.where(revived, graveyard.ids[entry], new_mixture.ids)
        )
        confirmed = confirmed | revived
        appearance = jax.tree.map(
            lambda new, old: select_rows(revived, old[entry], new), appearance, graveyard.appearance
        )
        taken = jnp.zeros_like(revived).at[entry].max(revived)
        graveyard = bury(
            graveyard._replace(ids=jnp.where(taken, -1, graveyard.ids)),
            alive & ~survivors & state.confirmed,
            mixture.ids,
            local,
            state.frame,
            appearance_before,
        )
    new_state = CMTState(
        mixture=new_mixture,
        appearance=appearance,
        estimates=jnp.where(born[:, None], decisions, estimates),
        confirmed=confirmed,
        misses=jnp.where(new_mixture.alive & ~born, misses, 0),
        frame=state.frame + 1,
        mean_velocity=jnp.where(born[:, None], 0.0, mean_velocity),
        averaged=jnp.where(born, 0.0, averaged),
        merged_frames=jnp.where(born, 0.0, merged_frames),
        graveyard=graveyard,
        free=free,
        score_counts=score_counts,
        episodes=next_episodes(state.episodes, checked, close, survivors)
        if exchanging
        else state.episodes,
    )
    info = CMTInfo(
        tracks=tracks,
        candidates=candidates,
        particles=particles,
        log_weights=log_weights,
        conditions=conditions,
        alive=alive,
        feature_weights=rho,
        log_support=log_support,
        overflow=overflow,
    )
    return new_state, info


def init_cmt(
    key: Array,
    params: CMTParams,
    max_components: int,
    num_particles: int,
    num_features: int,
    num_values: int = NUM_VALUES,
) -> CMTState:
    """The state before the first frame: every slot dead (sizes static)."""
    mixture = init_mixture(key, params.mixture, max_components, num_particles)
    appearance = init_appearance(max_components, num_features, num_values)
    return CMTState(
        mixture=mixture,
        appearance=appearance,
        estimates=jnp.zeros((max_components, 6), jnp.float32),
        confirmed=jnp.zeros((max_components,), bool),
        misses=jnp.zeros((max_components,), jnp.int32),
        frame=jnp.zeros((), jnp.int32),
        mean_velocity=jnp.zeros((max_components, 2), jnp.float32),
        averaged=jnp.zeros((max_components,), jnp.float32),
        merged_frames=jnp.zeros((max_components,), jnp.float32),
        graveyard=Graveyard(
            ids=jnp.full((max_components,), -1, jnp.int32),
            estimates=jnp.zeros((max_components, 6), jnp.float32),
            frames=jnp.zeros((max_components,), jnp.int32),
            appearance=appearance,
        ),
        free=FreeBlobs(
            boxes=jnp.zeros((max_components, 4), jnp.float32),
            runs=jnp.zeros((max_components,), jnp.int32),
        ),
        score_counts=init_counts(),
        episodes=jnp.zeros((max_components, max_components), jnp.int8),
    )


#: IoU above which a free blob continues a free blob of the previous frame (:func:`free_runs`).
FREE_BLOB_IOU = 0.5


def free_runs(
    free: FreeBlobs, blobs: Detections, owner: Int[Array, " max_detections"]
) -> tuple[FreeBlobs, Int[Array, " max_detections"]]:
    """How long each blob has gone unowned, and the free blobs kept for the next frame.

    A blob no component owns (``owner`` < 0, :func:`blob_owners`) continues the longest run
    of the previous frame's free blobs it overlaps by IoU above :data:`FREE_BLOB_IOU`; an
    owned blob's run is 0. The longest runs fill the kept slots.

    Returns:
        The kept :class:`FreeBlobs` and every blob's run (this frame included).
    """
    unowned = blobs.mask & (owner < 0)
    overlap = iou_matrix(blobs.boxes, free.boxes, jnp)
    previous = jnp.max(
        jnp.where((overlap > FREE_BLOB_IOU) & (free.runs > 0)[None, :], free.runs[None, :], 0),
        axis=1,
    )
    runs = jnp.where(unowned, previous + 1, 0)
    slots = free.runs.shape[0]
    order = jnp.argsort(-runs)[:slots]
    kept_runs = jnp.zeros((slots,), jnp.int32).at[: order.shape[0]].set(runs[order])
    kept_boxes = (
        jnp.zeros((slots, 4), free.boxes.dtype)
        .at[: order.shape[0]]
        .set(blobs.boxes[order].astype(free.boxes.dtype))
    )
    return FreeBlobs(kept_boxes, kept_runs), runs


def bury(
    graveyard: Graveyard,
    dying: Bool[Array, " max_components"],
    ids: Int[Array, " max_components"],
    estimates: Float[Array, "max_components 6"],
    frame: Int[Array, ""],
    appearance: AppearanceState,
) -> Graveyard:
    """The graveyard with each ``dying`` slot's component written over that slot's entry."""
    pick = functools.partial(select_rows, dying)
    return Graveyard(
        ids=pick(ids, graveyard.ids),
        estimates=pick(estimates, graveyard.estimates),
        frames=pick(jnp.broadcast_to(frame, dying.shape), graveyard.frames),
        appearance=jax.tree.map(pick, appearance, graveyard.appearance),
    )


def select_rows(rows: Bool[Array, " n"], new: Array, old: Array) -> Array:
    """``new`` where ``rows`` (along the leading axis) is True, else ``old``."""
    return jnp.where(rows.reshape(-1, *([1] * (new.ndim - 1))), new, old)


def colour_distance(
    models: Float[Array, "rows num_features"],
    features: Float[Array, "cols num_features"],
    step: float = STEP,
) -> Float[Array, "rows cols"]:
    """Bhattacharyya distance ``sqrt(1 - BC)`` between the colour parts of feature vectors
    (:func:`~jaxtrack.filters.cmt_observation.box_features`: six normalised histograms of
    ``ceil(256 / lambda)`` buckets, then the shape), ``BC`` averaged over the six."""
    bins = num_bins(step)
    model_histograms = models[:, None, : 6 * bins].reshape(models.shape[0], 1, 6, bins)
    feature_histograms = features[None, :, : 6 * bins].reshape(1, features.shape[0], 6, bins)
    coefficient = jnp.mean(bhattacharyya_coefficient(model_histograms, feature_histograms), -1)
    return jnp.sqrt(jnp.maximum(1.0 - coefficient, 0.0))


def reidentified(
    graveyard: Graveyard,
    born: Bool[Array, " max_components"],
    decisions: Float[Array, "max_components 6"],
    features: Float[Array, "max_components num_features"],
    frame: Int[Array, ""],
    reidentify: int,
    step: float = STEP,
) -> Int[Array, " max_components"]:
    """For each slot, the graveyard entry whose identity its new component takes back, or -1.

    Entry ``g`` (deleted ``age = frame - frames_g`` frames before, ``1 <= age <=
    reidentify``) and newborn ``m`` (box ``decisions_m``) may pair when ``m``'s centre is within
    ``min(REID_GATE + REID_GATE_RATE age, REID_MAX_GATE) h_g`` of ``g``'s centre moved
    ``age`` frames at ``g``'s velocity, ``|log(h_m / h_g)| <= log REID_SIZE_RATIO`` and
    :func:`colour_distance` of ``g``'s model and ``m``'s features is at most
    ``REID_MAX_DISTANCE``; a pair is kept when each is the other's nearest in colour among
    those allowed (so no identity is given twice).
    """
    age = frame - graveyard.frames
    valid = (graveyard.ids >= 0) & (age >= 1) & (age <= reidentify)
    valid = valid & graveyard.appearance.initialised
    ages = jnp.clip(age, 0, reidentify).astype(decisions.dtype)
    dead = graveyard.estimates
    centres = dead[:, POSITION] + dead[:, VELOCITY] * ages[:, None]
    heights = jnp.maximum(dead[:, SIZE[1]], 1e-3)
    offsets = decisions[None, :, POSITION] - centres[:, None, :]
    distance = jnp.sqrt(jnp.sum(offsets**2, axis=-1)) / heights[:, None]
    gate = jnp.minimum(REID_GATE + REID_GATE_RATE * ages, REID_MAX_GATE)
    sizes = jnp.abs(jnp.log(jnp.maximum(decisions[None, :, SIZE[1]], 1e-3) / heights[:, None]))
    colour = colour_distance(graveyard.appearance.model, features, step)
    allowed = valid[:, None] & born[None, :] & (distance <= gate[:, None])
    allowed = allowed & (sizes <= math.log(REID_SIZE_RATIO)) & (colour <= REID_MAX_DISTANCE)
    cost = jnp.where(allowed, colour, jnp.inf)
    best_entry = jnp.argmin(cost, axis=0)
    best_born = jnp.argmin(cost, axis=1)
    slots = jnp.arange(born.shape[0])
    mutual = allowed[best_entry, slots] & (best_born[best_entry] == slots)
    return jnp.where(mutual, best_entry, -1)


def cmt_filter(
    variant: str,
    max_components: int,
    particles_per_component: int = PARTICLES_PER_COMPONENT,
    max_misses: int = 5,
    group_blobs: bool = True,
    hold_velocity: bool = False,
    reidentify: int = 0,
    free_blob_frames: int = 0,
    box_support: bool = False,
    exchange: bool = False,
) -> Filter:
    """Builds CMT; all arguments are static.

    Args:
        variant: ``"mtb"``, ``"cpd"`` or ``"cmt"`` (:data:`VARIANTS`).
        max_components: local tracker slots (> 0).
        particles_per_component: particles per local tracker (> 0; 40 in CMT).
        max_misses: unsupported frames a component survives.
        group_blobs: compile the group-blob rule in (see :func:`cmt_step`); False when
            ``params.proposal.group_area_ratio`` will be 0, which it then ignores.
        hold_velocity: compile the merge velocity in (see :func:`cmt_step`).
        reidentify: frames within which a new component may take back a deleted confirmed
            component's identity (see :func:`cmt_step`; 0: never).
        free_blob_frames: frames a blob stays unowned before it starts a component whatever
            explains it (see :func:`cmt_step`; 0: never).
        box_support: supports from the box likelihood alone (see :func:`cmt_step`).
        exchange: compile split exchanges in (see :func:`cmt_step`).

    Returns:
        The :class:`~jaxtrack.filters.base.Filter` (steps on
        :class:`~jaxtrack.types.FrameInputs`).

    Raises:
        ValueError: an unknown variant or a non-positive size.
    """
    if variant not in VARIANTS:
        raise ValueError(f"variant must be one of {', '.join(VARIANTS)}, got {variant!r}")
    if max_components <= 0 or particles_per_component <= 0:
        raise ValueError(
            "max_components and particles_per_component must be positive, got "
            f"{max_components} and {particles_per_component}"
        )
    step = functools.partial(
        cmt_step,
        variant=variant,
        max_misses=max_misses,
        group_blobs=group_blobs,
        hold_velocity=hold_velocity,
        reidentify=reidentify,
        free_blob_frames=free_blob_frames,
        box_support=box_support,
        exchange=exchange,
    )
    init = functools.partial(
        init_cmt,
        max_components=max_components,
        num_particles=particles_per_component,
        num_features=num_features(),
    )
    return Filter(init=init, step=step)


def _confirms(
    estimates: Float[Array, "max_components 6"],
    blobs: Detections,
    params: CMTParams,
    threshold: Float[Array, ""],
) -> Bool[Array, " max_components"]:
    """True for the components a blob of score ``>= threshold`` explains (its box
    log-likelihood under the local decision above ``birth_log_likelihood``)."""
    measurements = xywh_to_cxcywh(blobs.boxes, jnp)
    scores = log_likelihood(
        measurements, estimates, params.mixture.measurement_noise_std, state_dependent_std
    )
    confident = blobs.mask & (blobs.scores >= threshold)
    return jnp.any(confident[:, None] & (scores > params.mixture.birth_log_likelihood), axis=0)


def blob_owners(
    predictions: Float[Array, "max_components 6"],
    alive: Bool[Array, " max_components"],
    blobs: Detections,
    log_appearance: Float[Array, "max_components max_detections"],
    params: CMTParams,
) -> Int[Array, " max_detections"]:
    """The component each blob is evidence for (-1: none, a blob free to start one).

    Greedy on the blob's log-likelihood under each component: the box likelihood under the
    component's constant-velocity prediction plus ``log_appearance`` (the observation model
    on the blob's own box, so COM's feature weights tell apart nearby targets here too):
    the best (component, blob) pair is matched, both are removed, and so on, over pairs whose
    box likelihood is above ``birth_log_likelihood`` (the gate). One blob is evidence for one
    component, so two components cannot both feed on it (the nearest-blob likelihood alone
    lets a component whose target vanished latch onto a neighbour's blob).
    """
    measurements = xywh_to_cxcywh(blobs.boxes, jnp)
    box = log_likelihood(
        measurements, predictions, params.mixture.measurement_noise_std, state_dependent_std
    )
    gate = blobs.mask[:, None] & alive[None, :] & (box > params.mixture.birth_log_likelihood)
    scores = jax.lax.stop_gradient(jnp.where(gate, box + log_appearance.T, -jnp.inf))
    num_blobs, num_slots = scores.shape

    def match(carry, _):
        remaining, owner = carry
        best = jnp.argmax(remaining)
        blob, slot = best // num_slots, best % num_slots
        found = jnp.isfinite(remaining[blob, slot])
        owner = jnp.where(found, owner.at[blob].set(slot), owner)
        remaining = jnp.where(found, remaining.at[blob].set(-jnp.inf), remaining)
        remaining = jnp.where(found, remaining.at[:, slot].set(-jnp.inf), remaining)
        return (remaining, owner), None

    owner = jnp.full((num_blobs,), -1, jnp.int32)
    (_, owner), _ = jax.lax.scan(match, (scores, owner), None, length=min(num_blobs, num_slots))
    return owner


def owned_log_likelihood(
    particles: Float[Array, "max_components num_particles 6"],
    params: CMTParams,
    blobs: Detections,
    owner: Int[Array, " max_detections"],
) -> Float[Array, "max_components num_particles"]:
    """The box likelihood of each particle: the best of its component's own blob and the
    free blobs (:func:`blob_owners`), floored at ``background_log_likelihood``
    (:func:`~jaxtrack.filters.mixture_models.nearest_detection_log_likelihood` over the
    blobs the component may use)."""
    slots = jnp.arange(particles.shape[0])
    usable = blobs.mask[None, :] & ((owner[None, :] == slots[:, None]) | (owner[None, :] < 0))

    def one(component_particles, component_usable):
        own = blobs._replace(mask=component_usable)
        return nearest_detection_log_likelihood(component_particles[None], params.mixture, own)[0]

    return jax.vmap(one)(particles, usable)


def group_anchors(
    predictions: Float[Array, "max_components 6"],
    groups: Bool[Array, "max_components max_detections"],
) -> Bool[Array, "max_components max_detections 4"]:
    """Which edges of each group blob each member accounts for (left, top, right, bottom).

    A group blob is the box of its members together: its left edge is the left edge of the
    member whose predicted box reaches furthest left, and so on. ``anchors[m, j, e]`` is
    True when member ``m``'s predicted box is the extreme one of blob ``j``'s members on
    edge ``e`` (ties: all of them).
    """
    boxes = particle_boxes(predictions)
    edges = jnp.concatenate([boxes[:, :2], boxes[:, :2] + boxes[:, 2:]], axis=-1)
    signs = jnp.array([-1.0, -1.0, 1.0, 1.0])  # left and top: smallest; right, bottom: largest
    reach = jnp.where(groups[..., None], (signs * edges)[:, None, :], -jnp.inf)
    return groups[..., None] & (reach == jnp.max(reach, axis=0, keepdims=True))


def grouped_log_likelihood(
    particles: Float[Array, "max_components num_particles 6"],
    predictions: Float[Array, "max_components 6"],
    params: CMTParams,
    blobs: Detections,
    groups: Bool[Array, "max_components max_detections"],
) -> Float[Array, "max_components num_particles"]:
    """The box likelihood of each particle on the group blobs its component is a member of
    (:func:`~jaxtrack.filters.cmt_conditions.group_members`; ``LOG_ZERO`` where none).

    A group blob is the box of its members together: each of its edges is some member's
    edge (:func:`group_anchors`), and every member lies inside it. Per edge ``e`` of the
    particle's box (``x_0, y_0, x_1, y_1``) against the blob's, the residual is the edge's
    offset where the component's prediction is the extreme member on that edge, else the
    part of the box outside the blob (``max(0, b_x0 - x_0)`` on the left, and so on); the
    likelihood is the box likelihood's Gaussian (:func:`~jaxtrack.models.likelihood.
    log_likelihood`'s SDV standard deviations ``s_1`` for the vertical edges, ``s_2`` for
    the horizontal ones, and its four-coordinate normaliser) of these residuals. The
    standard deviations are those of the component's predicted box (``predictions``: the
    constant-velocity prediction of its previous local decision, whose size it keeps), the
    same for all its particles, so that smaller boxes are not favoured. Box sizes are not observed
    directly: they follow the motion model within what the anchored edges allow.
    """
    std = state_dependent_std(predictions[:, SIZE], params.mixture.measurement_noise_std)
    std = jnp.where(jnp.all(std > 0, axis=-1, keepdims=True), std, 1.0)
    log_norm = jnp.sum(jnp.log(std), axis=-1) + 2 * jnp.log(2 * jnp.pi)
    edge_std = std[:, (0, 1, 0, 1)][:, None, None, :]
    boxes = particle_boxes(particles)[..., None, :]
    edges = jnp.concatenate([boxes[..., :2], boxes[..., :2] + boxes[..., 2:]], axis=-1)
    blob_edges = jnp.concatenate([blobs.boxes[:, :2], blobs.boxes[:, :2] + blobs.boxes[:, 2:]], -1)
    signs = jnp.array([-1.0, -1.0, 1.0, 1.0])
    beyond = signs * (edges - blob_edges)  # > 0: the particle's edge is outside the blob
    anchors = group_anchors(predictions, groups)[:, None]
    residual = jnp.where(anchors, beyond, jax.nn.relu(beyond)) / edge_std
    per_blob = -0.5 * jnp.sum(residual**2, axis=-1) - log_norm[:, None, None]
    per_blob = jnp.where(groups[:, None, :], per_blob, LOG_ZERO)
    return jnp.max(per_blob, axis=-1, initial=LOG_ZERO)


def held_velocities(
    particles: Float[Array, "max_components num_particles 6"],
    estimates: Float[Array, "max_components 6"],
    state: CMTState,
    merged: Bool[Array, " max_components"],
    survivors: Bool[Array, " max_components"],
    rate: Float[Array, ""],
) -> tuple[
    Float[Array, "max_components num_particles 6"],
    Float[Array, "max_components 6"],
    Float[Array, "max_components 2"],
    Float[Array, " max_components"],
    Float[Array, " max_components"],
]:
    """The merge condition's motion (CMT Sec. IV-B: a merged target follows its own motion
    model, frozen like its appearance) for the velocity part of the state.

    While one blob holds two components' predicted centres (``merged``,
    :func:`~jaxtrack.filters.cmt_conditions.sharing_blob`), the box follows the pair's
    centre, which stands still as two people pass: the velocity the particles infer from it
    is the pair's, not the target's, and the component comes out of the merge moving the
    wrong way (CMT's identity exchanges at crossings). So each component keeps a long-run
    velocity, the exponential average of its decisions' velocities outside merges,

        v_bar_t = (1 - alpha) v_bar_{t-1} + alpha v_t     (not merged; held while merged),

    started at zero when the component is born and read with the bias correction
    ``v_bar / (1 - (1 - alpha)^n)`` after ``n`` averaged frames. A surviving merged
    component whose average holds at least ``1 / alpha`` frames (one time constant) gets
    ``v_bar`` as the velocity of all its resampled particles and of its decision; positions
    and sizes still follow the blob. A younger one is left alone (its average says little).
    A merge is held for its first ``1 / alpha`` frames only: one that lasts longer (two
    people walking or standing together) is the pair's motion, which is then the target's
    own, so the component is treated as not merged (its average resumes).

    Returns:
        ``(particles, estimates, mean_velocity, averaged, merged_frames)``: the resampled
        particles and the decisions with the held velocities, the updated averages, their
        frame counts and the merges' lengths.
    """
    old, count = state.mean_velocity, state.averaged
    frames = jnp.where(merged, state.merged_frames + 1.0, 0.0)
    merged = merged & (state.merged_frames * rate < 1.0 - 1e-6)
    corrected = old / jnp.maximum(1.0 - (1.0 - rate) ** count, 1e-6)[:, None]
    hold = survivors & merged & (count * rate >= 1.0 - 1e-6)
    velocity = jnp.array(VELOCITY)
    particles = particles.at[..., velocity].set(
        jnp.where(hold[:, None, None], corrected[:, None, :], particles[..., velocity])
    )
    estimates = estimates.at[:, velocity].set(
        jnp.where(hold[:, None], corrected, estimates[:, velocity])
    )
    averaged = jnp.where(merged[:, None], old, (1.0 - rate) * old + rate * estimates[:, velocity])
    return particles, estimates, averaged, count + (~merged).astype(count.dtype), frames


def _merging(
    estimates: Float[Array, "max_components 6"],
    alive: Bool[Array, " max_components"],
    params: CMTParams,
) -> Bool[Array, " max_components"]:
    """True for a component with another living one within ``context_distance`` of its
    box heights (its field of context, where merges happen)."""
    gaps = estimates[:, None, POSITION] - estimates[None, :, POSITION]
    distance = jnp.sqrt(jnp.sum(gaps**2, axis=-1))
    near = distance < context_radius(estimates, params)[:, None]
    others = alive[None, :] & ~jnp.eye(alive.shape[0], dtype=bool)
    return alive & jnp.any(near & others, axis=1)


#: IoU of a component's local decision with an older component's above which it is not
#: confirmed (with free-blob births on: :func:`_crowded`).
SEPARATION_IOU = 0.1


def _crowded(
    estimates: Float[Array, "max_components 6"],
    alive: Bool[Array, " max_components"],
    ids: Int[Array, " max_components"],
) -> Bool[Array, " max_components"]:
    """True for a component whose local decision overlaps an older living component's by IoU
    above :data:`SEPARATION_IOU`. With free-blob births on, such a component is not confirmed
    (a blob that goes unowned beside a tracked target is as often the detector's second box
    of that target as another person: it earns its confirmation once apart)."""
    return _overlaps_older(estimates, alive, ids, SEPARATION_IOU)


def _duplicates(
    estimates: Float[Array, "max_components 6"],
    alive: Bool[Array, " max_components"],
    ids: Int[Array, " max_components"],
    params: CMTParams,
) -> Bool[Array, " max_components"]:
    """True for a component whose local decision overlaps an older living component's by
    IoU above ``duplicate_iou`` (Vermaak et al. merge overlapping components; here the
    younger one is not supported on the frame: an unconfirmed one is deleted at once, a
    confirmed one after ``max_misses`` such frames, so two targets crossing both live)."""
    return _overlaps_older(estimates, alive, ids, params.duplicate_iou)


def _overlaps_older(
    estimates: Float[Array, "max_components 6"],
    alive: Bool[Array, " max_components"],
    ids: Int[Array, " max_components"],
    threshold: float | Float[Array, ""],
) -> Bool[Array, " max_components"]:
    """True for a living component whose local decision overlaps an older (smaller id)
    living component's by IoU above ``threshold``."""
    overlap = iou_matrix(particle_boxes(estimates), particle_boxes(estimates), jnp)
    older = ids[None, :] < ids[:, None]
    pair = alive[:, None] & alive[None, :] & older & (overlap > threshold)
    return jnp.any(pair, axis=1)


def _may_enter(
    blobs: Detections, frame: Int[Array, ""], params: CMTParams
) -> Bool[Array, " max_detections"]:
    """The blobs that may start a component under the contextual proposal (*enter*): on the
    first frame, or with no zone known, every blob; else those whose foot point lies within
    ``enter_distance`` box heights of a zone."""
    feet = blobs.boxes[:, :2] + blobs.boxes[:, 2:] * jnp.array([0.5, 1.0])
    boxes = jnp.where(params.zone_mask[:, None], params.zone_boxes, -1e6)
    near = zone_distance(boxes, feet) <= params.enter_distance * blobs.boxes[:, 3]
    return near | (frame == 0) | ~jnp.any(params.zone_mask)


def _tracks(
    estimates: Float[Array, "max_components 6"],
    ids: Int[Array, " max_components"],
    shown: Bool[Array, " max_components"],
    log_pi: Float[Array, " max_components"],
) -> Tracks:
    """The shown components' local decisions as labelled boxes."""
    boxes = particle_boxes(estimates)
    return Tracks(
        boxes=jnp.where(shown[:, None], boxes, jnp.asarray(PAD_BOX, boxes.dtype)),
        ids=jnp.where(shown, ids, -1),
        scores=jnp.where(shown, jnp.exp(log_pi), 0.0),
        mask=shown,
    )
