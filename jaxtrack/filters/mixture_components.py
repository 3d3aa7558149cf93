"""Deleting and starting the mixture filter's components (CMT Algorithm 1)."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from jaxtrack.boxes import xywh_to_cxcywh
from jaxtrack.filters.births import LOG_ZERO
from jaxtrack.filters.mixture_state import MixtureParams, MixtureState
from jaxtrack.models.dynamics import MEASURED, SIZE, STATE_DIM
from jaxtrack.models.likelihood import log_likelihood
from jaxtrack.models.noise import NoiseModel, state_dependent_std
from jaxtrack.types import Detections


def delete_components(
    state: MixtureState, log_support: Float[Array, " max_components"], params: MixtureParams
) -> tuple[MixtureState, Bool[Array, " max_components"]]:
    """Deletes the components with ``pi_m < min_mixture_weight`` or ``log w_m <
    min_log_support`` (CMT Algorithm 1, "local decision verification").

    The survivors' mixture weights are renormalised; deleted slots get ``LOG_ZERO`` and id -1.

    Args:
        state: the mixture after the mixture-weight update (eq. 4).
        log_support: ``log w_m`` of every slot.
        params: the filter's parameters (the two thresholds).

    Returns:
        The state and the mask of the slots deleted.
    """
    weak = (state.log_mixture_weights < jnp.log(params.min_mixture_weight)) | (
        log_support < params.min_log_support
    )
    deleted = state.alive & jax.lax.stop_gradient(weak)
    alive = state.alive & ~deleted
    kept = jnp.where(alive, state.log_mixture_weights, LOG_ZERO)
    log_total = jnp.where(jnp.any(alive), jax.nn.logsumexp(kept), 0.0)
    return state._replace(
        log_mixture_weights=jnp.where(alive, kept - log_total, LOG_ZERO),
        alive=alive,
        ids=jnp.where(alive, state.ids, -1),
    ), deleted


def add_component(
    key: Array,
    state: MixtureState,
    box: Float[Array, " 4"],
    params: MixtureParams,
    noise_model: NoiseModel = state_dependent_std,
) -> tuple[MixtureState, Bool[Array, ""]]:
    """Starts a local tracker in the first dead slot from a box ``(x, y, w, h)``.

    Its particles are the box centre and size plus measurement noise (``Sigma`` of the box),
    at zero velocity, equally weighted; it gets the next identity and ``pi = 1 / M`` with
    ``M`` the living components after the addition, the others scaled by ``1 - 1 / M``
    (Vermaak et al. 2003 give new components equal shares).

    Args:
        key: PRNG key of the particles' spread.
        state: the mixture.
        box: the new target's box.
        params: the filter's parameters (``measurement_noise_std``).
        noise_model: noise model of the spread.

    Returns:
        The state (unchanged when no slot is free) and True when no slot was free.
    """
    num_particles = state.particles.shape[1]
    centre = xywh_to_cxcywh(box, jnp)
    std = noise_model(centre[2:], params.measurement_noise_std)
    measured = centre + std * jax.random.normal(key, (num_particles, 4), centre.dtype)
    new_particles = jnp.zeros((num_particles, STATE_DIM), centre.dtype)
    new_particles = new_particles.at[:, MEASURED].set(measured)
    new_particles = new_particles.at[:, SIZE].set(jnp.maximum(new_particles[:, SIZE], 1.0))
    full = jnp.all(state.alive)
    slot = jnp.argmin(state.alive)
    count = jnp.sum(state.alive) + 1
    log_share = -jnp.log(count.astype(centre.dtype))
    scaled = state.log_mixture_weights + jnp.log1p(-jnp.exp(log_share))
    added = MixtureState(
        particles=state.particles.at[slot].set(new_particles),
        log_weights=state.log_weights.at[slot].set(-math.log(num_particles)),
        log_mixture_weights=jnp.where(state.alive, scaled, LOG_ZERO).at[slot].set(log_share),
        alive=state.alive.at[slot].set(True),
        ids=state.ids.at[slot].set(state.next_id),
        next_id=state.next_id + 1,
    )
    return jax.tree.map(lambda old, new: jnp.where(full, old, new), state, added), full


def add_unexplained(
    key: Array,
    state: MixtureState,
    detections: Detections,
    params: MixtureParams,
    noise_model: NoiseModel = state_dependent_std,
    forced: Bool[Array, " max_detections"] | None = None,
) -> tuple[MixtureState, Bool[Array, ""]]:
    """A new component (:func:`add_component`) for each detection no living component explains.

    Detection ``z`` is explained when a living component has a particle ``x`` with
    ``log N(z; C x, Sigma(x)) > params.birth_log_likelihood`` (the box Gaussian of
    :func:`~jaxtrack.models.likelihood.log_likelihood`, whatever the injected likelihood).
    The detections are visited in slot order, so a component started by one can explain the
    next ones. No gradient flows through these decisions.

    Args:
        key: PRNG key (one key per detection slot).
        state: the mixture.
        detections: the frame's padded detections.
        params: the filter's parameters.
        noise_model: noise model of the likelihood and the new particles' spread.
        forced: detections that start a component whether or not one explains them
            (default: none).

    Returns:
        The state and True when some unexplained detection found no free slot.
    """
    measurements = xywh_to_cxcywh(detections.boxes, jnp)
    keys = jax.random.split(key, measurements.shape[0])
    if forced is None:
        forced = jnp.zeros(detections.mask.shape, bool)

    def visit(carry, inputs):
        current, overflow = carry
        item_key, box, measurement, real, force = inputs
        flat = jax.lax.stop_gradient(current.particles).reshape(-1, STATE_DIM)
        scores = log_likelihood(measurement[None], flat, params.measurement_noise_std, noise_model)
        owners = jnp.repeat(current.alive, current.particles.shape[1])
        explained = jnp.any(owners & (scores[0] > params.birth_log_likelihood))
        added, full = add_component(item_key, current, box, params, noise_model)
        start = real & (~explained | force)
        current = jax.tree.map(lambda old, new: jnp.where(start, new, old), current, added)
        return (current, overflow | (start & full)), None

    (state, overflow), _ = jax.lax.scan(
        visit,
        (state, jnp.asarray(False)),
        (keys, detections.boxes, measurements, detections.mask, forced),
    )
    return state, overflow
