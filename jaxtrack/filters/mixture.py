"""Mixture particle filter, the core of CMT (Vermaak, Doucet & Perez 2003; CMT eqs. 1-4).

The posterior is a mixture of ``max_components`` local trackers (SPEC section 2),
``p(x_t | z_1:t) = sum_m pi_m p_m(x_t | z_1:t)`` (CMT eq. 1), each a weighted set of
``particles_per_component`` particles (eq. 2), held in a fixed table with an ``alive`` mask
and a persistent identity per slot. One :func:`mixture_step` composes public stages:

1. propose ``x_t^i ~ q(. | x_{t-1}^i, z_t)`` (an injected
   :data:`~jaxtrack.filters.mixture_models.Proposal`; the default
   :func:`~jaxtrack.filters.mixture_models.bootstrap_proposal` draws from the
   constant-velocity transition);
2. reweight, ``w_t^i = w_{t-1}^i p(z_t | x_t^i) p(x_t^i | x_{t-1}^i) / q(x_t^i | x_{t-1}^i,
   z_t)`` in log space (eq. 3, :func:`reweight`; an injected
   :data:`~jaxtrack.filters.mixture_models.LogLikelihood`, the default
   :func:`~jaxtrack.filters.mixture_models.nearest_detection_log_likelihood`);
3. mixture weights, ``pi_m <- pi_m w_m / sum_j pi_j w_j`` with ``w_m = sum_i w_t^i``
   (eq. 4, :func:`mixture_weights`);
4. local decision (CMT Algorithm 1): the weighted mean of the heaviest of two clusters
   (:func:`local_estimate`);
5. deletion of components whose ``pi_m`` or likelihood support fall below thresholds
   (:func:`~jaxtrack.filters.mixture_components.delete_components`);
6. per-component resampling (:func:`resample_components`);
7. a new component for each detection that no living component explains
   (:mod:`~jaxtrack.filters.mixture_components`); its first local decision comes on the
   next frame.

The state is the 6-D box state of :mod:`~jaxtrack.models.dynamics`,
``(y1, vy1, y2, vy2, w, h)``: the centre ``(Px, Py)``, its velocity and the box size
``(Bx, By)``. The step is pure and float32, differentiable w.r.t. the continuous params
(the deletions, births and resampling ancestors carry no gradient), and compiles once per
capacity.

The state, parameters and outputs live in :mod:`~jaxtrack.filters.mixture_state`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from jaxtrack.boxes import cxcywh_to_xywh
from jaxtrack.filters.base import Filter
from jaxtrack.filters.births import LOG_ZERO
from jaxtrack.filters.mixture_components import add_unexplained, delete_components
from jaxtrack.filters.mixture_models import (
    LogLikelihood,
    Proposal,
    bootstrap_proposal,
    log_transition,
    nearest_detection_log_likelihood,
)
from jaxtrack.filters.mixture_state import MixtureInfo, MixtureParams, MixtureState, init_mixture
from jaxtrack.filters.resampling import ResamplingScheme, resample, systematic
from jaxtrack.models.dynamics import MEASURED, POSITION
from jaxtrack.models.noise import NoiseModel, state_dependent_std
from jaxtrack.types import PAD_BOX, Detections, Tracks

#: Particles per local tracker in CMT (Sec. VI).
PARTICLES_PER_COMPONENT = 40
#: Iterations of the two-centre weighted k-means of :func:`local_estimate`.
KMEANS_ITERATIONS = 5


def reweight(
    log_weights: Float[Array, "max_components num_particles"],
    log_likelihoods: Float[Array, "max_components num_particles"],
    log_transitions: Float[Array, "max_components num_particles"],
    log_proposals: Float[Array, "max_components num_particles"],
) -> Float[Array, "max_components num_particles"]:
    """Importance weights (CMT eq. 3): ``log w_t = log w_{t-1} + log p(z|x) + log p(x|x') -
    log q(x|x', z)``, unnormalised.

    Args:
        log_weights: particle log-weights of the previous frame.
        log_likelihoods: ``log p(z_t | x_t)`` of the proposed particles.
        log_transitions: ``log p(x_t | x_{t-1})``.
        log_proposals: ``log q(x_t | x_{t-1}, z_t)``.

    Returns:
        The new particle log-weights.
    """
    return log_weights + log_likelihoods + log_transitions - log_proposals


def mixture_weights(
    log_mixture_weights: Float[Array, " max_components"],
    log_weights: Float[Array, "max_components num_particles"],
    alive: Bool[Array, " max_components"],
) -> tuple[Float[Array, " max_components"], Float[Array, " max_components"], Float[Array, ""]]:
    """Mixture weights (CMT eq. 4): ``pi_m <- pi_m w_m / sum_j pi_j w_j``, ``w_m = sum_i
    w_t^i``, over the living components.

    Args:
        log_mixture_weights: ``log pi_m`` before the frame.
        log_weights: unnormalised particle log-weights after :func:`reweight`.
        alive: True for living components (the others get ``LOG_ZERO``).

    Returns:
        The new ``log pi_m``, the supports ``log w_m``, and ``log sum_j pi_j w_j`` (0 when no
        component is alive).
    """
    log_support = jax.nn.logsumexp(log_weights, axis=-1)
    joint = jnp.where(alive, log_mixture_weights + log_support, LOG_ZERO)
    log_total = jax.nn.logsumexp(joint)
    any_alive = jnp.any(alive)
    new = jnp.where(alive, joint - jnp.where(any_alive, log_total, 0.0), LOG_ZERO)
    return new, log_support, jnp.where(any_alive, log_total, 0.0)


def normalise_weights(
    log_weights: Float[Array, "max_components num_particles"],
) -> Float[Array, "max_components num_particles"]:
    """Per-component normalised particle log-weights, ``log w_t^i - log w_m``."""
    return jax.nn.log_softmax(log_weights, axis=-1)


def local_estimate(
    particles: Float[Array, "num_particles 6"],
    log_weights: Float[Array, " num_particles"],
    num_iterations: int = KMEANS_ITERATIONS,
) -> Float[Array, " 6"]:
    """Local decision of one component (CMT Algorithm 1, step 3): cluster, keep the heaviest.

    The clustering is a weighted 2-means on the box centres ``(y1, y2)`` with
    ``num_iterations`` Lloyd iterations, seeded deterministically with the heaviest particle
    and the particle farthest from it. The estimate is the weighted mean state of the cluster
    with the larger total weight, ``x = sum_{i in C} w_i x_i / sum_{i in C} w_i``. No gradient
    flows through the cluster assignment; it flows through the weights and states.

    Args:
        particles: one component's particles.
        log_weights: their log-weights.
        num_iterations: Lloyd iterations (static).

    Returns:
        The estimated state.
    """
    weights = jnp.exp(log_weights - jax.nn.logsumexp(log_weights))
    centres_xy = jax.lax.stop_gradient(particles[:, POSITION])
    stopped_weights = jax.lax.stop_gradient(weights)
    first = centres_xy[jnp.argmax(stopped_weights)]
    second = centres_xy[jnp.argmax(jnp.sum((centres_xy - first) ** 2, axis=-1))]

    def lloyd(centres, _):
        assign = _nearest(centres_xy, centres)
        member = jax.nn.one_hot(assign, 2) * stopped_weights[:, None]
        mass = jnp.sum(member, axis=0)
        moved = (member.T @ centres_xy) / jnp.maximum(mass, 1e-30)[:, None]
        return jnp.where(mass[:, None] > 0, moved, centres), None

    centres, _ = jax.lax.scan(lloyd, jnp.stack([first, second]), None, length=num_iterations)
    assign = _nearest(centres_xy, centres)
    member = jax.nn.one_hot(assign, 2) * stopped_weights[:, None]
    heaviest = jnp.argmax(jnp.sum(member, axis=0))
    cluster_weights = jnp.where(assign == heaviest, weights, 0.0)
    return cluster_weights @ particles / jnp.sum(cluster_weights)


def _nearest(points: Array, centres: Array) -> Array:
    """Index of the nearest of the centres for each point."""
    return jnp.argmin(jnp.sum((points[:, None] - centres[None]) ** 2, axis=-1), axis=-1)


def resample_components(
    key: Array,
    particles: Float[Array, "max_components num_particles 6"],
    log_weights: Float[Array, "max_components num_particles"],
    scheme: ResamplingScheme = systematic,
) -> tuple[
    Float[Array, "max_components num_particles 6"], Float[Array, "max_components num_particles"]
]:
    """Per-component resampling (:func:`~jaxtrack.filters.resampling.resample`, vmapped):
    each component's particles are resampled from its own normalised weights.

    Args:
        key: PRNG key (split into one key per component).
        particles: the particles of every component.
        log_weights: their log-weights.
        scheme: resampling scheme (:mod:`~jaxtrack.filters.resampling`).

    Returns:
        The resampled particles and their normalised log-weights ``-log num_particles``.
    """
    keys = jax.random.split(key, particles.shape[0])
    num_particles = particles.shape[1]
    resampled, new_log_weights = jax.vmap(
        functools.partial(resample, num_samples=num_particles, scheme=scheme)
    )(keys, particles, log_weights)
    return resampled, normalise_weights(new_log_weights)


def mixture_step(
    key: Array,
    state: MixtureState,
    params: MixtureParams,
    inputs_t: Detections,
    *,
    propose: Proposal,
    log_likelihood: LogLikelihood,
    log_transition: Callable,
    resample: Callable,
    estimate: Callable,
    add: Callable,
) -> tuple[MixtureState, MixtureInfo]:
    """One frame of the mixture filter composed from its stages (the module's steps 1-7).

    Args:
        key: PRNG key of the frame; split into the proposal, resampling and birth keys.
        state: the carry after the previous frame.
        params: the filter's parameters.
        inputs_t: one frame of padded detections.
        propose: :data:`~jaxtrack.filters.mixture_models.Proposal`
            (:func:`~jaxtrack.filters.mixture_models.bootstrap_proposal`).
        log_likelihood: :data:`~jaxtrack.filters.mixture_models.LogLikelihood`
            (:func:`~jaxtrack.filters.mixture_models.nearest_detection_log_likelihood`).
        log_transition: ``(new, old, params) -> log p(new | old)``
            (:func:`~jaxtrack.filters.mixture_models.log_transition`).
        resample: ``(key, particles, log_weights) -> (particles, log_weights)``
            (:func:`resample_components`).
        estimate: ``(particles, log_weights) -> state`` of one component
            (:func:`local_estimate`).
        add: ``(key, state, detections, params) -> (state, overflow)``
            (:func:`~jaxtrack.filters.mixture_components.add_unexplained`).

    Returns:
        The new state and the frame's :class:`MixtureInfo`.
    """
    key_propose, key_resample, key_add = jax.random.split(key, 3)
    particles, log_q = propose(key_propose, state.particles, params, inputs_t)
    log_weights = reweight(
        state.log_weights,
        log_likelihood(particles, params, inputs_t),
        log_transition(particles, state.particles, params),
        log_q,
    )
    log_pi, log_support, frame_log_likelihood = mixture_weights(
        state.log_mixture_weights, log_weights, state.alive
    )
    log_weights = normalise_weights(log_weights)
    estimates = jax.vmap(estimate)(particles, log_weights)
    weighted = state._replace(
        particles=particles, log_weights=log_weights, log_mixture_weights=log_pi
    )
    survivors, deleted = delete_components(weighted, log_support, params)
    estimates = jnp.where(survivors.alive[:, None], estimates, 0.0)
    tracks = _tracks(estimates, survivors)
    new_particles, new_log_weights = resample(key_resample, particles, log_weights)
    resampled = survivors._replace(particles=new_particles, log_weights=new_log_weights)
    new_state, overflow = add(key_add, resampled, inputs_t, params)
    info = MixtureInfo(
        tracks=tracks,
        estimates=estimates,
        log_support=log_support,
        deleted=deleted,
        log_likelihood=frame_log_likelihood,
        overflow=overflow,
    )
    return new_state, info


def mixture_filter(
    max_components: int,
    particles_per_component: int = PARTICLES_PER_COMPONENT,
    propose: Proposal | None = None,
    likelihood: LogLikelihood | None = None,
    resampling: ResamplingScheme = systematic,
    noise_model: NoiseModel = state_dependent_std,
    kmeans_iterations: int = KMEANS_ITERATIONS,
) -> Filter:
    """Builds the mixture filter from its stages; all arguments are static.

    The step is :func:`mixture_step` with the stages bound by ``functools.partial``.

    Args:
        max_components: local tracker slots (> 0).
        particles_per_component: particles per local tracker (> 0; 40 in CMT).
        propose: :data:`~jaxtrack.filters.mixture_models.Proposal`; None for
            :func:`~jaxtrack.filters.mixture_models.bootstrap_proposal`.
        likelihood: :data:`~jaxtrack.filters.mixture_models.LogLikelihood`; None for
            :func:`~jaxtrack.filters.mixture_models.nearest_detection_log_likelihood`.
        resampling: resampling scheme of every component.
        noise_model: noise model of the dynamics, the default likelihood and the births.
        kmeans_iterations: Lloyd iterations of :func:`local_estimate`.

    Returns:
        The :class:`~jaxtrack.filters.base.Filter`.

    Raises:
        ValueError: a non-positive size.
    """
    if max_components <= 0 or particles_per_component <= 0:
        raise ValueError(
            "max_components and particles_per_component must be positive, got "
            f"{max_components} and {particles_per_component}"
        )
    step = functools.partial(
        mixture_step,
        propose=propose or functools.partial(bootstrap_proposal, noise_model=noise_model),
        log_likelihood=likelihood
        or functools.partial(nearest_detection_log_likelihood, noise_model=noise_model),
        log_transition=functools.partial(log_transition, noise_model=noise_model),
        resample=functools.partial(resample_components, scheme=resampling),
        estimate=functools.partial(local_estimate, num_iterations=kmeans_iterations),
        add=functools.partial(add_unexplained, noise_model=noise_model),
    )
    init = functools.partial(
        init_mixture, max_components=max_components, num_particles=particles_per_component
    )
    return Filter(init=init, step=step)


def _tracks(estimates: Float[Array, "max_components 6"], state: MixtureState) -> Tracks:
    """The living components' local decisions as labelled boxes (top-left ``x, y, w, h``)."""
    boxes = cxcywh_to_xywh(estimates[:, MEASURED], jnp)
    return Tracks(
        boxes=jnp.where(state.alive[:, None], boxes, jnp.asarray(PAD_BOX, boxes.dtype)),
        ids=state.ids,
        scores=jnp.where(state.alive, jnp.exp(state.log_mixture_weights), 0.0),
        mask=state.alive,
    )
