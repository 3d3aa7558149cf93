"""CMT's contextual proposal: motion conditions and blob-driven draws (CMT eqs. 5-10).

Each particle ``x'`` of component ``m`` draws a motion condition ``h ~ q_m(h)``
(:func:`~jaxtrack.filters.cmt_conditions.condition_probabilities`, eqs. 6-10), then a new
state from the condition's proposal (CMT Sec. IV-A and IV-B-2):

* normal and split: the blob-driven proposal ``q_blob``. A blob ``j`` (box centre and size
  ``b_j = (cx, cy, w, h)``) is taken as a Gaussian observation ``N(b_j, r_j^2)`` of the
  particle's ``(y1, y2, w, h)``, ``r_j = blob_spread * (w_j, h_j, w_j, h_j)``; the CV
  prediction's marginal is ``N(p, s^2)``. Among the real blobs within ``blob_gate`` heights
  of the prediction (except the group blobs the component is a member of,
  :func:`~jaxtrack.filters.cmt_conditions.group_members`: a box over several targets says
  where the group is, not where this target is), blob ``j`` is picked with probability ``c_j
  / sum_k c_k``, ``c_j = N(b_j; p, s^2 + r_j^2)`` (its Gaussian closeness to the
  prediction), and the centre and size are drawn from the product of the two Gaussians,
  ``N_j`` (:func:`blob_gaussians`): the blob's Gaussian pulled towards the prediction by the
  prior's precision (the locally optimal proposal of a linear-Gaussian observation, so the
  weights ``p / q`` stay bounded). The velocity is set to ``v = 2 (y - y') - v'`` (so that
  the CV position update ``y = y' + (v' + v) / 2`` holds). With probability
  ``defensive_weight`` (``beta``), or when no blob is near, the draw comes from the CV
  transition ``p_cv`` instead: ``q_blob = beta p_cv + (1 - beta) sum_j (c_j / sum_k c_k)
  N_j``;
* merge: the CV transition ``p_cv`` (the paper's AR(2) prediction: the state holds the
  velocity);
* exit: the particle is invalidated (``exited``; the caller gives it zero weight). Its
  state is a CV draw.

``log_q`` is the exact density of the whole proposal (eq. 5), marginalised over the
condition and the blob choice, at the drawn particle: for a particle that did not exit,
``q(x) = (q(normal) + q(split)) q_blob(x) + q(merge) p_cv(x)``, which integrates to
``1 - q(exit)``. Densities are w.r.t. the measure of
:func:`~jaxtrack.filters.mixture_models.log_transition`, the four noise coordinates
``(v1, v2, w, h)`` given ``x'``: a position drawn with density ``N(y)`` gives the velocity
``v = 2 (y - y') - v'`` the density ``N(y) / 2`` per position dimension. Sizes clipped at
:data:`~jaxtrack.models.dynamics.MIN_SIZE` are not corrected for (as in ``log_transition``).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from jaxtrack.boxes import xywh_to_cxcywh
from jaxtrack.filters.births import LOG_ZERO
from jaxtrack.filters.cmt_conditions import (
    ENTER,
    EXIT,
    MERGE,
    NORMAL,
    SPLIT,
    CPDParams,
    condition_probabilities,
    default_cpd_params,
    group_members,
    near_blobs,
    predicted_mean,
)
from jaxtrack.models.dynamics import (
    MEASURED,
    MIN_SIZE,
    POSITION,
    SIZE,
    STATE_DIM,
    VELOCITY,
    sample_constant_velocity,
)
from jaxtrack.models.noise import NoiseModel, state_dependent_std
from jaxtrack.types import Detections

#: The proposal's public API; the conditions, their probabilities and the parameters live in
#: :mod:`~jaxtrack.filters.cmt_conditions` and are re-exported here for the tracker.
__all__ = [
    "ENTER",
    "EXIT",
    "MERGE",
    "NORMAL",
    "SPLIT",
    "BlobGaussians",
    "CPDDraw",
    "CPDParams",
    "blob_gaussians",
    "condition_probabilities",
    "contextual_proposal",
    "default_cpd_params",
    "log_blob_gaussians",
    "log_constant_velocity",
    "log_proposal_density",
    "sample_near_blobs",
]

#: Standard deviation of the CV prediction's ``(y1, y2, w, h)`` per unit of noise std: the
#: positions move by half the velocity noise (``T^2 / 2``), the sizes by the size noise.
MEASURED_GAIN = (0.5, 0.5, 1.0, 1.0)
#: ``log(1 / 4)``: the Jacobian of ``v = 2 (y - y') - v'`` in the two position dimensions.
LOG_POSITION_JACOBIAN = -2 * math.log(2.0)


class CPDDraw(NamedTuple):
    """One draw of the contextual proposal.

    Attributes:
        particles: the proposed particles.
        log_q: the proposal's log-density at each particle (module docstring).
        conditions: the condition each particle drew (``NORMAL``, ``SPLIT``, ``MERGE`` or
            ``EXIT`` of :mod:`~jaxtrack.filters.cmt_conditions`).
        exited: True for the invalidated (``EXIT``) particles.
        probabilities: ``q(h)`` of each component, ``[max_components, 4]``.
    """

    particles: Float[Array, "max_components num_particles 6"]
    log_q: Float[Array, "max_components num_particles"]
    conditions: Int[Array, "max_components num_particles"]
    exited: Bool[Array, "max_components num_particles"]
    probabilities: Float[Array, "max_components 4"]


def _safe_log(values: Array) -> Array:
    """``log`` floored at the smallest normal float32 (finite values and gradients at 0)."""
    return jnp.log(jnp.maximum(values, jnp.finfo(jnp.float32).tiny))


def _gaussian_logpdf(values: Array, means: Array, stds: Array) -> Array:
    """``sum_d log N(values_d; means_d, stds_d^2)`` over the last axis."""
    return jnp.sum(jax.scipy.stats.norm.logpdf(values, means, stds), axis=-1)


def log_constant_velocity(
    new: Float[Array, "*batch 6"],
    old: Float[Array, "*batch 6"],
    motion_noise_std: Float[Array, " 4"],
    noise_model: NoiseModel = state_dependent_std,
) -> Float[Array, " *batch"]:
    """``log p_cv(x | x')``: the CV transition's density of ``(v1, v2, w, h)`` (CMT eq. 3).

    ``N(v; v', std_{1,2}) N((w, h); (w', h'), std_{w,h})`` with ``std = noise_model((w', h'),
    motion_noise_std)`` (:mod:`~jaxtrack.models.dynamics`).
    """
    std = noise_model(old[..., SIZE], motion_noise_std)
    noise_coordinates = (*VELOCITY, *SIZE)
    return _gaussian_logpdf(new[..., noise_coordinates], old[..., noise_coordinates], std)


class BlobGaussians(NamedTuple):
    """The blob-driven Gaussians of every particle and blob (module docstring).

    Attributes:
        log_closeness: ``log c_j``; ``LOG_ZERO`` for the blobs not near the prediction.
        means: means of ``(y1, y2, w, h)``.
        stds: standard deviations of ``(y1, y2, w, h)``.
    """

    log_closeness: Float[Array, "max_components num_particles max_detections"]
    means: Float[Array, "max_components num_particles max_detections 4"]
    stds: Float[Array, "max_components num_particles max_detections 4"]


def blob_gaussians(
    particles: Float[Array, "max_components num_particles 6"],
    blobs: Detections,
    params: CPDParams,
    motion_noise_std: Float[Array, " 4"],
    noise_model: NoiseModel = state_dependent_std,
    excluded: Bool[Array, "max_components max_detections"] | None = None,
) -> BlobGaussians:
    """The CV prediction of each particle fused with each blob, per coordinate (CMT Sec. IV-A).

    With the prediction's marginal ``N(p, s^2)`` of ``(y1, y2, w, h)`` (``p = C G x'``,
    ``s = MEASURED_GAIN * std(x')``) and the blob's ``N(b_j, r_j^2)`` (``r_j = blob_spread *
    (w_j, h_j, w_j, h_j)``): ``c_j = N(b_j; p, s^2 + r_j^2)`` and the Gaussian of mean
    ``(p r_j^2 + b_j s^2) / (s^2 + r_j^2)`` and variance ``s^2 r_j^2 / (s^2 + r_j^2)``.

    Args:
        particles: the previous particles ``x'``.
        blobs: the frame's padded foreground blobs.
        params: the proposal's parameters (``blob_gate``, ``blob_spread``).
        motion_noise_std: the CV transition's noise std.
        noise_model: noise model of the dynamics.
        excluded: ``[max_components, max_detections]`` blobs a component's particles may not
            be drawn onto (the group blobs it is a member of); None: none.

    Returns:
        The closeness, means and standard deviations.
    """
    prediction = predicted_mean(particles)
    predicted = prediction[..., None, MEASURED]
    prior_std = noise_model(particles[..., SIZE], motion_noise_std) * jnp.asarray(MEASURED_GAIN)
    prior_var = prior_std[..., None, :] ** 2
    boxes = xywh_to_cxcywh(blobs.boxes, jnp)
    blob_var = (params.blob_spread * boxes[:, (2, 3, 2, 3)]) ** 2
    total_var = prior_var + blob_var
    closeness = _gaussian_logpdf(boxes, predicted, jnp.sqrt(total_var))
    near = near_blobs(prediction, blobs, params.blob_gate)
    if excluded is not None:
        near = near & ~excluded[:, None, :]
    return BlobGaussians(
        log_closeness=jnp.where(near, closeness, LOG_ZERO),
        means=(predicted * blob_var + boxes * prior_var) / total_var,
        stds=jnp.sqrt(prior_var * blob_var / total_var),
    )


def log_blob_gaussians(
    new: Float[Array, "max_components num_particles 6"], gaussians: BlobGaussians
) -> Float[Array, "max_components num_particles max_detections"]:
    """``log N_j(x)``: density of ``(v1, v2, w, h)`` under each blob-driven Gaussian.

    ``N((y1, y2, w, h); mean_j, std_j^2) / 4``: the factor ``1 / 4`` is the Jacobian of
    ``v = 2 (y - y') - v'`` in the two position dimensions.
    """
    return (
        _gaussian_logpdf(new[..., None, MEASURED], gaussians.means, gaussians.stds)
        + LOG_POSITION_JACOBIAN
    )


def log_proposal_density(
    new: Float[Array, "max_components num_particles 6"],
    old: Float[Array, "max_components num_particles 6"],
    gaussians: BlobGaussians,
    probabilities: Float[Array, "max_components 4"],
    params: CPDParams,
    motion_noise_std: Float[Array, " 4"],
    noise_model: NoiseModel = state_dependent_std,
) -> Float[Array, "max_components num_particles"]:
    """``log q(x | x')`` of the non-exit part of the proposal (CMT eq. 5; module docstring).

    Args:
        new: the proposed particles ``x``.
        old: the previous particles ``x'``.
        gaussians: :func:`blob_gaussians` of ``old``.
        probabilities: ``q(h)`` per component (``NORMAL``, ``SPLIT``, ``MERGE``, ``EXIT``).
        params: the proposal's parameters (``defensive_weight``).
        motion_noise_std: the CV transition's noise std.
        noise_model: noise model of the dynamics.

    Returns:
        The log-densities.
    """
    log_cv = log_constant_velocity(new, old, motion_noise_std, noise_model)
    log_choice = jax.nn.log_softmax(gaussians.log_closeness, axis=-1)
    log_blobs = jax.nn.logsumexp(log_choice + log_blob_gaussians(new, gaussians), axis=-1)
    beta = params.defensive_weight
    log_blob_driven = jnp.logaddexp(_safe_log(beta) + log_cv, _safe_log(1 - beta) + log_blobs)
    any_near = jnp.any(gaussians.log_closeness > LOG_ZERO, axis=-1)
    log_blob_driven = jnp.where(any_near, log_blob_driven, log_cv)
    blob_share = _safe_log(probabilities[:, NORMAL] + probabilities[:, SPLIT])[:, None]
    merge_share = _safe_log(probabilities[:, MERGE])[:, None]
    return jnp.logaddexp(blob_share + log_blob_driven, merge_share + log_cv)


def sample_near_blobs(
    key: Array,
    particles: Float[Array, "max_components num_particles 6"],
    gaussians: BlobGaussians,
) -> Float[Array, "max_components num_particles 6"]:
    """Draws from ``sum_j (c_j / sum_k c_k) N_j`` (module docstring), sizes >= ``MIN_SIZE``.

    Rows without a near blob get an arbitrary blob's draw (the caller replaces them).
    """
    key_choice, key_noise = jax.random.split(key)
    chosen = jax.random.categorical(key_choice, gaussians.log_closeness, axis=-1)[..., None, None]
    means = jnp.take_along_axis(gaussians.means, chosen, axis=-2)[..., 0, :]
    stds = jnp.take_along_axis(gaussians.stds, chosen, axis=-2)[..., 0, :]
    drawn = means + stds * jax.random.normal(key_noise, means.shape, means.dtype)
    positions = drawn[..., :2]
    velocities = 2 * (positions - particles[..., POSITION]) - particles[..., VELOCITY]
    sizes = jnp.maximum(drawn[..., 2:], MIN_SIZE)
    return jnp.stack(
        [
            positions[..., 0],
            velocities[..., 0],
            positions[..., 1],
            velocities[..., 1],
            sizes[..., 0],
            sizes[..., 1],
        ],
        axis=-1,
    )


def contextual_proposal(
    key: Array,
    particles: Float[Array, "max_components num_particles 6"],
    estimates: Float[Array, "max_components 6"],
    alive: Bool[Array, " max_components"],
    params: CPDParams,
    motion_noise_std: Float[Array, " 4"],
    blobs: Detections,
    zone_boxes: Float[Array, "num_zones 4"],
    zone_mask: Bool[Array, " num_zones"],
    noise_model: NoiseModel = state_dependent_std,
    groups: Bool[Array, "max_components max_detections"] | None = None,
) -> CPDDraw:
    """One draw of CMT's motion-condition-specific proposal (CMT eq. 5; module docstring).

    Args:
        key: PRNG key of the draws.
        particles: the previous (resampled) particles ``x'`` of every component slot.
        estimates: the components' previous local decisions (the context of eqs. 7-10).
        alive: the living components.
        params: the proposal's parameters.
        motion_noise_std: the CV transition's noise std (``MixtureParams.motion_noise_std``).
        blobs: the frame's padded foreground blobs ``z~_t``.
        zone_boxes: padded entry/exit zone boxes ``(x, y, w, h)``, pixels.
        zone_mask: True for the real zones.
        noise_model: noise model of the dynamics.
        groups: :func:`~jaxtrack.filters.cmt_conditions.group_members` of the estimates'
            predictions, when the caller has them; None: computed here.

    Returns:
        The proposed particles, ``log q``, the drawn conditions and the exits, and ``q(h)``.
    """
    key_condition, key_defensive, key_cv, key_blob = jax.random.split(key, 4)
    num_components, num_particles = particles.shape[:2]
    if groups is None:
        groups = group_members(predicted_mean(estimates), alive, blobs, params.group_area_ratio)
    probabilities = condition_probabilities(
        estimates, alive, zone_boxes, zone_mask, blobs, params, groups
    )
    conditions = jax.random.categorical(
        key_condition, _safe_log(probabilities)[:, None, :], shape=(num_components, num_particles)
    )
    cv = sample_constant_velocity(
        key_cv, particles.reshape(-1, STATE_DIM), motion_noise_std, noise_model
    ).reshape(particles.shape)
    gaussians = blob_gaussians(particles, blobs, params, motion_noise_std, noise_model, groups)
    from_blobs = sample_near_blobs(key_blob, particles, gaussians)
    defensive = jax.random.uniform(key_defensive, conditions.shape) < params.defensive_weight
    blob_driven = (
        ((conditions == NORMAL) | (conditions == SPLIT))
        & jnp.any(gaussians.log_closeness > LOG_ZERO, axis=-1)
        & ~defensive
    )
    new = jnp.where(blob_driven[..., None], from_blobs, cv)
    log_q = log_proposal_density(
        new, particles, gaussians, probabilities, params, motion_noise_std, noise_model
    )
    return CPDDraw(
        particles=new,
        log_q=log_q,
        conditions=conditions,
        exited=conditions == EXIT,
        probabilities=probabilities,
    )
