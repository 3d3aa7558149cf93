"""Differentiable objectives of the PHD tracker over a sequence.

Both objectives run the filter over the frames with :func:`~jaxtrack.filters.base.run` (its
``checkpoint`` and a per-frame loss as its ``frame_output``) and differentiate through it:
the dynamics and the births are reparameterised samples (noise times a scale), the
resampling step uses one of three gradient estimators (:func:`tuning_filter`), and the scan
body is wrapped in ``jax.checkpoint`` so that the backward pass stores one carry per frame
and recomputes each frame's intermediates: memory grows with the number of frames only
through the carries, not the ``[detections, particles]`` arrays of the update.

* :func:`likelihood_objective` (unsupervised, no ground truth): minus the PHD measurement
  log-likelihood summed over the frames (SPEC section 1, Poisson approximation), divided by
  the number of frames.
* :func:`supervised_objective` (ground truth): a relaxed GOSPA between the posterior PHD and
  the ground-truth boxes plus a cardinality term, averaged over frames
  (:func:`relaxed_gospa`).

An objective is called as ``objective.loss(params, key, detections, ground_truth)`` and
returns ``(loss, metrics)``; :func:`~jaxtrack.pipelines.tuner.tune` averages it over several
keys (common random numbers).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal, NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from jaxtrack.boxes import xywh_to_cxcywh
from jaxtrack.filters.base import Filter, run
from jaxtrack.filters.phd import phd_filter
from jaxtrack.models.dynamics import MEASURED
from jaxtrack.types import Detections, GroundTruth

#: Gradient estimators of the resampling step (:func:`tuning_filter`).
ESTIMATORS = ("stop_gradient", "soft", "none")


class Objective(NamedTuple):
    """A differentiable loss of the tracker's parameters.

    Attributes:
        name: ``"likelihood"`` or ``"supervised"``.
        loss: ``(params, key, detections, ground_truth) -> (loss, metrics)``, a scalar loss
            and a dict of scalar diagnostics; ``ground_truth`` is None for objectives that
            do not use it.
        needs_ground_truth: True when ``ground_truth`` is required.
    """

    name: str
    loss: Callable[..., tuple[Float[Array, ""], dict[str, Float[Array, ""]]]]
    needs_ground_truth: bool


def tuning_filter(
    num_particles: int,
    births_per_detection: int = 16,
    estimator: Literal["stop_gradient", "soft", "none"] = "stop_gradient",
    soft_weight: float = 0.5,
    extraction: Literal["gmm", "partition"] = "partition",
) -> Filter:
    """The PHD filter with a choice of gradient estimator for its resampling step.

    Args:
        num_particles: particles after resampling.
        births_per_detection: birth particles per detection slot.
        estimator: ``"stop_gradient"`` (default): the ancestors' score enters the gradient
            (Scibior & Wood 2021), so ``grad`` of an expectation over the filter's weights is
            unbiased; ``"soft"``: soft resampling with uniform share ``soft_weight``
            (Karkus et al. 2018), biased but of lower variance; ``"none"``: the ancestors are
            constants (naive, biased).
        soft_weight: ``alpha`` of soft resampling, in ``(0, 1)``.
        extraction: state extraction of the filter (it sees no gradient).

    Returns:
        The :func:`~jaxtrack.filters.phd.phd_filter`, with ``expected_birth_mass=True`` (its
        log-likelihood counts the births' expected detected mass ``pD lambda_s``; without it
        the likelihood grows without bound in the birth rate).

    Raises:
        ValueError: an unknown estimator or a bad soft weight.
    """
    if estimator not in ESTIMATORS:
        raise ValueError(f"estimator must be one of {', '.join(ESTIMATORS)}, got {estimator!r}")
    if estimator == "soft" and not 0.0 < soft_weight < 1.0:
        raise ValueError(f"soft_weight must lie in (0, 1), got {soft_weight}")
    return phd_filter(
        num_particles,
        births_per_detection=births_per_detection,
        extraction=extraction,
        stop_gradient_resampling=estimator == "stop_gradient",
        soft_resampling=soft_weight if estimator == "soft" else 0.0,
        expected_birth_mass=True,
    )


def likelihood_objective(filt: Filter, checkpoint: bool = True) -> Objective:
    """Minus the PHD measurement log-likelihood per frame (unsupervised).

    ``loss = -(1/T) sum_k log p(Z_k | Z_1:k-1)`` with the Poisson approximation of SPEC
    section 1, ``log p(Z_k | Z_1:k-1) ~= -sum_i (1 - pM) w_i - int kappa +
    sum_z log(kappa(z) + C(z))``, as the filter reports it
    (:attr:`~jaxtrack.filters.phd.PHDInfo.log_likelihood`). Needs no ground truth.

    Args:
        filt: a PHD filter (e.g. :func:`tuning_filter`).
        checkpoint: rematerialise the scan body.

    Returns:
        The :class:`Objective`; its metrics are ``log_likelihood`` (the sum over frames) and
        ``mass`` (the mean PHD mass).
    """

    def frame_loss(state, info, index):
        return {"log_likelihood": info.log_likelihood, "mass": info.mass}

    def loss(params, key, detections, ground_truth=None):
        del ground_truth
        _, out = run(filt, key, params, detections, checkpoint=checkpoint, frame_output=frame_loss)
        num_frames = detections.mask.shape[0]
        total = jnp.sum(out["log_likelihood"])
        return -total / num_frames, {"log_likelihood": total, "mass": jnp.mean(out["mass"])}

    return Objective("likelihood", loss, needs_ground_truth=False)


def box_distance2(
    states: Float[Array, "num_particles 4"], boxes: Float[Array, "max_objects 4"]
) -> Float[Array, "num_particles max_objects"]:
    """Squared scale-free distance of particle boxes to ground-truth boxes (``cx, cy, w, h``).

    ``d^2(x, g) = sum_c ((x_c - g_c) / s_c)^2`` with ``s = (g_w, g_h, g_w, g_h)``: an offset of
    one box width (or height) counts 1, whatever the box size (the SDV scaling of SPEC
    section 1).
    """
    scale = jnp.concatenate([boxes[:, 2:], boxes[:, 2:]], axis=-1)
    diff = (states[:, None, :] - boxes[None, :, :]) / scale[None]
    return jnp.sum(diff**2, axis=-1)


def relaxed_gospa(
    states: Float[Array, "num_particles 4"],
    log_weights: Float[Array, " num_particles"],
    boxes: Float[Array, "max_objects 4"],
    mask: Bool[Array, " max_objects"],
    cutoff: float = 1.0,
    epsilon: float = 0.05,
    iterations: int = 30,
) -> tuple[Float[Array, ""], Float[Array, ""]]:
    """An entropy-smoothed GOSPA (``p = 2``, ``alpha = 2``) between a PHD and a set of boxes.

    GOSPA (Rahmathullah, Garcia-Fernandez & Svensson 2017) with ``alpha = 2`` is the optimal
    assignment cost ``sum_assigned d^2 + (c^2 / 2) (#missed + #false)``. For a PHD (particles
    of masses ``w_i``, total ``M``) its linear-programming relaxation lets each ground-truth
    box take up to one unit of particle mass: an optimal transport between the particle masses
    plus a dummy of mass ``n`` (the number of boxes) and the boxes' unit masses plus a dummy of
    mass ``M``, with costs ``d_c^2(x_i, g_j)`` between particles and boxes and ``c^2 / 2`` to a
    dummy (a missed box, or false mass). For a PHD of point masses of weight 1 on an integer
    number of states this is GOSPA exactly. Two smoothings make it differentiable: the
    cut-off ``min(d^2, c^2)`` becomes ``c^2 (1 - exp(-d^2 / c^2))`` (equal to ``d^2`` to
    first order, saturating at ``c^2``), and the transport is entropy-regularised (log-domain
    Sinkhorn, ``epsilon`` relative to ``c^2``, a fixed number of iterations unrolled so that
    gradients flow through it).

    Args:
        states: particle boxes ``(cx, cy, w, h)``.
        log_weights: particle log-masses.
        boxes: ground-truth boxes ``(cx, cy, w, h)`` (padded slots any positive size).
        mask: True for the boxes that count.
        cutoff: ``c``, in box sizes (:func:`box_distance2`).
        epsilon: entropic regularisation, relative to ``c^2``.
        iterations: Sinkhorn iterations.

    Returns:
        The relaxed GOSPA squared (the transport cost, excluding the entropy) and the PHD
        mass ``M``.
    """
    c2 = cutoff**2
    cost_pairs = c2 * -jnp.expm1(-box_distance2(states, boxes) / c2)
    num_boxes = jnp.sum(mask)
    log_mass = jax.nn.logsumexp(log_weights)
    # Rows: particles + dummy (missed boxes); columns: boxes + dummy (false mass).
    cost = jnp.full((states.shape[0] + 1, boxes.shape[0] + 1), c2 / 2)
    cost = cost.at[:-1, :-1].set(cost_pairs).at[-1, -1].set(0.0)
    log_num_boxes = jnp.log(jnp.maximum(num_boxes, 1e-30))
    log_rows = jnp.concatenate([log_weights, log_num_boxes[None]])
    log_cols = jnp.concatenate([jnp.where(mask, 0.0, -jnp.inf), log_mass[None]])
    log_total = jnp.logaddexp(log_mass, log_num_boxes)
    log_a, log_b = log_rows - log_total, log_cols - log_total
    kernel = -cost / (epsilon * c2)

    def sinkhorn(potentials, _):
        f, g = potentials
        f = log_a - jax.nn.logsumexp(kernel + g[None, :], axis=1)
        f = jnp.where(jnp.isfinite(log_a), f, 0.0)
        g = log_b - jax.nn.logsumexp(kernel + f[:, None], axis=0)
        g = jnp.where(jnp.isfinite(log_b), g, 0.0)
        return (f, g), None

    init = (jnp.zeros_like(log_a), jnp.zeros_like(log_b))
    (f, g), _ = jax.lax.scan(sinkhorn, init, None, length=iterations)
    log_plan = kernel + f[:, None] + g[None, :]
    log_plan = jnp.where(
        jnp.isfinite(log_a)[:, None] & jnp.isfinite(log_b)[None, :], log_plan, -jnp.inf
    )
    plan = jnp.exp(log_plan + log_total)
    return jnp.sum(plan * cost), jnp.exp(log_mass)


def supervised_objective(
    filt: Filter,
    cutoff: float = 1.0,
    cardinality_weight: float = 0.5,
    epsilon: float = 0.05,
    iterations: int = 30,
    checkpoint: bool = True,
) -> Objective:
    """A smooth loss between the posterior PHD and the ground truth.

    Per frame: :func:`relaxed_gospa` between the posterior particles (after the update and
    resampling, their boxes ``C x``) and the ground-truth boxes that are not ignored, plus
    ``cardinality_weight * (M - n)^2``, ``M`` the PHD mass, ``n`` the number of boxes;
    averaged over frames.

    Why this choice: GOSPA (``alpha = 2``) is the multi-target metric whose parts are the
    MOTA's parts (localisation, misses, false tracks) rather than OSPA's normalised mix; on
    the PHD itself (not on extracted states) it is differentiable in the particle states and
    masses, where extraction and labelling are discrete. Its relaxation charges the false mass
    and the misses only linearly, and spreading mass is cheap inside the cut-off, so the
    squared cardinality error adds the PHD's defining property, ``E|X| = M``, with a gradient
    that stays informative when the PHD mass is far from the truth.

    Args:
        filt: a PHD filter (e.g. :func:`tuning_filter`).
        cutoff: GOSPA cut-off ``c`` in box sizes.
        cardinality_weight: weight of the cardinality term, ``>= 0``.
        epsilon: Sinkhorn regularisation relative to ``c^2``.
        iterations: Sinkhorn iterations per frame.
        checkpoint: rematerialise the scan body.

    Returns:
        The :class:`Objective`; its metrics are ``gospa`` and ``cardinality_error`` (means
        over frames) and ``mass`` (mean PHD mass).

    Raises:
        ValueError: a non-positive cut-off, epsilon or iteration count, or a negative weight.
    """
    if cutoff <= 0 or epsilon <= 0 or iterations <= 0:
        raise ValueError("cutoff, epsilon and iterations must be positive")
    if cardinality_weight < 0:
        raise ValueError(f"cardinality_weight must be >= 0, got {cardinality_weight}")

    def loss(params, key, detections, ground_truth):
        boxes = xywh_to_cxcywh(jnp.asarray(ground_truth.boxes), jnp)
        mask = jnp.asarray(ground_truth.mask) & ~jnp.asarray(ground_truth.ignored)

        def frame_loss(state, info, index):
            particle_boxes = state.particles[:, MEASURED]
            gospa, mass = relaxed_gospa(
                particle_boxes,
                state.log_weights,
                boxes[index],
                mask[index],
                cutoff,
                epsilon,
                iterations,
            )
            cardinality_error = (mass - jnp.sum(mask[index])) ** 2
            return {"gospa": gospa, "cardinality_error": cardinality_error, "mass": mass}

        _, out = run(filt, key, params, detections, checkpoint=checkpoint, frame_output=frame_loss)
        metrics = {name: jnp.mean(value) for name, value in out.items()}
        total = metrics["gospa"] + cardinality_weight * metrics["cardinality_error"]
        return total, metrics

    return Objective("supervised", loss, needs_ground_truth=True)


def check_ground_truth(detections: Detections, ground_truth: GroundTruth | None) -> None:
    """Raises ``ValueError`` unless ``ground_truth`` has one frame per frame of detections."""
    if ground_truth is None:
        raise ValueError("the supervised objective needs ground truth")
    if ground_truth.mask.shape[0] != detections.mask.shape[0]:
        raise ValueError(
            f"ground truth has {ground_truth.mask.shape[0]} frames, detections "
            f"{detections.mask.shape[0]}"
        )


ObjectiveName = Literal["likelihood", "supervised"]


def make_objective(name: ObjectiveName, filt: Filter, **options) -> Objective:
    """:func:`likelihood_objective` or :func:`supervised_objective` by name.

    Raises:
        ValueError: an unknown name.
    """
    if name == "likelihood":
        return likelihood_objective(filt, **options)
    if name == "supervised":
        return supervised_objective(filt, **options)
    raise ValueError(f"objective must be 'likelihood' or 'supervised', got {name!r}")
