"""Measurement-driven births of the particle PHD filter (PHD-context Sec. III, step 2).

``J = births_per_detection * |Z_k|`` new particles are drawn from an importance density built
on the current detections,

    p(x | Z_k) = (1 / |Z_k|) sum_z N((y1, y2, w, h); z, Sigma(z)) U((vy1, vy2); V_v),

each detection contributing ``births_per_detection`` particles: centre and size around the
detection with the measurement noise of a box of the detection's size, velocity uniform over
the velocity range ``V_v`` of the birth intensity's volume (so that the weights do not depend
on the velocity for a uniform birth intensity and stay bounded in it for a learned mixture,
whose velocity tails a Gaussian proposal would not cover). The weights are

    w = gamma(x) / (J p(x | Z_k)),

``gamma`` the birth intensity, which makes the birth particles an unbiased estimate of
``gamma`` wherever the importance density covers it (the neighbourhood of the detections,
the only place where births can gain mass in the update).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from jaxtrack.context.intensity import Intensity, log_intensity
from jaxtrack.models.dynamics import MEASURED, MIN_SIZE, VELOCITY
from jaxtrack.models.noise import NoiseModel, state_dependent_std

#: Log-weight standing for "no mass" (finite, so that gradients and differences stay finite).
LOG_ZERO = -1e30


def sample_births(
    key: Array,
    measurements: Float[Array, "max_detections 4"],
    mask: Bool[Array, " max_detections"],
    births_per_detection: int,
    birth_intensity: Intensity,
    measurement_noise_std: Float[Array, " 4"],
    noise_model: NoiseModel = state_dependent_std,
) -> tuple[Float[Array, "num_births 6"], Float[Array, " num_births"]]:
    """Draws birth particles around the detections and weights them by ``gamma / (J p)``.

    Args:
        key: PRNG key; split into the Gaussian draws ``normal(k1, (M, J, 4))`` and the
            velocity draws ``uniform(k2, (M, J, 2))``.
        measurements: detections ``(y1, y2, w, h)``; padded slots must hold a positive size.
        mask: True for real detections.
        births_per_detection: particles per detection slot (static).
        birth_intensity: ``gamma`` over the 6-D state space (PHD-context eq. 19).
        measurement_noise_std: measurement noise parameters (relative for SDV).
        noise_model: the likelihood's noise model.

    Returns:
        ``births_per_detection * max_detections`` states, detection-major (sizes clipped
        below at :data:`~jaxtrack.models.dynamics.MIN_SIZE`, far in the Gaussian's tail), and their
        log-weights (:data:`LOG_ZERO` for particles of padded slots).
    """
    num_slots = measurements.shape[0]
    key_gauss, key_velocity = jax.random.split(key)
    std = noise_model(measurements[:, 2:], measurement_noise_std)
    normal = jax.random.normal(key_gauss, (num_slots, births_per_detection, 4), measurements.dtype)
    measured = (measurements[:, None, :] + std[:, None, :] * normal).reshape(-1, 4)
    measured = measured.at[:, 2:].set(jnp.maximum(measured[:, 2:], MIN_SIZE))
    velocity_lower = birth_intensity.lower[jnp.array(VELOCITY)]
    velocity_upper = birth_intensity.upper[jnp.array(VELOCITY)]
    velocity = jax.random.uniform(
        key_velocity,
        (num_slots * births_per_detection, 2),
        measurements.dtype,
        minval=velocity_lower,
        maxval=velocity_upper,
    )
    states = jnp.zeros((measured.shape[0], 6), measurements.dtype)
    states = states.at[:, MEASURED].set(measured).at[:, VELOCITY].set(velocity)

    residual = (measured[:, None, :] - measurements[None]) / std[None]
    log_gauss = -0.5 * jnp.sum(residual**2, axis=-1) - jnp.sum(jnp.log(std), axis=-1)[None]
    log_gauss = log_gauss - 2 * math.log(2 * math.pi)
    log_mixture_sum = jax.nn.logsumexp(jnp.where(mask[None], log_gauss, LOG_ZERO), axis=-1)
    log_velocity_volume = jnp.sum(jnp.log(velocity_upper - velocity_lower))
    log_weights = (
        log_intensity(birth_intensity, states)
        - math.log(births_per_detection)
        - log_mixture_sum
        + log_velocity_volume
    )
    real = jnp.repeat(mask, births_per_detection)
    return states, jnp.where(real, log_weights, LOG_ZERO)
