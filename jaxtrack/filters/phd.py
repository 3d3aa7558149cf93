"""Particle PHD multi-target tracker (PHD-context Sec. III, SPEC section 1).

One :func:`phd_filter` step on frame ``k`` with detections ``Z_k``:

1. predict the survivors through the dynamics, ``w_i <- e(x_i) w_i`` (eq. 9);
2. add measurement-driven births (:mod:`~jaxtrack.filters.births`);
3. update (eq. 10, :func:`phd_update`),
   ``w_i <- [pM + sum_z psi_z(x_i) / (kappa(z) + C(z))] w_i``,
   ``psi_z(x) = (1 - pM) g(z | x)``, ``C(z) = sum_j psi_z(x_j) w_j``, in log space, optionally
   with the detector scores as a detection feature (:func:`score_log_ratio`);
4. resample to ``num_particles`` preserving the mass (:mod:`~jaxtrack.filters.resampling`);
5. extract the states (:mod:`~jaxtrack.filters.extraction`);
6. label them (:mod:`~jaxtrack.association.labelling`); tracks are output once confirmed by
   a detection score of at least ``params.labelling.confirm_score``.

It also returns the PHD measurement log-likelihood of the frame (Poisson approximation),
``log p(Z_k | Z_1:k-1) ~= -sum_i (1 - pM) w_i - int kappa + sum_z log(kappa(z) + C(z))``
over the predicted particles (survivors and births), the objective for gradient-based tuning.
Steps 5-6 see no gradient.

Detections come padded (``max_detections`` slots with a mask): one compile per capacity.
"""

from __future__ import annotations

from typing import Literal, NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from jaxtrack.association.estimates import Estimates
from jaxtrack.association.labelling import (
    LabelParams,
    Labels,
    LabelState,
    init_labels,
    label_step,
)
from jaxtrack.boxes import cxcywh_to_xywh, xywh_to_cxcywh
from jaxtrack.context.intensity import Intensity, log_intensity
from jaxtrack.filters.base import Filter
from jaxtrack.filters.births import LOG_ZERO, sample_births
from jaxtrack.filters.extraction import gmm_clusters, measurement_partition
from jaxtrack.filters.resampling import ResamplingScheme, resample, systematic
from jaxtrack.models.dynamics import MEASURED, STATE_DIM, sample_constant_velocity
from jaxtrack.models.likelihood import log_likelihood
from jaxtrack.models.noise import NoiseModel, state_dependent_std
from jaxtrack.models.survival import SurvivalMap, survival_probability
from jaxtrack.types import PAD_BOX, Detections, Tracks


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


class PHDState(NamedTuple):
    """The scan carry.

    Attributes:
        particles: ``(y1, vy1, y2, vy2, w, h)`` of each particle.
        log_weights: particle log-weights (``LOG_ZERO`` for no mass).
        mass: total PHD mass ``sum_i w_i`` (expected number of targets).
        labels: the labelling's track table.
        started: False before the first frame (which uses ``params.initial_intensity``).
    """

    particles: Float[Array, "num_particles 6"]
    log_weights: Float[Array, " num_particles"]
    mass: Float[Array, ""]
    labels: LabelState
    started: Bool[Array, ""]


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
) -> Filter:
    """Builds the particle PHD tracker; all arguments are static.

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

    Returns:
        The :class:`~jaxtrack.filters.base.Filter`.
    """
    if extraction not in ("gmm", "partition"):
        raise ValueError(f"extraction must be 'gmm' or 'partition', got {extraction!r}")
    if not 0.0 <= soft_resampling < 1.0:
        raise ValueError(f"soft_resampling must lie in [0, 1), got {soft_resampling}")
    if soft_resampling > 0 and stop_gradient_resampling:
        raise ValueError("soft_resampling and stop_gradient_resampling are exclusive")

    def init(key: Array, params: PHDParams) -> PHDState:
        del key
        particles = jnp.zeros((num_particles, STATE_DIM)).at[:, 4:].set(1.0)
        return PHDState(
            particles=particles,
            log_weights=jnp.full((num_particles,), LOG_ZERO, particles.dtype),
            mass=jnp.zeros(()),
            labels=init_labels(max_tracks),
            started=jnp.asarray(False),
        )

    def step(
        key: Array, state: PHDState, params: PHDParams, detections: Detections
    ) -> tuple[PHDState, PHDInfo]:
        key_motion, key_birth, key_resample, key_extract = jax.random.split(key, 4)
        measurements = xywh_to_cxcywh(detections.boxes, jnp)
        mask = detections.mask

        survivors = sample_constant_velocity(
            key_motion, state.particles, params.motion_noise_std, motion_noise_model
        )
        survivor_log_weights = state.log_weights + jnp.log(
            survival_probability(params.survival_prob, state.particles)
        )
        particles, log_weights = survivors, survivor_log_weights
        if births_per_detection > 0:
            births, birth_log_weights = sample_births(
                key_birth,
                measurements,
                mask,
                births_per_detection,
                params.birth_intensity,
                params.measurement_noise_std,
                measurement_noise_model,
            )
            initial, initial_log_weights = sample_births(
                key_birth,
                measurements,
                mask,
                births_per_detection,
                params.initial_intensity,
                params.measurement_noise_std,
                measurement_noise_model,
            )
            births = jnp.where(state.started, births, initial)
            birth_log_weights = jnp.where(state.started, birth_log_weights, initial_log_weights)
            particles = jnp.concatenate([survivors, births])
            log_weights = jnp.concatenate([survivor_log_weights, birth_log_weights])

        log_detection_terms, log_likelihood_k, updated_log_weights = phd_update(
            params,
            measurements,
            detections.scores,
            mask,
            particles,
            log_weights,
            measurement_noise_model,
        )
        if births_per_detection > 0 and expected_birth_mass:
            magnitude = jnp.where(
                state.started,
                params.birth_intensity.magnitude,
                params.initial_intensity.magnitude,
            )
            birth_mass = jnp.sum(jnp.exp(birth_log_weights))
            log_likelihood_k = log_likelihood_k + params.detection_prob * (birth_mass - magnitude)
        if extraction == "gmm":
            detected_scores = _expected_scores(log_detection_terms, detections.scores)
            resampled, new_log_weights = resample(
                key_resample,
                jnp.concatenate([particles, detected_scores[:, None]], axis=-1),
                updated_log_weights,
                num_particles,
                resampling,
                stop_gradient_resampling,
                soft_resampling,
            )
            new_particles = resampled[:, :STATE_DIM]
            estimates = gmm_clusters(
                key_extract,
                jax.lax.stop_gradient(new_particles),
                jax.lax.stop_gradient(new_log_weights),
                jax.lax.stop_gradient(resampled[:, STATE_DIM]),
                max_clusters,
                em_iterations,
                params.mass_threshold,
            )
        else:
            new_particles, new_log_weights = resample(
                key_resample,
                particles,
                updated_log_weights,
                num_particles,
                resampling,
                stop_gradient_resampling,
                soft_resampling,
            )
            estimates = measurement_partition(
                jax.lax.stop_gradient(particles),
                jax.lax.stop_gradient(log_weights),
                jax.lax.stop_gradient(log_detection_terms),
                detections.scores,
                mask,
                params.mass_threshold,
            )
        label_state, labels = label_step(state.labels, params.labelling, estimates)
        mass = jnp.exp(jax.nn.logsumexp(new_log_weights))
        new_state = PHDState(new_particles, new_log_weights, mass, label_state, jnp.asarray(True))
        info = PHDInfo(
            tracks=_tracks(estimates, labels, labels.confirmed),
            candidates=_tracks(estimates, labels, labels.ids >= 0),
            estimates=estimates,
            mass=mass,
            log_likelihood=log_likelihood_k,
            track_overflow=labels.overflow,
        )
        return new_state, info

    return Filter(init=init, step=step)


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
    clipped = jnp.clip(scores, 1e-6, 1 - 1e-6)
    return score_weight * (jnp.log(clipped) - jnp.log1p(-clipped))


#: Detection x particle pairs per block of :func:`phd_update` (the ``[max_detections, block]``
#: intermediates then stay in cache instead of being written out as ``[max_detections,
#: num_particles]`` arrays).
_PAIRS_PER_BLOCK = 32768
#: Smallest block of particles of :func:`phd_update`.
_MIN_BLOCK = 128


def phd_update(
    params: PHDParams,
    measurements: Float[Array, "max_detections 4"],
    scores: Float[Array, " max_detections"],
    mask: Bool[Array, " max_detections"],
    particles: Float[Array, "num_particles 6"],
    log_weights: Float[Array, " num_particles"],
    noise_model: NoiseModel = state_dependent_std,
) -> tuple[
    Float[Array, "max_detections num_particles"], Float[Array, ""], Float[Array, " num_particles"]
]:
    """The PHD update (PHD-context eq. 10) in log space, and the frame's log-likelihood.

    ``w_i <- [pM + sum_z psi_z(x_i) / (kappa(z) + C(z))] w_i`` with
    ``psi_z(x) = (1 - pM) g(z | x)`` and ``C(z) = sum_j psi_z(x_j) w_j``; with detector scores
    ``kappa(z)`` becomes ``kappa(z) / r(s_z)`` (:func:`score_log_ratio`). The log-likelihood is
    ``-sum_i (1 - pM) w_i - int kappa + sum_z log(kappa(z) + r(s_z) C(z))`` (SPEC section 1;
    with scores, up to ``sum_z log p(s_z | clutter)``, which does not depend on the tracker).

    The sums over particles (``C(z)``) and over detections (the weight update) run over
    blocks of particles (``lax.map``), two passes that recompute ``log psi`` per block rather
    than writing several ``[max_detections, num_particles]`` arrays to memory: on CPU that
    is an order of magnitude faster at 1e6 particles. The per-pair terms returned are one
    such array, which XLA drops when the caller does not use it.

    Args:
        params: the tracker's parameters.
        measurements: detections ``(y1, y2, w, h)``; padded slots must hold a positive size.
        scores: detector confidences.
        mask: True for real detections.
        particles: predicted particles (survivors and births).
        log_weights: their log-weights.
        noise_model: the likelihood's noise model.

    Returns:
        ``log(psi_z(x_i) / (kappa(z) / r(s_z) + C(z)))`` per detection and particle
        (``LOG_ZERO`` for padded detections), the log-likelihood, and the updated log-weights
        (at least ``LOG_ZERO``).
    """
    num_particles, num_slots = particles.shape[0], measurements.shape[0]
    block = min(num_particles, max(_MIN_BLOCK, _PAIRS_PER_BLOCK // max(num_slots, 1)))
    num_blocks = -(-num_particles // block)
    log_detection = jnp.log(params.detection_prob)
    log_missed = jnp.log1p(-params.detection_prob)

    def block_log_psi(index):
        """``log psi_z(x_i)`` of block ``index`` (the last block overlaps its predecessor)."""
        start = jnp.minimum(index * block, num_particles - block)
        block_particles = jax.lax.dynamic_slice_in_dim(particles, start, block)
        block_log_weights = jax.lax.dynamic_slice_in_dim(log_weights, start, block)
        fresh = start + jnp.arange(block) >= index * block
        log_psi = log_detection + log_likelihood(
            measurements, block_particles, params.measurement_noise_std, noise_model
        )
        return log_psi, block_log_weights, fresh

    def block_log_c(index):
        log_psi, block_log_weights, fresh = block_log_psi(index)
        masked_log_weights = jnp.where(fresh, block_log_weights, LOG_ZERO)
        return jax.nn.logsumexp(log_psi + masked_log_weights[None], axis=-1)

    log_c = jax.nn.logsumexp(jax.lax.map(block_log_c, jnp.arange(num_blocks)), axis=0)
    log_ratio = score_log_ratio(scores, params.score_weight)
    log_kappa = log_intensity(params.clutter_intensity, measurements)
    log_denominator = jnp.logaddexp(log_kappa - log_ratio, log_c)

    def block_update(index):
        log_psi, block_log_weights, _ = block_log_psi(index)
        terms = jnp.where(mask[:, None], log_psi - log_denominator[:, None], LOG_ZERO)
        log_factor = jnp.logaddexp(log_missed, jax.nn.logsumexp(terms, axis=0))
        return jnp.maximum(block_log_weights + log_factor, LOG_ZERO)

    updated_blocks = jax.lax.map(block_update, jnp.arange(num_blocks))
    overlap = num_blocks * block - num_particles
    updated_log_weights = jnp.concatenate(
        [updated_blocks[:-1].reshape(-1), updated_blocks[-1, overlap:]]
    )
    log_psi = log_detection + log_likelihood(
        measurements, particles, params.measurement_noise_std, noise_model
    )
    log_detection_terms = jnp.where(mask[:, None], log_psi - log_denominator[:, None], LOG_ZERO)
    log_likelihood_k = (
        -params.detection_prob * jnp.sum(jnp.exp(log_weights))
        - params.clutter_intensity.magnitude
        + jnp.sum(jnp.where(mask, log_denominator + log_ratio, 0.0))
    )
    return log_detection_terms, log_likelihood_k, updated_log_weights


def _expected_scores(log_detection_terms, scores):
    """Per particle: mean detection score over the detection terms of its eq. 10 update."""
    shares = jax.nn.softmax(jax.lax.stop_gradient(log_detection_terms), axis=0)
    return scores @ shares


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
