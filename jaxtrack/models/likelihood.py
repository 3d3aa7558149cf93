"""Gaussian single-target likelihood ``g(z | x) = N(z; C x, Sigma(x))`` (PHD-context Sec. III).

``C`` picks ``(y1, y2, w, h)`` from the state; ``Sigma(x)`` is diagonal with standard
deviations from a :mod:`~jaxtrack.models.noise` model (SDV: ``(s_w w, s_h h, s_w w, s_h h)``
of the state's box, or constant pixels).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from jaxtrack.models.dynamics import MEASURED, SIZE
from jaxtrack.models.noise import NoiseModel, state_dependent_std, std_columns

MEAS_DIM = 4


def log_likelihood(
    measurements: Float[Array, "max_detections 4"],
    states: Float[Array, "num_particles 6"],
    noise_std: Float[Array, " 4"],
    noise_model: NoiseModel = state_dependent_std,
    elementwise_log_norm: bool = False,
) -> Float[Array, "max_detections num_particles"]:
    """``log g(z | x)`` for every measurement and particle.

    Computed in a particles-last layout: the per-particle terms (predicted measurement,
    inverse standard deviations, normaliser) are formed once as ``[4, num_particles]`` rows,
    and the squared Mahalanobis distance is a sum of four ``[max_detections, num_particles]``
    elementwise terms, which XLA fuses into one vectorised loop (a trailing axis of size 4
    would not vectorise).

    Args:
        measurements: ``z = (y1, y2, w, h)`` (box centre and size).
        states: particle states ``(y1, vy1, y2, vy2, w, h)``.
        noise_std: measurement noise parameters (relative for SDV), positive.
        noise_model: :func:`~jaxtrack.models.noise.state_dependent_std` (SDV, default) or
            :func:`~jaxtrack.models.noise.constant_std`.
        elementwise_log_norm: the log-normaliser ``sum(log(std))`` as three elementwise
            additions (:func:`sum_of_logs_in_order`) instead of :func:`sum_of_logs`'s
            reduction (static). Above about 4,096 particles XLA:CPU hands the reduction and
            the ``[max_detections, num_particles]`` arithmetic that reads it to one YNNPACK
            fusion, 1.2-1.4x slower than XLA's own loops (the PHD update asks for the
            additions for such blocks, :func:`~jaxtrack.filters.phd.phd_update`). The two
            can round differently. The standard deviations are then formed as four vectors
            (:func:`~jaxtrack.models.noise.std_columns`), not as a stacked array.

    Returns:
        The log-likelihoods, ``[max_detections, num_particles]``.
    """
    predicted = states[:, MEASURED].T
    if elementwise_log_norm:
        # The standard deviations as four vectors (noise.std_columns): the stacked
        # [n, 4] array, which XLA:CPU wrote out per block, is never formed. The same
        # values, and the log-normaliser the same additions as sum_of_logs_in_order's.
        sizes = states[:, SIZE[0] : SIZE[1] + 1]
        std_rows = [column[:, 0] for column in std_columns(noise_model, sizes, noise_std)]
        inverse_std = [1.0 / std for std in std_rows]
        log_sum = _added_in_order([jnp.log(std) for std in std_rows])
    else:
        std = noise_model(states[:, SIZE], noise_std)
        inverse_std = (1.0 / std).T
        log_sum = sum_of_logs(std)
    log_norm = log_sum + 0.5 * MEAS_DIM * jnp.log(2 * jnp.pi)
    squared_distance = sum(
        ((measurements[:, dim, None] - predicted[dim]) * inverse_std[dim]) ** 2
        for dim in range(MEAS_DIM)
    )
    return -0.5 * squared_distance - log_norm[None]


@jax.custom_jvp
def sum_of_logs(values: Float[Array, "n dim"]) -> Float[Array, " n"]:
    """``sum(log(values), axis=-1)``, with a batching rule for a sweep's configurations.

    Unbatched it is ``jnp.sum(jnp.log(values), axis=-1)``, which XLA:CPU hands to YNNPACK
    (the PHD tracker's outputs are kept bit for bit). Under ``vmap`` YNNPACK's fusion also
    took the likelihood's particle x detection arithmetic that reads the sum: on the
    magnitude sweep's batches of 9 configurations, two such fusions cost 1,037 us per frame
    each, a third of the batched step (README, "Where the PHD step's time goes", session
    49). There the sum is written as ``dim`` elementwise additions of the logs, in order,
    which XLA fuses into its own loops (the batched step 30 % faster). The batched
    results may then differ from unbatched ones at float32 rounding (a batched program
    already rounds differently). The derivative is ``t / values`` summed, both ways.
    """
    return _sum_of_logs(values)


@sum_of_logs.defjvp
def _sum_of_logs_jvp(primals, tangents):
    (values,), (tangent,) = primals, tangents
    return sum_of_logs(values), jnp.sum(tangent / values, axis=-1)


@jax.custom_batching.custom_vmap
def _sum_of_logs(values):
    return jnp.sum(jnp.log(values), axis=-1)


def sum_of_logs_in_order(values: Float[Array, "n dim"]) -> Float[Array, " n"]:
    """``sum(log(values), axis=-1)`` as ``dim - 1`` elementwise additions of the logs, in
    order (the batched form of :func:`sum_of_logs`; XLA fuses it into its own loops)."""
    logs = jnp.log(values)
    return _added_in_order([logs[..., dim] for dim in range(values.shape[-1])])


def _added_in_order(terms: list[Array]) -> Array:
    """``((terms[0] + terms[1]) + terms[2]) + ...``: left to right, elementwise."""
    total = terms[0]
    for term in terms[1:]:
        total = total + term
    return total


@_sum_of_logs.def_vmap
def _sum_of_logs_batch(axis_size: int, in_batched: list[bool], values):
    return sum_of_logs_in_order(values), in_batched[0]
