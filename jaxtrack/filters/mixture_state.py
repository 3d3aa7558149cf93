"""The state, parameters and per-frame outputs of the mixture filter (CMT eqs. 1-2).

See :mod:`jaxtrack.filters.mixture` for the filter; a mixture is a fixed table of
``max_components`` component slots of ``num_particles`` particles each.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from jaxtrack.filters.births import LOG_ZERO
from jaxtrack.models.dynamics import SIZE, STATE_DIM
from jaxtrack.types import Tracks


class MixtureParams(NamedTuple):
    """Everything tunable in the mixture filter (a PyTree: vmap to sweep, grad to tune).

    Attributes:
        motion_noise_std: ``(sigma_1, sigma_2, sigma_w, sigma_h)`` of the constant-velocity
            transition, > 0 (relative to the box size with the SDV noise model).
        measurement_noise_std: ``(s_1, s_2, s_w, s_h)`` of the box likelihood, > 0 (relative
            with SDV); also the spread of a new component's particles around its box.
        background_log_likelihood: log-likelihood of a particle that no detection explains
            (the floor of :func:`nearest_detection_log_likelihood`).
        min_mixture_weight: a component whose ``pi_m`` falls below it is deleted (CMT
            Algorithm 1, "local decision verification").
        min_log_support: a component whose log likelihood support ``log(w_m)`` (the log of
            its summed particle weights, eq. 4) falls below it is deleted.
        birth_log_likelihood: a detection starts a component when no living component's
            particle has a log-likelihood above it for that detection.
    """

    motion_noise_std: Float[Array, " 4"]
    measurement_noise_std: Float[Array, " 4"]
    background_log_likelihood: Float[Array, ""]
    min_mixture_weight: Float[Array, ""]
    min_log_support: Float[Array, ""]
    birth_log_likelihood: Float[Array, ""]


class MixtureState(NamedTuple):
    """The scan carry.

    Attributes:
        particles: the particles of every component slot.
        log_weights: per-component normalised particle log-weights.
        log_mixture_weights: ``log pi_m`` (``LOG_ZERO`` for dead slots).
        alive: True for slots holding a local tracker.
        ids: identity of each slot's tracker (-1 for dead slots).
        next_id: the identity the next new component gets.
    """

    particles: Float[Array, "max_components num_particles 6"]
    log_weights: Float[Array, "max_components num_particles"]
    log_mixture_weights: Float[Array, " max_components"]
    alive: Bool[Array, " max_components"]
    ids: Int[Array, " max_components"]
    next_id: Int[Array, ""]


class MixtureInfo(NamedTuple):
    """Per-frame outputs (stacked over frames by :func:`~jaxtrack.filters.base.run`).

    Attributes:
        tracks: the living components' local decisions as labelled boxes (top-left
            ``x, y, w, h``; scores are the mixture weights ``pi_m``).
        estimates: the local decision of every slot (zeros for dead slots).
        log_support: ``log w_m`` of every slot after the reweighting.
        deleted: True for the slots deleted on this frame.
        log_likelihood: ``log sum_j pi_j w_j`` over the components alive before the frame,
            the frame's measurement log-likelihood under the mixture (0 with none alive).
        overflow: True when a detection found no free slot for a new component.
    """

    tracks: Tracks
    estimates: Float[Array, "max_components 6"]
    log_support: Float[Array, " max_components"]
    deleted: Bool[Array, " max_components"]
    log_likelihood: Float[Array, ""]
    overflow: Bool[Array, ""]


def init_mixture(
    key: Array, params: MixtureParams, max_components: int, num_particles: int
) -> MixtureState:
    """The state before the first frame: every slot dead.

    Args:
        key: unused (the initial state is deterministic).
        params: unused.
        max_components: component slots (static).
        num_particles: particles per component (static).

    Returns:
        The initial :class:`MixtureState`.
    """
    del key, params
    particles = jnp.zeros((max_components, num_particles, STATE_DIM)).at[..., SIZE].set(1.0)
    return MixtureState(
        particles=particles,
        log_weights=jnp.full(
            (max_components, num_particles), -math.log(num_particles), jnp.float32
        ),
        log_mixture_weights=jnp.full((max_components,), LOG_ZERO, jnp.float32),
        alive=jnp.zeros((max_components,), bool),
        ids=jnp.full((max_components,), -1, jnp.int32),
        next_id=jnp.zeros((), jnp.int32),
    )
