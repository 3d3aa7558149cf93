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

import functools
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from jaxtrack.context.intensity import Intensity, log_intensity
from jaxtrack.filters import draws
from jaxtrack.models.dynamics import MIN_SIZE, VELOCITY
from jaxtrack.models.noise import NoiseModel, state_dependent_std

#: Log-weight standing for "no mass" (finite, so that gradients and differences stay finite).
LOG_ZERO = -1e30


class BirthDraws(NamedTuple):
    """Birth particles drawn around the detections, before weighting.

    Attributes:
        states: ``births_per_detection * max_detections`` states, detection-major.
        log_mixture: ``log sum_z N((y1, y2, w, h); z, Sigma(z))`` over the real detections.
        log_velocity_volume: ``log |V_v|`` of the velocity range the velocities were drawn in.
        real: True for the particles of real detection slots.
    """

    states: Float[Array, "num_births 6"]
    log_mixture: Float[Array, " num_births"]
    log_velocity_volume: Float[Array, ""]
    real: Bool[Array, " num_births"]


def velocity_bounds(intensity: Intensity) -> tuple[Float[Array, " 2"], Float[Array, " 2"]]:
    """Lower and upper corners ``V_v`` of the velocity part of an intensity's volume."""
    return intensity.lower[jnp.array(VELOCITY)], intensity.upper[jnp.array(VELOCITY)]


def birth_requests(
    key: Array, draw_slots: int, births_per_detection: int, dtype=jnp.float32
) -> list:
    """The random numbers :func:`draw_births` draws from ``key``: ``key`` split in two, the
    Gaussian draws ``normal(k1, (draw_slots, J, 4))`` and the velocities' unit draws
    ``uniform(k2, (draw_slots J, 2))`` (scaled to the velocity range by :func:`draw_births`,
    as ``jax.random.uniform(k2, ..., minval, maxval)`` scales them)."""
    key_gauss, key_velocity = jax.random.split(key)
    return [
        draws.normal(key_gauss, (draw_slots, births_per_detection, 4), dtype),
        draws.uniform(key_velocity, (draw_slots * births_per_detection, 2), dtype=dtype),
    ]


def draw_births(
    key: Array,
    measurements: Float[Array, "max_detections 4"],
    mask: Bool[Array, " max_detections"],
    births_per_detection: int,
    velocity_lower: Float[Array, " 2"],
    velocity_upper: Float[Array, " 2"],
    measurement_noise_std: Float[Array, " 4"],
    noise_model: NoiseModel = state_dependent_std,
    draw_slots: int | None = None,
    random: tuple[Array, Array] | None = None,
) -> BirthDraws:
    """Draws birth particles from ``p(x | Z_k)`` (the module's importance density).

    Args:
        key: PRNG key; split into the Gaussian draws ``normal(k1, (M, J, 4))`` and the
            velocity draws ``uniform(k2, (M, J, 2))``.
        measurements: detections ``(y1, y2, w, h)``; padded slots must hold a positive size.
        mask: True for real detections.
        births_per_detection: particles per detection slot (static).
        velocity_lower: lower corner of the velocity range ``V_v``.
        velocity_upper: upper corner of ``V_v``.
        measurement_noise_std: measurement noise parameters (relative for SDV).
        noise_model: the likelihood's noise model.
        draw_slots: draw the random numbers for this many slots (static, at least
            ``max_detections``) and keep the first ``max_detections`` slots' share: a step
            that works on a frame's first slots only draws what the full-capacity step
            draws for them. None: ``max_detections``.
        random: the random numbers :func:`birth_requests` asks ``key`` for, already drawn
            (:func:`jaxtrack.filters.draws.draw`); None: drawn here.

    Returns:
        The draws (sizes clipped below at :data:`~jaxtrack.models.dynamics.MIN_SIZE`, far in
        the Gaussian's tail) and the parts of their proposal density.

    Raises:
        ValueError: ``draw_slots`` below ``max_detections``.
    """
    num_slots = measurements.shape[0]
    drawn = num_slots if draw_slots is None else draw_slots
    if drawn < num_slots:
        raise ValueError(f"draw_slots ({drawn}) must be at least the {num_slots} slots")
    num_births = num_slots * births_per_detection
    if random is None:
        random = draws.draw(birth_requests(key, drawn, births_per_detection, measurements.dtype))
    normal, unit = random
    std = noise_model(measurements[:, 2:], measurement_noise_std)
    normal = normal[:num_slots]
    measured = (measurements[:, None, :] + std[:, None, :] * normal).reshape(-1, 4)
    measured = measured.at[:, 2:].set(jnp.maximum(measured[:, 2:], MIN_SIZE))
    # jax.random.uniform(key_velocity, shape, minval=lower, maxval=upper) on the unit draws.
    velocity = draws.scale_uniform(unit[:num_births], velocity_lower, velocity_upper)
    # (y1, vy1, y2, vy2, w, h) stacked as rows, then transposed (see phd_step's join).
    y1, y2, width, height = (measured[:, i] for i in range(4))
    states = jnp.stack([y1, velocity[:, 0], y2, velocity[:, 1], width, height], axis=0).T
    return BirthDraws(
        states=states,
        log_mixture=log_mixture_density(measured, measurements, std, mask),
        log_velocity_volume=jnp.sum(jnp.log(velocity_upper - velocity_lower)),
        real=jnp.repeat(mask, births_per_detection),
    )


#: Point x detection pairs per block of :func:`log_mixture_density`: its ``[block,
#: max_detections]`` intermediates take a few MB whatever the number of detections.
PAIRS_PER_BLOCK = 1 << 18


#: Most rows :func:`logsumexp_rows` reduces as elementwise operations, row after row.
UNROLLED_ROWS = 32


def logsumexp_rows(values: Float[Array, "rows n"]) -> Float[Array, " n"]:
    """``jax.nn.logsumexp(values, axis=0)``, up to float32 rounding.

    With at most :data:`UNROLLED_ROWS` rows the maximum and the sum run row after row as
    elementwise operations, which XLA emits as one vectorised loop wherever it fuses them; a
    reduction over a short axis fused into a consumer's loop (the births' log-weights joined
    to the survivors') is emitted one output element at a time, about 5x slower at 9
    detections. The values agree with XLA:CPU's reduction up to an ulp; in the PHD tracker
    the MOT15 sequences' results did not change (README, "Where the PHD step's time goes",
    session 49: one ulp in one frame's estimates). More rows: ``logsumexp``.
    """
    if values.shape[0] > UNROLLED_ROWS:
        return jax.nn.logsumexp(values, axis=0)
    # The rows are sliced from ``values`` twice, once per pass: with one slice per row used by
    # both passes, XLA fuses the rows' formulas into both and, through them, into a consumer
    # as large as a join of the log-weights, which it emits one element at a time.
    top = functools.reduce(jnp.maximum, list(values))
    top = jax.lax.stop_gradient(jnp.where(jnp.isfinite(top), top, 0.0))
    total = functools.reduce(jnp.add, [jnp.exp(row - top) for row in values])
    return jnp.log(jnp.abs(total)) + top


def log_mixture_density(
    points: Float[Array, "num_points 4"],
    measurements: Float[Array, "max_detections 4"],
    std: Float[Array, "max_detections 4"],
    mask: Bool[Array, " max_detections"],
    block_size: int | None = None,
) -> Float[Array, " num_points"]:
    """``log sum_z N(p; z, diag(std_z^2))`` over the real detections ``z``, for each point.

    Every point meets every detection, and births are ``births_per_detection`` points per
    detection slot, so the pairs grow with the square of the detection capacity. They are
    reduced in blocks of ``block_size`` points (``lax.map``, each block recomputed in the
    backward pass by ``jax.checkpoint``); a block holds the whole ``[block, max_detections]``
    reduction of its points, so blocking does not change any point's sum.

    Args:
        points: ``(y1, y2, w, h)`` of each point.
        measurements: detections ``(y1, y2, w, h)``.
        std: each detection's measurement noise standard deviations.
        mask: True for real detections.
        block_size: points per block (static); None for ``PAIRS_PER_BLOCK // max_detections``.

    Returns:
        The log-density of each point (about ``LOG_ZERO`` when no detection is real).
    """
    num_points, num_slots = points.shape[0], measurements.shape[0]
    block = block_size or max(1, PAIRS_PER_BLOCK // max(num_slots, 1))
    log_norm = jnp.sum(jnp.log(std), axis=-1)

    # Written per dimension (one fused loop; a trailing axis of 4 to reduce does not
    # vectorise and costs a separate reduction pass). With few detections the pairs are laid
    # out [max_detections, block] and reduced row after row (:func:`logsumexp_rows`),
    # otherwise [block, max_detections] and reduced by ``logsumexp``.
    by_rows = num_slots <= UNROLLED_ROWS
    per_slot = functools.partial(jnp.expand_dims, axis=1 if by_rows else 0)
    per_point = functools.partial(jnp.expand_dims, axis=0 if by_rows else 1)

    def block_density(block_points):
        squares = sum(
            ((per_point(block_points[:, d]) - per_slot(measurements[:, d])) / per_slot(std[:, d]))
            ** 2
            for d in range(points.shape[-1])
        )
        log_gauss = -0.5 * squares - per_slot(log_norm)
        log_gauss = log_gauss - 2 * math.log(2 * math.pi)
        log_gauss = jnp.where(per_slot(mask), log_gauss, LOG_ZERO)
        return logsumexp_rows(log_gauss) if by_rows else jax.nn.logsumexp(log_gauss, axis=-1)

    if num_points <= block:
        return block_density(points)
    num_blocks = -(-num_points // block)
    padded = jnp.pad(points, ((0, num_blocks * block - num_points), (0, 0)), mode="edge")
    blocks = jax.lax.map(jax.checkpoint(block_density), padded.reshape(num_blocks, block, -1))
    return blocks.reshape(-1)[:num_points]


def birth_log_weights(
    draws: BirthDraws, birth_intensity: Intensity, births_per_detection: int
) -> Float[Array, " num_births"]:
    """``log w = log gamma(x) - log(J p(x | Z_k))`` of drawn births.

    ``J p(x | Z_k) = births_per_detection sum_z N(x; z, Sigma(z)) / |V_v|``.

    Args:
        draws: the births (:func:`draw_births`).
        birth_intensity: ``gamma`` over the 6-D state space (PHD-context eq. 19).
        births_per_detection: particles per detection slot (static).

    Returns:
        The log-weights (:data:`LOG_ZERO` for particles of padded slots).
    """
    log_weights = (
        log_intensity(birth_intensity, draws.states)
        - math.log(births_per_detection)
        - draws.log_mixture
        + draws.log_velocity_volume
    )
    return jnp.where(draws.real, log_weights, LOG_ZERO)


def sample_births(
    key: Array,
    measurements: Float[Array, "max_detections 4"],
    mask: Bool[Array, " max_detections"],
    births_per_detection: int,
    birth_intensity: Intensity,
    initial_intensity: Intensity,
    started: Bool[Array, ""],
    measurement_noise_std: Float[Array, " 4"],
    noise_model: NoiseModel = state_dependent_std,
    draw_slots: int | None = None,
    random: tuple[Array, Array] | None = None,
) -> tuple[Float[Array, "num_births 6"], Float[Array, " num_births"]]:
    """Draws one frame's birth particles and weights them by ``gamma / (J p)``.

    Before the first frame (``started`` False) ``gamma`` is ``initial_intensity``, afterwards
    ``birth_intensity``. The particles are drawn once, with the velocity range of the chosen
    intensity; both intensities are evaluated and the chosen log-weights kept (they may be
    PyTrees of different shapes, e.g. a learned mixture and a uniform).

    Args:
        key: PRNG key (:func:`draw_births`).
        measurements: detections ``(y1, y2, w, h)``; padded slots must hold a positive size.
        mask: True for real detections.
        births_per_detection: particles per detection slot (static).
        birth_intensity: ``gamma`` over the 6-D state space (PHD-context eq. 19).
        initial_intensity: ``gamma`` of the first frame.
        started: False on the first frame.
        measurement_noise_std: measurement noise parameters (relative for SDV).
        noise_model: the likelihood's noise model.
        draw_slots: slots the random numbers are drawn for (:func:`draw_births`).
        random: :func:`draw_births`'s random numbers, already drawn (None: drawn there).

    Returns:
        ``births_per_detection * max_detections`` states, detection-major, and their
        log-weights (:data:`LOG_ZERO` for particles of padded slots).
    """
    (birth_lower, birth_upper), (initial_lower, initial_upper) = (
        velocity_bounds(birth_intensity),
        velocity_bounds(initial_intensity),
    )
    draws = draw_births(
        key,
        measurements,
        mask,
        births_per_detection,
        jnp.where(started, birth_lower, initial_lower),
        jnp.where(started, birth_upper, initial_upper),
        measurement_noise_std,
        noise_model,
        draw_slots,
        random,
    )
    log_weights = jnp.where(
        started,
        birth_log_weights(draws, birth_intensity, births_per_detection),
        birth_log_weights(draws, initial_intensity, births_per_detection),
    )
    return draws.states, log_weights
