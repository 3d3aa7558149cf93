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

**Velocities from the previous frame's detections** (``velocities="detections"``,
:func:`propose_velocities`; the tracker's option ``PHDConfig.birth_velocity``, default
``"uniform"``: on the scene bank it did not track better, README "A held-out failure
traced, and births' velocities from the previous frame", session 50). A uniform velocity
over ``V_v`` (46 x 46 pixels per frame at 576 rows) gives the 32 births of a detection one
draw per ~66 (pixels per frame)^2: a new track may start with a velocity several pixels
per frame off, its prediction then lags the target, and where the context's clutter
intensity is high (a clutter source the target walks through) its detections are explained
as clutter and the track dies (layout-change-26, issue 15). A target seen in the previous
frame moved by about ``z - z'``; so the velocity is drawn, given the drawn box ``p = (y1, y2,
w, h)``, from

    q(v | p) = eps U(v; V_v) + (1 - eps) sum_j a_j(p) N(v; p_xy - z'_j, 2 diag(s_xy(p))^2),
    a_j(p) proportional to N(p_wh - z'_j,wh; 0, 2 diag(s_wh(p))^2) over the previous
    detections z'_j whose displacement p_xy - z'_j lies in V_v and whose size passes a
    99 % chi-square gate (SIZE_GATE; q = U when there is none),

``s(p)`` the measurement noise of a box of ``p``'s size (the difference of two detections of
one target has twice its variance; the weights ``a_j`` prefer previous boxes of a compatible
size) and ``eps`` = :data:`UNIFORM_VELOCITY_SHARE` (a target missed in the previous frame, or
one whose previous box is not among the slots kept, is still covered). The proposal is
``p(x | Z_k) = [(1 / |Z_k|) sum_z N(p; z, Sigma(z))] q(v | p)`` and the weights ``gamma / (J
p)`` use it exactly, so the births remain an unbiased estimate of ``gamma``: the filter is
the same in expectation, its Monte Carlo error at a new target's velocity smaller.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
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

#: The births' velocity proposals (:func:`draw_births`): uniform over ``V_v`` (the paper's) or
#: from the previous frame's detections (:func:`propose_velocities`).
VELOCITY_PROPOSALS = ("uniform", "detections")
#: Previous-frame detections a PHD state keeps for the velocity proposal (the first slots;
#: the MOT15 training sequences have at most 16 detections per frame). A step reads as many
#: of them as its run has detection slots.
PREVIOUS_SLOTS = 32
#: ``eps``: share of the velocity proposal that is uniform over ``V_v`` (chosen a priori: a
#: quarter of a detection's births as before, the rest at the previous detections'
#: displacements).
UNIFORM_VELOCITY_SHARE = 0.25


#: Gate on a previous box's size: ``|(p_wh - z'_wh) / (sqrt(2) s_wh(p))|^2`` at most the 99 %
#: quantile of the chi-square law with 2 degrees of freedom (a box of another size is not the
#: same target; :func:`propose_velocities`).
SIZE_GATE = 9.21


class PreviousDetections(NamedTuple):
    """The previous frame's detections, kept for the births' velocity proposal.

    Attributes:
        boxes: ``(y1, y2, w, h)`` (centre and size) of :data:`PREVIOUS_SLOTS` slots; padded
            slots hold a positive size.
        mask: True for real detections.
    """

    boxes: Float[Array, "slots 4"]
    mask: Bool[Array, " slots"]


def no_previous_detections(dtype=jnp.float32) -> PreviousDetections:
    """The :class:`PreviousDetections` before the first frame: none."""
    return PreviousDetections(
        jnp.ones((PREVIOUS_SLOTS, 4), dtype), jnp.zeros((PREVIOUS_SLOTS,), bool)
    )


def keep_previous_detections(
    measurements: Float[Array, "max_detections 4"], mask: Bool[Array, " max_detections"]
) -> PreviousDetections:
    """A frame's first :data:`PREVIOUS_SLOTS` detection slots, padded to that many (padded
    slots hold ones whatever the frame's padding, so a step on the first half of the slots
    keeps what the full step keeps)."""
    pad = max(PREVIOUS_SLOTS - measurements.shape[0], 0)
    mask = jnp.pad(mask, (0, pad))[:PREVIOUS_SLOTS]
    boxes = jnp.pad(measurements, ((0, pad), (0, 0)))[:PREVIOUS_SLOTS]
    return PreviousDetections(jnp.where(mask[:, None], boxes, 1), mask)


class BirthDraws(NamedTuple):
    """Birth particles drawn around the detections, before weighting.

    Attributes:
        states: ``births_per_detection * max_detections`` states, detection-major.
        log_mixture: ``log sum_z N((y1, y2, w, h); z, Sigma(z))`` over the real detections.
        log_velocity_weight: ``-log q(v | p)`` of each birth's velocity under its proposal:
            ``log |V_v|`` (a scalar) for uniform velocities, one value per birth for
            :func:`propose_velocities`.
        real: True for the particles of real detection slots.
    """

    states: Float[Array, "num_births 6"]
    log_mixture: Float[Array, " num_births"]
    log_velocity_weight: Float[Array, "*num_births"]
    real: Bool[Array, " num_births"]


def velocity_bounds(intensity: Intensity) -> tuple[Float[Array, " 2"], Float[Array, " 2"]]:
    """Lower and upper corners ``V_v`` of the velocity part of an intensity's volume."""
    return intensity.lower[jnp.array(VELOCITY)], intensity.upper[jnp.array(VELOCITY)]


def birth_requests(
    key: Array,
    draw_slots: int,
    births_per_detection: int,
    dtype=jnp.float32,
    velocities: str = "uniform",
) -> list:
    """The random numbers :func:`draw_births` draws from ``key``: ``key`` split in two, the
    Gaussian draws ``normal(k1, (draw_slots, J, 4))`` and the velocities' unit draws
    ``uniform(k2, (draw_slots J, 2))`` (scaled to the velocity range by :func:`draw_births`,
    as ``jax.random.uniform(k2, ..., minval, maxval)`` scales them). With ``velocities =
    "detections"`` also, from ``fold_in(key, 1)`` split in two, the proposal's Gaussian
    draws ``normal(k3, (draw_slots J, 2))`` and its choices ``uniform(k4, (draw_slots J,
    2))`` (:func:`propose_velocities`); the first two are the same numbers either way."""
    key_gauss, key_velocity = draws.split(key)
    num_births = draw_slots * births_per_detection
    requests = [
        draws.normal(key_gauss, (draw_slots, births_per_detection, 4), dtype),
        draws.uniform(key_velocity, (num_births, 2), dtype=dtype),
    ]
    if velocities == "detections":
        key_offset, key_choice = jax.random.split(jax.random.fold_in(key, 1))
        requests += [
            draws.normal(key_offset, (num_births, 2), dtype),
            draws.uniform(key_choice, (num_births, 2), dtype=dtype),
        ]
    return requests


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
    random: tuple[Array, ...] | None = None,
    velocities: str = "uniform",
    previous: PreviousDetections | None = None,
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
        random: the random numbers :func:`birth_requests` asks ``key`` for (with the same
            ``velocities``), already drawn (:func:`jaxtrack.filters.draws.draw`); None:
            drawn here.
        velocities: the velocity proposal (static): ``"uniform"`` over ``V_v`` or
            ``"detections"`` (:func:`propose_velocities`, needs ``previous``).
        previous: the previous frame's detections (``velocities="detections"``).

    Returns:
        The draws (sizes clipped below at :data:`~jaxtrack.models.dynamics.MIN_SIZE`, far in
        the Gaussian's tail) and the parts of their proposal density.

    Raises:
        ValueError: ``draw_slots`` below ``max_detections``, an unknown ``velocities``, or
            ``"detections"`` without ``previous``.
    """
    num_slots = measurements.shape[0]
    drawn = num_slots if draw_slots is None else draw_slots
    if drawn < num_slots:
        raise ValueError(f"draw_slots ({drawn}) must be at least the {num_slots} slots")
    if velocities not in VELOCITY_PROPOSALS:
        raise ValueError(f"velocities must be one of {VELOCITY_PROPOSALS}, got {velocities!r}")
    if velocities == "detections" and previous is None:
        raise ValueError('velocities="detections" needs the previous frame\'s detections')
    num_births = num_slots * births_per_detection
    if random is None:
        random = draws.draw(
            birth_requests(key, drawn, births_per_detection, measurements.dtype, velocities)
        )
    normal, unit = random[:2]
    std = noise_model(measurements[:, 2:], measurement_noise_std)
    normal = normal[:num_slots]
    measured = (measurements[:, None, :] + std[:, None, :] * normal).reshape(-1, 4)
    measured = measured.at[:, 2:].set(jnp.maximum(measured[:, 2:], MIN_SIZE))
    # jax.random.uniform(key_velocity, shape, minval=lower, maxval=upper) on the unit draws.
    velocity = draws.scale_uniform(unit[:num_births], velocity_lower, velocity_upper)
    log_velocity_weight = jnp.sum(jnp.log(velocity_upper - velocity_lower))
    if velocities == "detections":
        offsets, choices = (numbers[:num_births] for numbers in random[2:])
        # The previous frame's first slots, as many as the run's (the full step's, also for
        # a step on half the slots, which then draws what the full step draws).
        kept = min(PREVIOUS_SLOTS, drawn)
        previous = PreviousDetections(previous.boxes[:kept], previous.mask[:kept])
        velocity, log_velocity_density = propose_velocities(
            measured,
            velocity,
            velocity_lower,
            velocity_upper,
            previous,
            std_of=functools.partial(noise_model, noise_std=measurement_noise_std),
            offsets=offsets,
            choices=choices,
        )
        log_velocity_weight = -log_velocity_density
    # (y1, vy1, y2, vy2, w, h) stacked as rows, then transposed (see phd_step's join).
    y1, y2, width, height = (measured[:, i] for i in range(4))
    states = jnp.stack([y1, velocity[:, 0], y2, velocity[:, 1], width, height], axis=0).T
    return BirthDraws(
        states=states,
        log_mixture=log_mixture_density(measured, measurements, std, mask),
        log_velocity_weight=log_velocity_weight,
        real=jnp.repeat(mask, births_per_detection),
    )


def propose_velocities(
    points: Float[Array, "num_births 4"],
    uniform_velocity: Float[Array, "num_births 2"],
    velocity_lower: Float[Array, " 2"],
    velocity_upper: Float[Array, " 2"],
    previous: PreviousDetections,
    std_of: Callable[[Array], Array],
    offsets: Float[Array, "num_births 2"],
    choices: Float[Array, "num_births 2"],
) -> tuple[Float[Array, "num_births 2"], Float[Array, " num_births"]]:
    """Draws each birth's velocity from ``q(v | p)`` (the module docstring) and its log-density.

    The ``[births, previous slots]`` pairs are computed once, in linear space (the shares
    ``a_j`` are at most 1; a birth whose reachable shares all underflow is given uniform
    velocities, as one with no reachable box); ``j`` is chosen by inverse transform of the
    shares' cumulative sums (a product with a triangular matrix) and gathered as a one-hot
    sum: about 6x faster on CPU than log-space shares with a gather.

    Args:
        points: the births' drawn boxes ``p = (y1, y2, w, h)``.
        uniform_velocity: a velocity drawn uniformly over ``V_v`` per birth (kept where the
            choice is the uniform part).
        velocity_lower: lower corner of ``V_v``.
        velocity_upper: upper corner of ``V_v``.
        previous: the previous frame's detections ``z'_j``.
        std_of: the measurement noise ``s(p)`` of boxes of the given sizes ``[..., 2]``
            (pixels, ``[..., 4]``); held constant for gradients (the proposal's spread).
        offsets: standard normal draws, the Gaussian part's offsets.
        choices: unit uniform draws: column 0 picks ``j`` (by ``a_j(p)``), column 1 the part
            (uniform when below :data:`UNIFORM_VELOCITY_SHARE`).

    Returns:
        The velocities and ``log q(v | p)``.
    """
    boxes, mask = previous
    num_previous = mask.shape[0]
    scale = 1.0 / (math.sqrt(2.0) * jax.lax.stop_gradient(std_of(points[:, 2:])))
    # [births, previous] pairs, one array per coordinate.
    shift_x = points[:, 0:1] - boxes[None, :, 0]
    shift_y = points[:, 1:2] - boxes[None, :, 1]
    gap_w = (points[:, 2:3] - boxes[None, :, 2]) * scale[:, 2:3]
    gap_h = (points[:, 3:4] - boxes[None, :, 3]) * scale[:, 3:4]
    reachable = (
        mask[None, :]
        & (shift_x >= velocity_lower[0])
        & (shift_x <= velocity_upper[0])
        & (shift_y >= velocity_lower[1])
        & (shift_y <= velocity_upper[1])
    )
    size_gap = gap_w * gap_w + gap_h * gap_h
    # Only boxes of a compatible size: their shares then lie in [exp(-SIZE_GATE / 2), 1], far
    # above float32's rounding of the cumulative sums and its flushed subnormals (a pick's
    # probability must be what its density says, or its births' weights explode).
    reachable = reachable & (size_gap <= SIZE_GATE)
    shares = jnp.where(reachable, jnp.exp(-0.5 * size_gap), 0.0)
    cumulative = shares @ jnp.triu(jnp.ones((num_previous, num_previous), shares.dtype))
    total = cumulative[:, -1]
    any_reachable = total > 0
    # The first box of positive share whose cumulative sum reaches the target (the last one
    # when rounding leaves none): the sums are separate dot products, so a zero share may
    # round to a step of the cumulative sum, and a box of no share must never be picked
    # (its displacement may be far outside the mixture's support).
    positive = shares > 0
    reached = positive & (cumulative >= choices[:, :1] * total[:, None])
    last = num_previous - 1 - jnp.argmax(positive[:, ::-1], axis=1)
    index = jnp.where(jnp.any(reached, axis=1), jnp.argmax(reached, axis=1), last)
    picked = jnp.arange(num_previous)[None, :] == index[:, None]
    centre = jnp.stack(
        [jnp.sum(jnp.where(picked, shift, 0.0), axis=1) for shift in (shift_x, shift_y)], -1
    )
    uniform = (choices[:, 1] < UNIFORM_VELOCITY_SHARE) | ~any_reachable
    velocity = jnp.where(uniform[:, None], uniform_velocity, centre + offsets / scale[:, :2])
    inside = jnp.all((velocity >= velocity_lower) & (velocity <= velocity_upper), axis=-1)
    uniform_density = jnp.where(inside, 1.0 / jnp.prod(velocity_upper - velocity_lower), 0.0)
    err_x = (velocity[:, 0:1] - shift_x) * scale[:, 0:1]
    err_y = (velocity[:, 1:2] - shift_y) * scale[:, 1:2]
    mixture = jnp.sum(shares * jnp.exp(-0.5 * (err_x * err_x + err_y * err_y)), axis=1)
    gauss_density = (
        mixture * scale[:, 0] * scale[:, 1] / (2 * math.pi) / jnp.where(any_reachable, total, 1.0)
    )
    density = jnp.where(
        any_reachable,
        UNIFORM_VELOCITY_SHARE * uniform_density + (1 - UNIFORM_VELOCITY_SHARE) * gauss_density,
        uniform_density,
    )
    # A draw's own component keeps its density far above float32's smallest normal number
    # (its offsets are a few standard deviations); the floor only keeps the log finite.
    return velocity, jnp.log(jnp.maximum(density, jnp.finfo(density.dtype).tiny))


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

    ``J p(x | Z_k) = births_per_detection sum_z N(p; z, Sigma(z)) q(v | p)``, ``p`` the box
    and ``v`` the velocity of ``x``, ``q = 1 / |V_v|`` for uniform velocities.

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
        + draws.log_velocity_weight
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
    random: tuple[Array, ...] | None = None,
    velocities: str = "uniform",
    previous: PreviousDetections | None = None,
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
        velocities: the velocity proposal (static; :func:`draw_births`).
        previous: the previous frame's detections (``velocities="detections"``).

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
        velocities,
        previous,
    )
    log_weights = jnp.where(
        started,
        birth_log_weights(draws, birth_intensity, births_per_detection),
        birth_log_weights(draws, initial_intensity, births_per_detection),
    )
    return draws.states, log_weights
