"""The default proposal, transition density and likelihood of the mixture filter (CMT eq. 3).

The mixture filter takes them as injected callables (:data:`Proposal`, :data:`LogLikelihood`);
a contextual proposal or observation model replaces them without touching the filter.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from jaxtrack.boxes import xywh_to_cxcywh
from jaxtrack.filters.births import LOG_ZERO
from jaxtrack.filters.mixture_state import MixtureParams
from jaxtrack.models.dynamics import SIZE, STATE_DIM, VELOCITY, sample_constant_velocity
from jaxtrack.models.likelihood import log_likelihood
from jaxtrack.models.noise import NoiseModel, state_dependent_std
from jaxtrack.types import Detections

#: A proposal: ``(key, particles, params, inputs_t) -> (new_particles, log_q)``, particles
#: ``[max_components, num_particles, 6]``, ``log_q`` the proposal's log-density ``[max_components,
#: num_particles]`` w.r.t. the same measure as :func:`log_transition` (a density of the four
#: noise coordinates: the proposed positions must follow from the velocities as in the
#: constant-velocity model, ``y_t = y_{t-1} + (v_{t-1} + v_t) / 2``).
Proposal = Callable[[Array, Array, MixtureParams, Detections], tuple[Array, Array]]
#: An observation model: ``(particles, params, inputs_t) -> log p(z_t | x)``, ``[max_components,
#: num_particles]``.
LogLikelihood = Callable[[Array, MixtureParams, Detections], Array]


def transition_noise(
    new: Float[Array, "*batch 6"],
    old: Float[Array, "*batch 6"],
    params: MixtureParams,
    noise_model: NoiseModel = state_dependent_std,
) -> tuple[Float[Array, "*batch 4"], Float[Array, "*batch 4"]]:
    """The standard normal draws ``n`` that move ``old`` to ``new``, and their scales.

    The constant-velocity transition (:mod:`~jaxtrack.models.dynamics`, ``T = 1``) moves the
    velocities by ``std_d n_d`` and the sizes by ``std_w n_w``, ``std_h n_h`` (the positions
    follow from the velocities), so ``n = (dv1, dv2, dw, dh) / std(old)``.

    Args:
        new: the states at ``t``.
        old: the states at ``t - 1``.
        params: the filter's parameters (``motion_noise_std``).
        noise_model: noise model of the dynamics.

    Returns:
        ``n`` and ``std(old)``, both ``[..., 4]``.
    """
    std = noise_model(old[..., SIZE], params.motion_noise_std)
    steps = jnp.concatenate(
        [new[..., VELOCITY] - old[..., VELOCITY], new[..., SIZE] - old[..., SIZE]], axis=-1
    )
    return steps / std, std


def log_transition(
    new: Float[Array, "*batch 6"],
    old: Float[Array, "*batch 6"],
    params: MixtureParams,
    noise_model: NoiseModel = state_dependent_std,
) -> Float[Array, " *batch"]:
    """``log p(x_t | x_{t-1})`` of the constant-velocity transition (CMT eq. 3 numerator).

    The transition has four noise dimensions, so this is the density of
    ``(v1, v2, w, h)`` given ``old`` (the positions are then determined):
    ``sum_d log N(n_d; 0, 1) - log std_d`` with ``n`` from :func:`transition_noise`. Sizes
    clipped at :data:`~jaxtrack.models.dynamics.MIN_SIZE` by the sampler are not corrected
    for; with the bootstrap proposal the two densities cancel exactly anyway.

    Args:
        new: the states at ``t``.
        old: the states at ``t - 1``.
        params: the filter's parameters (``motion_noise_std``).
        noise_model: noise model of the dynamics.

    Returns:
        The log-densities, one per particle.
    """
    noise, std = transition_noise(new, old, params, noise_model)
    return jnp.sum(jax.scipy.stats.norm.logpdf(noise) - jnp.log(std), axis=-1)


def bootstrap_proposal(
    key: Array,
    particles: Float[Array, "max_components num_particles 6"],
    params: MixtureParams,
    inputs_t: Detections,
    noise_model: NoiseModel = state_dependent_std,
) -> tuple[
    Float[Array, "max_components num_particles 6"], Float[Array, "max_components num_particles"]
]:
    """The bootstrap proposal ``q = p(x_t | x_{t-1})``: constant-velocity draws.

    Args:
        key: PRNG key of the draws.
        particles: the previous particles.
        params: the filter's parameters (``motion_noise_std``).
        inputs_t: unused (the bootstrap proposal ignores the observations).
        noise_model: noise model of the dynamics.

    Returns:
        The proposed particles and ``log q`` (:func:`log_transition`).
    """
    del inputs_t
    flat = particles.reshape(-1, STATE_DIM)
    new = sample_constant_velocity(key, flat, params.motion_noise_std, noise_model)
    new = new.reshape(particles.shape)
    return new, log_transition(new, particles, params, noise_model)


def nearest_detection_log_likelihood(
    particles: Float[Array, "max_components num_particles 6"],
    params: MixtureParams,
    inputs_t: Detections,
    noise_model: NoiseModel = state_dependent_std,
) -> Float[Array, "max_components num_particles"]:
    """The box likelihood against the frame's detections: the nearest detection's Gaussian.

    ``log p(z | x) = max(b, max_z log N(z; C x, Sigma(x)))`` over the real detections ``z``
    (boxes ``(y1, y2, w, h)``; :func:`~jaxtrack.models.likelihood.log_likelihood`), ``b`` =
    ``params.background_log_likelihood`` (a particle far from every detection, or a frame
    without any).

    Args:
        particles: the proposed particles.
        params: the filter's parameters (``measurement_noise_std``,
            ``background_log_likelihood``).
        inputs_t: the frame's padded detections.
        noise_model: noise model of the likelihood.

    Returns:
        The log-likelihoods.
    """
    measurements = xywh_to_cxcywh(inputs_t.boxes, jnp)
    flat = particles.reshape(-1, STATE_DIM)
    per_detection = log_likelihood(measurements, flat, params.measurement_noise_std, noise_model)
    per_detection = jnp.where(inputs_t.mask[:, None], per_detection, LOG_ZERO)
    best = jnp.max(per_detection, axis=0, initial=LOG_ZERO)
    return jnp.maximum(best, params.background_log_likelihood).reshape(particles.shape[:2])
