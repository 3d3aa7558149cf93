"""Particle PHD multi-target tracker (PHD-context Sec. III, SPEC section 1).

One :func:`phd_filter` step on frame ``k`` with detections ``Z_k`` is :func:`phd_step`, which
composes public stages (a benchmark or a test composes them the same way):

1. predict the survivors through the dynamics, ``w_i <- e(x_i) w_i`` (eq. 9, :func:`predict`);
2. add measurement-driven births (:func:`phd_births`, :mod:`~jaxtrack.filters.births`);
3. update (eq. 10, :func:`phd_update`),
   ``w_i <- [pM + sum_z psi_z(x_i) / (kappa(z) + C(z))] w_i``,
   ``psi_z(x) = (1 - pM) g(z | x)``, ``C(z) = sum_j psi_z(x_j) w_j``, in log space, optionally
   with the detector scores as a detection feature (:func:`score_log_ratio`) and with the
   detections targets generate besides their own added to ``kappa`` (:class:`TargetClutter`,
   learned by a context; none by default);
4. resample to ``num_particles`` preserving the mass (:mod:`~jaxtrack.filters.resampling`);
5. extract the states (:func:`partition_estimates`, :func:`gmm_estimates`); the update's
   blocked pass already reduced what they need from the ``[detections, particles]`` pairs;
6. label them (:mod:`~jaxtrack.association.labelling`); tracks are output once confirmed by
   a detection score of at least ``params.labelling.confirm_score``.

It also returns the PHD measurement log-likelihood of the frame (Poisson approximation),
``log p(Z_k | Z_1:k-1) ~= -sum_i (1 - pM) w_i - int kappa + sum_z log(kappa(z) + C(z))``
over the predicted particles (survivors and births), the objective for gradient-based tuning.
Steps 5-6 see no gradient.

Detections come padded (``max_detections`` slots with a mask): one compile per capacity.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, Literal, NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from jaxtrack.association.estimates import Estimates
from jaxtrack.association.labelling import (
    LabelParams,
    Labels,
    LabelState,
    confirm_by_calibrated_evidence,
    confirm_by_evidence,
    confirm_by_score,
    init_labels,
    label_step,
    score_log_odds,
)
from jaxtrack.boxes import cxcywh_to_xywh, xywh_to_cxcywh
from jaxtrack.context.intensity import Intensity, log_intensity
from jaxtrack.control import any_member
from jaxtrack.filters import draws
from jaxtrack.filters.base import Filter
from jaxtrack.filters.births import (
    LOG_ZERO,
    VELOCITY_PROPOSALS,
    PreviousDetections,
    birth_requests,
    keep_previous_detections,
    no_previous_detections,
    sample_births,
)
from jaxtrack.filters.extraction import gmm_clusters, measurement_partition
from jaxtrack.filters.resampling import ResamplingScheme, resample, systematic
from jaxtrack.models.dynamics import MEASURED, STATE_DIM, rows_layout, sample_constant_velocity
from jaxtrack.models.likelihood import log_likelihood
from jaxtrack.models.noise import NoiseModel, state_dependent_std
from jaxtrack.models.survival import SurvivalMap, survival_probability
from jaxtrack.types import PAD_BOX, Detections, Tracks


class TargetClutter(NamedTuple):
    """Detections a target generates besides its own: ``kappa_t(z) = rate int q(z | x) D(x) dx``.

    A real detector gives some targets a second box, or a box on a part of the person, beside
    the box of the target itself (the detections :mod:`jaxtrack.context.samples` leaves out of
    the clutter events because they overlap an object). The PHD update's model has one
    detection per target at most; these extra detections are then explained as new targets
    (a duplicate box) or as scene clutter along the targets' paths. Here each target
    generates a Poisson number of them, ``rate`` per frame, spread around it by
    ``q(z | x) = N(z; h(x), diag(s(x))^2)`` with ``s(x)`` the SDV scale of ``noise_std``
    (relative to the box, like the likelihood's); their intensity moves with the targets and
    adds to the scene's clutter in the update's denominator (:func:`phd_update`).
    ``rate = 0`` (the default of every run without a learned context) is the paper's model.

    Attributes:
        rate: extra detections per target per frame, ``>= 0``.
        noise_std: relative standard deviations ``(s_1, s_2, s_w, s_h)`` of ``q``, > 0.
    """

    rate: Float[Array, ""]
    noise_std: Float[Array, " 4"]


class PHDParams(NamedTuple):
    """Everything tunable in the PHD tracker (a PyTree: vmap to sweep, grad to tune).

    Attributes:
        motion_noise_std: ``(sigma_n1, sigma_n2, sigma_nw, sigma_nh)`` of the dynamics, > 0;
            relative to the box size per frame with the SDV noise model (PHD-context Sec. III).
        measurement_noise_std: ``(s_1, s_2, s_w, s_h)`` of the likelihood, > 0; relative to
            the box size with the SDV noise model.
        detection_prob: ``1 - pM`` in ``(0, 1]``.
        survival_prob: ``e(x)``, a constant in ``(0, 1]`` or a
            :class:`~jaxtrack.models.survival.SurvivalMap`.
        birth_intensity: ``gamma(x)`` over the 6-D state space (PHD-context eq. 19).
        initial_intensity: the intensity of the targets already present when the run starts:
            on the first frame it replaces ``birth_intensity`` (births around the first
            frame's detections). A learned birth intensity describes where targets *enter*;
            a span that starts with targets in view needs births anywhere on its first frame
            (the defaults use the uniform birth intensity here).
        clutter_intensity: ``kappa(z)`` over the 4-D measurement space (eq. 20).
        score_weight: ``beta >= 0``, weight of the detector scores: a detection with score
            ``s`` has its clutter intensity divided by ``(s / (1 - s))^beta`` (see
            :func:`score_log_ratio`); 0 ignores the scores (plain eq. 10).
        mass_threshold: an extracted cluster / detection part becomes an estimate when its mass
            exceeds it, in ``(0, 1)`` (0.5 in the paper).
        labelling: gate and track-ending rule of the labelling.
        target_clutter: the detections targets generate besides their own
            (:class:`TargetClutter`; rate 0: none).
    """

    motion_noise_std: Float[Array, " 4"]
    measurement_noise_std: Float[Array, " 4"]
    detection_prob: Float[Array, ""]
    survival_prob: Float[Array, ""] | SurvivalMap
    birth_intensity: Intensity
    initial_intensity: Intensity
    clutter_intensity: Intensity
    score_weight: Float[Array, ""]
    mass_threshold: Float[Array, ""]
    labelling: LabelParams
    target_clutter: TargetClutter


class PHDState(NamedTuple):
    """The scan carry.

    Attributes:
        particles: ``(y1, vy1, y2, vy2, w, h)`` of each particle.
        log_weights: particle log-weights (``LOG_ZERO`` for no mass).
        mass: total PHD mass ``sum_i w_i`` (expected number of targets).
        labels: the labelling's track table.
        started: False before the first frame (which uses ``params.initial_intensity``).
        previous: the previous frame's detections (the births' velocity proposal).
    """

    particles: Float[Array, "num_particles 6"]
    log_weights: Float[Array, " num_particles"]
    mass: Float[Array, ""]
    labels: LabelState
    started: Bool[Array, ""]
    previous: PreviousDetections


class PHDInfo(NamedTuple):
    """Per-frame outputs (stacked over frames by :func:`~jaxtrack.filters.base.run`).

    Attributes:
        tracks: the online output, labelled boxes of confirmed tracks: a frame of
            :class:`~jaxtrack.types.Tracks` (top-left ``x, y, w, h``; scores are the
            estimates' PHD masses).
        candidates: every labelled estimate, tentative tracks included (for offline
            post-processing such as :func:`~jaxtrack.association.offline.finalise_tracks`).
        estimates: the extracted states, velocities included.
        mass: PHD mass after the update.
        log_likelihood: PHD measurement log-likelihood of the frame.
        track_overflow: True when new tracks did not fit in the track table.
    """

    tracks: Tracks
    candidates: Tracks
    estimates: Estimates
    mass: Float[Array, ""]
    log_likelihood: Float[Array, ""]
    track_overflow: Bool[Array, ""]


class PHDUpdate(NamedTuple):
    """The outputs of :func:`phd_update`.

    Attributes:
        log_weights: updated log-weights (at least ``LOG_ZERO``).
        log_likelihood: the PHD measurement log-likelihood of the frame.
        detection_log_masses: ``log(C(z) / (kappa(z) / r(s_z) + C(z)))``, the log-mass of each
            detection's part ``D_z`` of the updated PHD (``LOG_ZERO`` for padded detections).
        detection_states: weighted mean state of each detection's part,
            ``sum_i psi_z(x_i) w_i x_i / C(z)`` (zeros for padded detections).
        particle_scores: per particle, the mean detection score over its eq. 10 detection
            terms (softmax over the detections of ``log(psi_z(x_i) / (kappa(z) / r + C(z)))``).
    """

    log_weights: Float[Array, " num_particles"]
    log_likelihood: Float[Array, ""]
    detection_log_masses: Float[Array, " max_detections"]
    detection_states: Float[Array, "max_detections 6"]
    particle_scores: Float[Array, " num_particles"]


class Posterior(NamedTuple):
    """The resampled posterior particles.

    Attributes:
        particles: states after resampling.
        log_weights: their log-weights.
        scores: the resampled :attr:`PHDUpdate.particle_scores`.
    """

    particles: Float[Array, "num_particles 6"]
    log_weights: Float[Array, " num_particles"]
    scores: Float[Array, " num_particles"]


#: An extractor: ``(key, update, posterior, detections, params) -> Estimates``.
Extractor = Callable[[Array, PHDUpdate, Posterior, Detections, PHDParams], Estimates]


def init_phd(key: Array, params: PHDParams, num_particles: int, max_tracks: int) -> PHDState:
    """The state before the first frame: no mass, an empty track table.

    Args:
        key: unused (the initial state is deterministic).
        params: unused.
        num_particles: particles of the state (static).
        max_tracks: slots of the track table (static).

    Returns:
        The initial :class:`PHDState`.
    """
    del key, params
    particles = jnp.zeros((num_particles, STATE_DIM)).at[:, 4:].set(1.0)
    return PHDState(
        particles=particles,
        log_weights=jnp.full((num_particles,), LOG_ZERO, particles.dtype),
        mass=jnp.zeros(()),
        labels=init_labels(max_tracks),
        started=jnp.asarray(False),
        previous=no_previous_detections(particles.dtype),
    )


def predict(
    key: Array,
    particles: Float[Array, "num_particles 6"],
    log_weights: Float[Array, " num_particles"],
    params: PHDParams,
    noise_model: NoiseModel = state_dependent_std,
    normal: Float[Array, "num_particles 4"] | None = None,
) -> tuple[Float[Array, "num_particles 6"], Float[Array, " num_particles"]]:
    """Prediction of the survivors (PHD-context eq. 9): ``x_i ~ f(. | x_i)``, ``w_i <- e w_i``.

    Args:
        key: PRNG key of the dynamics' noise.
        particles: posterior particles of the previous frame.
        log_weights: their log-weights.
        params: the tracker's parameters (motion noise and survival probability).
        noise_model: noise model of the dynamics.
        normal: the dynamics' standard normal draws ``normal(key, (n, 4))``, already drawn
            (None: drawn here).

    Returns:
        The predicted particles (constant-velocity dynamics) and log-weights.
    """
    survivors = sample_constant_velocity(
        key, particles, params.motion_noise_std, noise_model, normal
    )
    return survivors, log_weights + jnp.log(survival_probability(params.survival_prob, particles))


def phd_births(
    key: Array,
    measurements: Float[Array, "max_detections 4"],
    mask: Bool[Array, " max_detections"],
    params: PHDParams,
    started: Bool[Array, ""],
    births_per_detection: int,
    noise_model: NoiseModel = state_dependent_std,
    draw_slots: int | None = None,
    random: tuple[Array, ...] | None = None,
    velocities: str = "uniform",
    previous: PreviousDetections | None = None,
) -> tuple[Float[Array, "num_births 6"], Float[Array, " num_births"]]:
    """One frame's measurement-driven births (:func:`~jaxtrack.filters.births.sample_births`).

    Args:
        key: PRNG key of the draws.
        measurements: detections ``(y1, y2, w, h)``.
        mask: True for real detections.
        params: the tracker's parameters (birth and initial intensities, measurement noise).
        started: False on the first frame (``params.initial_intensity`` is then ``gamma``).
        births_per_detection: particles per detection slot (static, > 0).
        noise_model: the likelihood's noise model.
        draw_slots: slots the random numbers are drawn for (static; None: every slot of
            ``measurements``; :func:`~jaxtrack.filters.births.draw_births`).
        random: the draws' random numbers, already drawn
            (:func:`~jaxtrack.filters.births.birth_requests`; None: drawn here).
        velocities: the births' velocity proposal (static): ``"uniform"`` over the birth
            intensity's velocity range (the paper's) or ``"detections"`` (from the previous
            frame's detections, :func:`~jaxtrack.filters.births.propose_velocities`).
        previous: the previous frame's detections (``velocities="detections"``;
            :func:`phd_step` passes the state's).

    Returns:
        The birth particles and their log-weights ``log(gamma / (J p))``.
    """
    return sample_births(
        key,
        measurements,
        mask,
        births_per_detection,
        params.birth_intensity,
        params.initial_intensity,
        started,
        params.measurement_noise_std,
        noise_model,
        draw_slots,
        random,
        velocities,
        previous,
    )


def join_particles(
    survivors: Float[Array, "num_survivors 6"], born: Float[Array, "num_births 6"]
) -> Float[Array, "num_particles 6"]:
    """The predicted survivors followed by the births (``concatenate`` along the particles).

    Joined as :func:`predict` forms the survivors
    (:func:`~jaxtrack.models.dynamics.rows_layout`). Up to
    :data:`~jaxtrack.models.dynamics.ROWS_MAX_PARTICLES` survivors, as ``[6, n]`` rows
    transposed back: :func:`predict` and :func:`phd_births` build their states as rows, so
    XLA cancels the transposes, where a join of the ``[n, 6]`` arrays along the particle axis
    fuses the two sets of row formulas into one slow per-element select (3x slower at 2048
    particles, 10x at 1e5). Above, in the states' own ``[n, 6]`` layout, as the survivors
    are then formed (session 54). Same values as ``jnp.concatenate`` either way.
    """
    if rows_layout(survivors.shape[0]):
        return jnp.concatenate([survivors.T, born.T], axis=1).T
    return jnp.concatenate([survivors, born], axis=0)


def expected_birth_mass_term(
    params: PHDParams, started: Bool[Array, ""], birth_log_weights: Float[Array, " num_births"]
) -> Float[Array, ""]:
    """Log-likelihood correction counting the births by their expected mass.

    Replaces the births' part ``-(1 - pM) sum_b w_b`` of ``-sum_i (1 - pM) w_i`` by
    ``-(1 - pM) lambda_s`` (``lambda_s`` the magnitude of the frame's birth intensity).

    Args:
        params: the tracker's parameters.
        started: False on the first frame (``params.initial_intensity`` is then ``gamma``).
        birth_log_weights: log-weights of the frame's birth particles.

    Returns:
        ``(1 - pM) (sum_b w_b - lambda_s)``, to add to the log-likelihood.
    """
    magnitude = jnp.where(
        started, params.birth_intensity.magnitude, params.initial_intensity.magnitude
    )
    birth_mass = jnp.sum(jnp.exp(birth_log_weights))
    return params.detection_prob * (birth_mass - magnitude)


def score_log_ratio(
    scores: Float[Array, " max_detections"], score_weight: Float[Array, ""]
) -> Float[Array, " max_detections"]:
    """``log p(s | target) - log p(s | clutter)`` of the detector scores, up to a constant.

    With the score as a feature of each detection (the amplitude-feature PHD filter of Clark,
    Ristic & Vo 2010), ``g(z, s | x) = g(z | x) p(s | target)`` and
    ``kappa(z, s) = kappa(z) p(s | clutter)``, so eq. 10 holds with ``kappa(z)`` replaced by
    ``kappa(z) / r(s)``, ``r = p(s | target) / p(s | clutter)``. For a calibrated detector,
    ``p(target | s) = s``, ``r(s)`` is ``s / (1 - s)`` up to a constant, which the clutter
    magnitude absorbs; ``beta`` tempers it.

    Args:
        scores: detector confidences in ``[0, 1]`` (clipped to ``[1e-6, 1 - 1e-6]``).
        score_weight: ``beta >= 0``.

    Returns:
        ``log r(s) = beta * logit(s)`` per detection.
    """
    return score_weight * score_log_odds(scores)


#: Detection x particle pairs per block of :func:`phd_update` by default (the
#: ``[max_detections, block]`` intermediates then stay in cache).
PAIRS_PER_BLOCK = 65536
#: Smallest default block of particles of :func:`phd_update`.
MIN_BLOCK = 128


#: Blocks of :func:`phd_update` wider than this many particles form the likelihood's
#: log-normaliser by elementwise additions (:func:`elementwise_log_norm`).
YNN_FUSED_BLOCK = 4096


def elementwise_log_norm(num_particles: int, block: int) -> bool:
    """Whether :func:`phd_update` asks :func:`~jaxtrack.models.likelihood.log_likelihood`
    for the elementwise log-normaliser (standard deviations as four vectors, three
    additions of their logs) on ``num_particles`` particles in blocks of ``block``.

    * Blocks wider than :data:`YNN_FUSED_BLOCK` particles (fewer than 16 detection slots at
      the default 64k pairs per block): XLA:CPU fused the reduction ``sum(log(std))`` with
      the block's particle x detection arithmetic into one YNNPACK kernel, 1.2-1.4x slower
      per recursion than XLA's own loops (5e3-1e6 particles x 4-12 detections).
    * More than :data:`~jaxtrack.models.dynamics.ROWS_MAX_PARTICLES` particles: the
      reduction's input, the stacked ``[block, 4]`` standard deviations, was written out per
      block; without it the recursion ran 1.07-1.15x faster at 1e4-1e6 particles x 18-128
      detections (README, "Where the PHD step's time goes", session 54).

    Otherwise (the tracker at tracking sizes: at most 8,192 particles, 16 or more slots)
    the reduction is kept, and the tracker's outputs round as before. The two forms can
    differ by float32 rounding.
    """
    return block > YNN_FUSED_BLOCK or not rows_layout(num_particles)


def default_block_size(num_particles: int, max_detections: int) -> int:
    """Particles per block of :func:`phd_update`: at most about :data:`PAIRS_PER_BLOCK` pairs.

    The particles are shared evenly among the fewest blocks of that size, so that the last
    block, which overlaps its predecessor, recomputes few particles (10,128 particles at 8
    detections: two blocks of 5,064 rather than 8,192 and an overlapping 8,192).
    """
    largest = min(num_particles, max(MIN_BLOCK, PAIRS_PER_BLOCK // max(max_detections, 1)))
    num_blocks = -(-num_particles // largest)
    return -(-num_particles // num_blocks)


def phd_update(
    params: PHDParams,
    measurements: Float[Array, "max_detections 4"],
    scores: Float[Array, " max_detections"],
    mask: Bool[Array, " max_detections"],
    particles: Float[Array, "num_particles 6"],
    log_weights: Float[Array, " num_particles"],
    noise_model: NoiseModel = state_dependent_std,
    block_size: int | None = None,
) -> PHDUpdate:
    """The PHD update (PHD-context eq. 10) in log space, the log-likelihood and the parts.

    ``w_i <- [pM + sum_z psi_z(x_i) / (kappa(z) + C(z))] w_i`` with
    ``psi_z(x) = (1 - pM) g(z | x)`` and ``C(z) = sum_j psi_z(x_j) w_j``; with detector scores
    ``kappa(z)`` becomes ``kappa(z) / r(s_z)`` (:func:`score_log_ratio`). The log-likelihood is
    ``-sum_i (1 - pM) w_i - int kappa + sum_z log(kappa(z) + r(s_z) C(z))`` (SPEC section 1;
    with scores, up to ``sum_z log p(s_z | clutter)``, which does not depend on the tracker).
    With a target clutter rate ``> 0`` (:class:`TargetClutter`), ``kappa(z)`` includes
    ``kappa_t(z) = rate sum_j q(z | x_j) w_j`` (:func:`target_log_clutter`, a third pass over
    the blocks) and ``int kappa`` its ``rate sum_j w_j``.

    The sums over particles and over detections run over blocks of ``block_size`` particles
    (``lax.scan``; the last block overlaps its predecessor when ``block_size`` does not divide
    ``num_particles``) in two passes that recompute ``log psi`` per block: the first sums
    ``C(z)`` (a log-sum-exp); the second updates the weights and reduces the parts of the
    extraction (the detection parts' mean states, the particles' expected scores) from one
    exponential per pair, ``exp(log psi - log(kappa / r + C) - top)`` with ``top`` the
    particle's largest such term, shared by the weight factor, the expected scores' softmax
    and the parts (each part's mean state is normalised by its own pass-2 mass, equal to
    ``C(z) / (kappa / r + C(z))`` up to rounding). The sums over particles of each detection
    (``C(z)``, the parts' weighted state sums) are carried from block to
    block. No ``[max_detections, num_particles]`` array is written, nor a ``[num_blocks,
    max_detections]`` one, so memory grows with the block and the inputs (with
    ``max_detections`` large, the number of blocks grows with it too), and on CPU it runs an
    order of magnitude faster at 1e6 particles. The parts carry no gradient; outputs a
    caller does not use are dropped by XLA.

    Args:
        params: the tracker's parameters.
        measurements: detections ``(y1, y2, w, h)``; padded slots must hold a positive size.
        scores: detector confidences.
        mask: True for real detections.
        particles: predicted particles (survivors and births).
        log_weights: their log-weights.
        noise_model: the likelihood's noise model.
        block_size: particles per block (static); None for :func:`default_block_size`.

    Returns:
        The :class:`PHDUpdate`.
    """
    num_particles, num_slots = particles.shape[0], measurements.shape[0]
    block = min(num_particles, block_size or default_block_size(num_particles, num_slots))
    num_blocks = -(-num_particles // block)
    log_detection = jnp.log(params.detection_prob)
    log_missed = jnp.log1p(-params.detection_prob)

    elementwise = elementwise_log_norm(num_particles, block)

    def log_psi_of(block_particles):
        return log_detection + log_likelihood(
            measurements, block_particles, params.measurement_noise_std, noise_model, elementwise
        )

    def block_log_psi(index):
        """``log psi_z(x_i)`` of block ``index`` (the last block overlaps its predecessor)."""
        block_particles, block_log_weights, fresh = _particle_block(
            particles, log_weights, index, block
        )
        return log_psi_of(block_particles), block_particles, block_log_weights, fresh

    log_c = _blocked_log_sum(log_psi_of, particles, log_weights, block, num_slots)
    log_ratio = score_log_ratio(scores, params.score_weight)
    log_kappa = jnp.logaddexp(
        log_intensity(params.clutter_intensity, measurements),
        target_log_clutter(
            params.target_clutter, measurements, particles, log_weights, noise_model, block
        ),
    )
    log_denominator = jnp.logaddexp(log_kappa - log_ratio, log_c)

    def block_update(part_sums, index):
        log_psi, block_particles, block_log_weights, fresh = block_log_psi(index)
        # One exponential per pair serves the weight factor's log-sum-exp over detections,
        # the expected scores' softmax and the detection parts: with
        # top_i = max_z terms_zi and ratio_zi = exp(terms_zi - top_i),
        # log_factor_i = log(pM + e^top_i sum_z ratio_zi) and
        # psi_z(x_i) w_i / (kappa / r + C(z)) = ratio_zi e^(top_i + log w_i).
        terms = jnp.where(mask[:, None], log_psi - log_denominator[:, None], LOG_ZERO)
        top = jax.lax.stop_gradient(jnp.max(terms, axis=0))
        ratio = jnp.exp(terms - top[None])
        ratio_sum = jnp.sum(ratio, axis=0)
        log_factor = jnp.logaddexp(log_missed, top + jnp.log(ratio_sum))
        updated = jnp.maximum(block_log_weights + log_factor, LOG_ZERO)
        stopped = jax.lax.stop_gradient((ratio, ratio_sum, top, block_particles, block_log_weights))
        block_sums, particle_scores = _block_parts(*stopped, fresh, scores)
        return part_sums + block_sums, (updated, particle_scores)

    part_sums, (updated, particle_scores) = jax.lax.scan(
        block_update,
        jnp.zeros((num_slots, STATE_DIM + 1), particles.dtype),
        jnp.arange(num_blocks),
    )
    state_sums, part_masses = part_sums[:, :STATE_DIM], part_sums[:, STATE_DIM]
    detection_states = jnp.where(
        mask[:, None] & (part_masses[:, None] > 0),
        state_sums / jnp.where(part_masses > 0, part_masses, 1.0)[:, None],
        0.0,
    )
    log_likelihood_k = (
        -(params.detection_prob + params.target_clutter.rate) * jnp.sum(jnp.exp(log_weights))
        - params.clutter_intensity.magnitude
        + jnp.sum(jnp.where(mask, log_denominator + log_ratio, 0.0))
    )
    detection_log_masses = jax.lax.stop_gradient(log_c - log_denominator)
    return PHDUpdate(
        log_weights=_unblock(updated, num_particles),
        log_likelihood=log_likelihood_k,
        detection_log_masses=jnp.where(mask, detection_log_masses, LOG_ZERO),
        detection_states=detection_states,
        particle_scores=_unblock(particle_scores, num_particles),
    )


def target_log_clutter(
    target_clutter: TargetClutter,
    measurements: Float[Array, "max_detections 4"],
    particles: Float[Array, "num_particles 6"],
    log_weights: Float[Array, " num_particles"],
    noise_model: NoiseModel = state_dependent_std,
    block_size: int | None = None,
) -> Float[Array, " max_detections"]:
    """``log kappa_t(z) = log rate + log sum_j q(z | x_j) w_j`` (:class:`TargetClutter`).

    Summed over blocks of ``block_size`` particles like ``C(z)`` in :func:`phd_update`. With
    ``rate = 0`` it is ``LOG_ZERO`` everywhere, and the pass over the particles is skipped (a
    ``lax.cond``; under ``vmap`` over parameter sets it runs for the whole batch when any
    member has a rate, :func:`~jaxtrack.control.any_member`).
    """
    num_particles, num_slots = particles.shape[0], measurements.shape[0]
    block = min(num_particles, block_size or default_block_size(num_particles, num_slots))

    elementwise = elementwise_log_norm(num_particles, block)

    def log_q_of(block_particles):
        return log_likelihood(
            measurements, block_particles, target_clutter.noise_std, noise_model, elementwise
        )

    def spread():
        log_sum = _blocked_log_sum(log_q_of, particles, log_weights, block, num_slots)
        rate = jnp.maximum(target_clutter.rate, jnp.finfo(log_weights.dtype).tiny)
        return jnp.maximum(jnp.log(rate) + log_sum, LOG_ZERO)

    empty = jnp.full(num_slots, LOG_ZERO, log_weights.dtype)
    present = target_clutter.rate > 0
    # Under vmap the pass runs when any configuration has the rate (control.any_member),
    # and each keeps its own branch.
    return jnp.where(present, jax.lax.cond(any_member(present), spread, lambda: empty), empty)


def _particle_block(particles, log_weights, index, block: int):
    """Block ``index`` of ``block`` particles (the last block overlaps its predecessor when
    ``block`` does not divide the particles): ``(particles, log_weights, fresh)``, ``fresh``
    False for the overlap's particles, which the previous block already counted."""
    start = jnp.minimum(index * block, particles.shape[0] - block)
    block_particles = jax.lax.dynamic_slice_in_dim(particles, start, block)
    block_log_weights = jax.lax.dynamic_slice_in_dim(log_weights, start, block)
    fresh = start + jnp.arange(block) >= index * block
    return block_particles, block_log_weights, fresh


def _blocked_log_sum(log_kernel, particles, log_weights, block: int, num_slots: int):
    """``log sum_j k_z(x_j) w_j`` for every detection slot ``z``, a ``lax.scan`` over blocks
    of ``block`` particles with ``log_kernel(block_particles) -> [num_slots, block]`` (``C(z)``
    with ``log psi``, :func:`phd_update`; ``kappa_t(z) / rate`` with ``log q``,
    :func:`target_log_clutter`)."""

    def add_block(log_sum, index):
        block_particles, block_log_weights, fresh = _particle_block(
            particles, log_weights, index, block
        )
        masked_log_weights = jnp.where(fresh, block_log_weights, LOG_ZERO)
        block_log_sum = jax.nn.logsumexp(
            log_kernel(block_particles) + masked_log_weights[None], axis=-1
        )
        return jnp.logaddexp(log_sum, block_log_sum), None

    num_blocks = -(-particles.shape[0] // block)
    log_sum, _ = jax.lax.scan(
        add_block, jnp.full(num_slots, LOG_ZERO, log_weights.dtype), jnp.arange(num_blocks)
    )
    return log_sum


def _block_parts(ratio, ratio_sum, top, particles, log_weights, fresh, scores):
    """One block's share of the extraction's reductions (no gradient).

    ``ratio[z, i] e^(top_i) w_i`` is ``psi_z(x_i) w_i / (kappa(z) / r + C(z))``, proportional
    over ``i`` to particle ``i``'s share of detection ``z``'s part ``D_z``.

    Returns:
        Per detection, ``sum_i a_zi x_i`` and ``sum_i a_zi`` over the block's fresh particles,
        ``a_zi = ratio[z, i] e^(top_i) w_i`` (``[max_detections, 7]``: the part's mean state is
        their ratio), and each particle's expected score ``sum_z s_z ratio_zi / sum_z ratio_zi``.
    """
    share = jnp.where(fresh, jnp.exp(top + log_weights), 0.0)
    weighted = ratio * share[None]
    # Contracted over the trailing (particle) axis of both: the states as [7, block] rows
    # (their transpose cancels with the particles' own, built as rows), which a vmapped
    # sweep's batched product runs twice as fast as a [block, 7] operand.
    rows = jnp.concatenate([particles.T, jnp.ones((1, particles.shape[0]), particles.dtype)])
    sums = jax.lax.dot_general(weighted, rows, (((1,), (1,)), ((), ())))
    return sums, (scores @ ratio) / ratio_sum


def _unblock(blocks: Array, num_particles: int) -> Array:
    """Per-particle values from ``[num_blocks, block, ...]``, the last block overlapping."""
    overlap = blocks.shape[0] * blocks.shape[1] - num_particles
    return jnp.concatenate([blocks[:-1].reshape(-1, *blocks.shape[2:]), blocks[-1, overlap:]])


def partition_estimates(
    key: Array, update: PHDUpdate, posterior: Posterior, detections: Detections, params: PHDParams
) -> Estimates:
    """The measurement-partition extractor.

    :func:`~jaxtrack.filters.extraction.measurement_partition` of the update's detection parts.

    Args:
        key: unused (the extraction is deterministic).
        update: the frame's update (its detection parts).
        posterior: unused.
        detections: the frame's detections.
        params: the tracker's parameters (``mass_threshold``).

    Returns:
        One estimate slot per detection slot.
    """
    del key, posterior
    return measurement_partition(
        jax.lax.stop_gradient(update.detection_log_masses),
        jax.lax.stop_gradient(update.detection_states),
        detections.scores,
        detections.mask,
        params.mass_threshold,
    )


def gmm_estimates(
    key: Array,
    update: PHDUpdate,
    posterior: Posterior,
    detections: Detections,
    params: PHDParams,
    max_clusters: int,
    num_iterations: int,
) -> Estimates:
    """The Gaussian-mixture extractor (:func:`~jaxtrack.filters.extraction.gmm_clusters`).

    Args:
        key: PRNG key of the clustering's seeding.
        update: unused.
        posterior: the resampled particles, their log-weights and expected scores.
        detections: unused.
        params: the tracker's parameters (``mass_threshold``).
        max_clusters: mixture components / estimate slots (static).
        num_iterations: EM iterations (static).

    Returns:
        ``max_clusters`` estimate slots.
    """
    del update, detections
    stopped = jax.lax.stop_gradient(posterior)
    return gmm_clusters(
        key,
        stopped.particles,
        stopped.log_weights,
        stopped.scores,
        max_clusters,
        num_iterations,
        params.mass_threshold,
    )


def phd_step(
    key: Array,
    state: PHDState,
    params: PHDParams,
    detections: Detections,
    *,
    predict: Callable = predict,
    births: Callable | None,
    update: Callable = phd_update,
    resample: Callable,
    extract: Extractor = partition_estimates,
    label: Callable = label_step,
    expected_birth_mass: bool = False,
    split_capacity: bool = False,
) -> tuple[PHDState, PHDInfo]:
    """One frame of the PHD tracker composed from its stages (the module's steps 1-6).

    **Split capacity.** Every detection slot, padded or not, costs its
    ``births_per_detection`` birth particles and a row of particle x detection pairs, and a
    run's capacity is a power of two (:func:`~jaxtrack.filters.base.capacity_for`: 16 slots for
    PETS09-S2L1's at most 9 detections). With ``split_capacity`` (static), a frame whose real
    detections all lie in the first half of its ``S`` slots runs its births, update,
    extraction and labelling on those ``S / 2`` slots (a ``lax.cond`` between the half and
    the full step, so the step compiles twice); the births' random numbers are drawn for all
    ``S`` slots and the first half's kept (:func:`~jaxtrack.filters.births.draw_births`'s
    ``draw_slots``), and the per-slot outputs are padded back as the full step pads them. The
    result is the full step's up to float32 rounding (the reductions over slots and births
    run over fewer terms), which a particle filter then carries into its later decisions: a
    run equals the full step's in distribution, not digit for digit. Under ``vmap`` with
    detections shared by the batch (sweeps, tuning keys) the cond stays a cond; with
    batched detections both branches run.

    Args:
        key: PRNG key of the frame; split into the motion, birth, resampling and extraction
            keys.
        state: the carry after the previous frame.
        params: the tracker's parameters.
        detections: one frame of padded detections.
        predict: ``(key, particles, log_weights, params) -> (particles, log_weights)``
            (:func:`predict`).
        births: ``(key, measurements, mask, params, started) -> (particles, log_weights)``
            (:func:`phd_births`), or None for no births.
        update: ``(params, measurements, scores, mask, particles, log_weights) -> PHDUpdate``
            (:func:`phd_update`).
        resample: ``(key, particles, log_weights) -> (particles, log_weights)`` for a PyTree
            of particles (:func:`~jaxtrack.filters.resampling.resample`).
        extract: :data:`Extractor` (:func:`partition_estimates`, :func:`gmm_estimates`).
        label: ``(label_state, label_params, estimates) -> (label_state, labels)``
            (:func:`~jaxtrack.association.labelling.label_step`).
        expected_birth_mass: add :func:`expected_birth_mass_term` to the log-likelihood.
        split_capacity: run frames that fit in half the slots on that half (above);
            ``births`` must then take ``draw_slots`` (:func:`phd_births` does).

    Returns:
        The new state and the frame's :class:`PHDInfo`.
    """
    stages = _Stages(predict, births, update, resample, extract, label, expected_birth_mass)
    frame = functools.partial(_frame_step, stages=stages)
    num_slots = detections.mask.shape[0]
    half = num_slots // 2
    if not split_capacity or half == 0:
        return frame(key, state, params, detections)
    _, full_info = jax.eval_shape(frame, key, state, params, detections)
    if births is not None:
        births = functools.partial(births, draw_slots=num_slots)
        frame = functools.partial(_frame_step, stages=stages._replace(births=births))

    def on_half(key, state, params, detections):
        first = jax.tree.map(lambda x: x[:half], detections)
        new_state, info = frame(key, state, params, first)
        return new_state, _pad_info(info, full_info, detections)

    used = jnp.max(jnp.where(detections.mask, jnp.arange(1, num_slots + 1), 0))
    return jax.lax.cond(used <= half, on_half, frame, key, state, params, detections)


def _pad_info(info: PHDInfo, full: PHDInfo, detections: Detections) -> PHDInfo:
    """A frame's info on its first slots padded to the full step's shapes, with the values the
    full step gives padded slots (empty tracks; estimates of zero state and mass, the padded
    detections' scores, masked out). Fields already of the full shape (e.g. the GMM
    extractor's cluster slots) are kept."""

    def pad(value, shape, fill):
        extra = shape[0] - value.shape[0]
        if extra == 0:
            return value
        tail = jnp.broadcast_to(fill[-extra:], (extra, *shape[1:])).astype(value.dtype)
        return jnp.concatenate([value, tail])

    def pad_tracks(tracks: Tracks, shape: Tracks) -> Tracks:
        slots = shape.mask.shape[0]
        return Tracks(
            boxes=pad(tracks.boxes, shape.boxes.shape, jnp.tile(jnp.asarray(PAD_BOX), (slots, 1))),
            ids=pad(tracks.ids, shape.ids.shape, jnp.full(slots, -1, tracks.ids.dtype)),
            scores=pad(tracks.scores, shape.scores.shape, jnp.zeros(slots, tracks.scores.dtype)),
            mask=pad(tracks.mask, shape.mask.shape, jnp.zeros(slots, bool)),
        )

    estimates, slots = info.estimates, full.estimates.mask.shape[0]
    states = estimates.states
    return info._replace(
        tracks=pad_tracks(info.tracks, full.tracks),
        candidates=pad_tracks(info.candidates, full.candidates),
        estimates=Estimates(
            states=pad(states, full.estimates.states.shape, jnp.zeros((slots, 6), states.dtype)),
            masses=pad(
                estimates.masses, full.estimates.masses.shape, jnp.zeros(slots, states.dtype)
            ),
            scores=pad(estimates.scores, full.estimates.scores.shape, detections.scores),
            mask=pad(estimates.mask, full.estimates.mask.shape, jnp.zeros(slots, bool)),
        ),
    )


class _Stages(NamedTuple):
    """:func:`phd_step`'s stage arguments."""

    predict: Callable
    births: Callable | None
    update: Callable
    resample: Callable
    extract: Extractor
    label: Callable
    expected_birth_mass: bool


def _joint_draws(predict_stage, births_stage, key_motion, key_birth, state, detections):
    """The motion noise and the births' random numbers from one Threefry evaluation
    (:mod:`~jaxtrack.filters.draws`: the same numbers as the stages' own draws, bit for bit;
    the arithmetic after them may round differently) when the stages are this module's
    :func:`predict` and :func:`phd_births`; otherwise no keyword arguments (the stages draw
    for themselves)."""
    if not _is_stage(predict_stage, predict) or (
        births_stage is not None and not _is_stage(births_stage, phd_births)
    ):
        return {}, {}
    births = None
    if births_stage is not None:
        slots = births_stage.keywords.get("draw_slots") or detections.mask.shape[0]
        births = (
            slots,
            births_stage.keywords["births_per_detection"],
            detections.boxes.dtype,
            _births_keyword(births_stage, "velocities") or "uniform",
        )
    normal, random = recursion_draws(
        key_motion, key_birth, state.particles.shape[0], state.particles.dtype, births
    )
    return {"normal": normal}, ({"random": random} if births_stage else {})


def recursion_draws(
    key_motion: Array,
    key_birth: Array,
    num_particles: int,
    dtype,
    births: tuple[int, int, Any] | tuple[int, int, Any, str] | None = None,
) -> tuple[Array, tuple[Array, ...] | None]:
    """The random numbers of one PHD recursion from one Threefry evaluation
    (:func:`~jaxtrack.filters.draws.draw`): the motion noise :func:`predict` draws from
    ``key_motion`` (``[num_particles, 4]`` standard normals of ``dtype``) and, with ``births
    = (draw_slots, births_per_detection, birth_dtype[, velocities])``, the births' numbers
    :func:`phd_births` draws from ``key_birth``
    (:func:`~jaxtrack.filters.births.birth_requests`). The same numbers as the stages' own
    draws, bit for bit; pass them as ``predict(..., normal=)`` and ``phd_births(...,
    random=)``.

    Returns:
        ``(normal, random)``; ``random`` is None without ``births``.
    """
    requests = [draws.normal(key_motion, (num_particles, 4), dtype)]
    if births is not None:
        requests += birth_requests(key_birth, *births)
    drawn = draws.draw(requests)
    return drawn[0], (tuple(drawn[1:]) if births is not None else None)


def _births_keyword(births_stage, name: str):
    """A keyword bound on :func:`phd_births` (None for another births stage or none bound)."""
    if not isinstance(births_stage, functools.partial) or births_stage.func is not phd_births:
        return None
    return births_stage.keywords.get(name)


def _is_stage(stage, function) -> bool:
    """``stage`` is ``function`` or a ``functools.partial`` of it with no positional arguments
    bound and the draws' keywords left free (:func:`phd_births` also needs its
    ``births_per_detection`` bound: the draws' shape)."""
    if stage is function:
        keywords = {}
    elif isinstance(stage, functools.partial) and stage.func is function and not stage.args:
        keywords = stage.keywords
    else:
        return False
    if "normal" in keywords or "random" in keywords:
        return False
    return function is not phd_births or "births_per_detection" in keywords


def _frame_step(
    key: Array, state: PHDState, params: PHDParams, detections: Detections, *, stages: _Stages
) -> tuple[PHDState, PHDInfo]:
    """:func:`phd_step` on every slot of ``detections`` (its arguments)."""
    predict, births, update, resample, extract, label, expected_birth_mass = stages
    key_motion, key_birth, key_resample, key_extract = draws.split(key, 4)
    measurements = xywh_to_cxcywh(detections.boxes, jnp)
    motion_kw, birth_kw = _joint_draws(predict, births, key_motion, key_birth, state, detections)
    particles, log_weights = predict(
        key_motion, state.particles, state.log_weights, params, **motion_kw
    )
    if births is not None:
        if _births_keyword(births, "velocities") == "detections":
            birth_kw["previous"] = state.previous
        born, birth_log_weights = births(
            key_birth, measurements, detections.mask, params, state.started, **birth_kw
        )
        particles = join_particles(particles, born)
        log_weights = jnp.concatenate([log_weights, birth_log_weights])
    updated = update(
        params, measurements, detections.scores, detections.mask, particles, log_weights
    )
    log_likelihood_k = updated.log_likelihood
    if births is not None and expected_birth_mass:
        log_likelihood_k += expected_birth_mass_term(params, state.started, birth_log_weights)
    (new_particles, new_scores), new_log_weights = resample(
        key_resample, (particles, updated.particle_scores), updated.log_weights
    )
    posterior = Posterior(new_particles, new_log_weights, new_scores)
    estimates = extract(key_extract, updated, posterior, detections, params)
    label_state, labels = label(state.labels, params.labelling, estimates)
    mass = jnp.exp(jax.nn.logsumexp(new_log_weights))
    new_state = PHDState(
        new_particles,
        new_log_weights,
        mass,
        label_state,
        jnp.asarray(True),
        keep_previous_detections(measurements, detections.mask),
    )
    info = PHDInfo(
        tracks=_tracks(estimates, labels, labels.confirmed),
        candidates=_tracks(estimates, labels, labels.ids >= 0),
        estimates=estimates,
        mass=mass,
        log_likelihood=log_likelihood_k,
        track_overflow=labels.overflow,
    )
    return new_state, info


#: The track confirmation rules of :func:`phd_filter`, by name.
CONFIRMATIONS = {
    "auto": confirm_by_calibrated_evidence,
    "score": confirm_by_score,
    "evidence": confirm_by_evidence,
}


def phd_filter(
    num_particles: int,
    births_per_detection: int = 32,
    extraction: Literal["gmm", "partition"] = "partition",
    max_clusters: int = 32,
    em_iterations: int = 10,
    max_tracks: int = 64,
    resampling: ResamplingScheme = systematic,
    stop_gradient_resampling: bool = False,
    soft_resampling: float = 0.0,
    expected_birth_mass: bool = False,
    motion_noise_model: NoiseModel = state_dependent_std,
    measurement_noise_model: NoiseModel = state_dependent_std,
    block_size: int | None = None,
    split_capacity: bool = False,
    confirmation: Literal["auto", "score", "evidence"] = "auto",
    birth_velocities: Literal["uniform", "detections"] = "uniform",
) -> Filter:
    """Builds the particle PHD tracker from its stages; all arguments are static.

    The step is :func:`phd_step` with the stages bound by ``functools.partial``.

    Args:
        num_particles: particles kept after resampling (2048 suits scenes of up to about
            20 pedestrians).
        births_per_detection: birth particles per detection slot (0: no births).
        extraction: ``"partition"`` (measurement-driven, one estimate slot per detection
            slot; the default: on the MOT15 training sequences it scores as well as or
            better than ``"gmm"`` and runs about ten times faster) or ``"gmm"`` (the paper's
            Gaussian-mixture clustering, ``max_clusters`` estimate slots).
        max_clusters: mixture components / estimate slots of ``"gmm"``.
        em_iterations: EM iterations of ``"gmm"``.
        max_tracks: slots of the labelling's track table (live and coasting tracks).
        resampling: resampling scheme (:mod:`~jaxtrack.filters.resampling`).
        stop_gradient_resampling: unbiased-gradient resampling (Scibior & Wood 2021).
        soft_resampling: ``alpha`` in ``[0, 1)`` of soft resampling (Karkus et al. 2018;
            :func:`~jaxtrack.filters.resampling.resample`); 0 (default) resamples plainly.
        expected_birth_mass: in the log-likelihood's term ``-sum_i (1 - pM) w_i``, count the
            births by their expected mass ``(1 - pM) int gamma = (1 - pM) lambda_s`` instead of
            the birth particles' mass. Births drawn around the detections cover only their
            neighbourhood, so the particles' mass misses most of ``int gamma`` and the
            likelihood then grows without bound in ``lambda_s``; with this option it has a
            finite maximiser (for tuning ``lambda_s``, :mod:`jaxtrack.tuning`). Default False.
        motion_noise_model: noise model of the dynamics (SDV by default).
        measurement_noise_model: noise model of the likelihood (SDV by default).
        block_size: particles per block of the update (:func:`phd_update`); None for
            :func:`default_block_size`.
        split_capacity: frames whose detections fit in half the run's slots run on that
            half (:func:`phd_step`): faster runs, twice the compile; results equal up to
            float32 rounding. Default False.
        confirmation: how a track is confirmed (output from then on): ``"score"``
            (:func:`~jaxtrack.association.labelling.confirm_by_score`: one estimate whose
            detection score reaches ``confirm_score``), ``"evidence"``
            (:func:`~jaxtrack.association.labelling.confirm_by_evidence`: the score log-odds
            of the estimates it has held add up to ``logit(confirm_score)``) or ``"auto"``
            (default, :func:`~jaxtrack.association.labelling.confirm_by_calibrated_evidence`:
            ``"evidence"`` when the parameters carry a learned score calibration, as a
            context learned from the ground truth does, ``"score"`` otherwise).
        birth_velocities: the births' velocity proposal: ``"uniform"`` over the birth
            intensity's velocity range (default here, the paper's) or ``"detections"``
            (mostly at the displacements from the previous frame's detections,
            :func:`~jaxtrack.filters.births.propose_velocities`;
            :class:`~jaxtrack.filters.phd_tracker.PHDConfig`'s ``birth_velocity``). Both
            are importance densities of the same birth intensity.

    Returns:
        The :class:`~jaxtrack.filters.base.Filter`.
    """
    if extraction not in ("gmm", "partition"):
        raise ValueError(f"extraction must be 'gmm' or 'partition', got {extraction!r}")
    if not 0.0 <= soft_resampling < 1.0:
        raise ValueError(f"soft_resampling must lie in [0, 1), got {soft_resampling}")
    if soft_resampling > 0 and stop_gradient_resampling:
        raise ValueError("soft_resampling and stop_gradient_resampling are exclusive")
    if confirmation not in CONFIRMATIONS:
        raise ValueError(f"confirmation must be one of {list(CONFIRMATIONS)}, got {confirmation!r}")
    if birth_velocities not in VELOCITY_PROPOSALS:
        raise ValueError(
            f"birth_velocities must be one of {list(VELOCITY_PROPOSALS)}, got {birth_velocities!r}"
        )

    extract = (
        partition_estimates
        if extraction == "partition"
        else functools.partial(
            gmm_estimates, max_clusters=max_clusters, num_iterations=em_iterations
        )
    )
    births = (
        functools.partial(
            phd_births,
            births_per_detection=births_per_detection,
            noise_model=measurement_noise_model,
            velocities=birth_velocities,
        )
        if births_per_detection > 0
        else None
    )
    step = functools.partial(
        phd_step,
        predict=functools.partial(predict, noise_model=motion_noise_model),
        births=births,
        update=functools.partial(
            phd_update, noise_model=measurement_noise_model, block_size=block_size
        ),
        resample=functools.partial(
            resample,
            num_samples=num_particles,
            scheme=resampling,
            stop_gradient=stop_gradient_resampling,
            soft_weight=soft_resampling,
        ),
        extract=extract,
        label=functools.partial(label_step, confirmation=CONFIRMATIONS[confirmation]),
        expected_birth_mass=expected_birth_mass,
        split_capacity=split_capacity,
    )
    init = functools.partial(init_phd, num_particles=num_particles, max_tracks=max_tracks)
    return Filter(init=init, step=step)


def _tracks(estimates: Estimates, labels: Labels, selected) -> Tracks:
    """One frame of labelled output boxes (top-left ``x, y, w, h``) of the selected estimates."""
    boxes = cxcywh_to_xywh(estimates.states[:, MEASURED], jnp)
    output = estimates.mask & (labels.ids >= 0) & selected
    return Tracks(
        boxes=jnp.where(output[:, None], boxes, jnp.asarray(PAD_BOX, boxes.dtype)),
        ids=jnp.where(output, labels.ids, -1),
        scores=jnp.where(output, estimates.masses, 0.0),
        mask=output,
    )
