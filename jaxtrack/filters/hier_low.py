"""Low level of the Hierarchical tracker: a Kalman bank with gated nearest-track association.

Hierarchical paper, Sec. 4 (SPEC section 4, "Low level"). One :func:`low_step` per frame on a
fixed table of ``T`` track slots (``alive`` mask), ``D`` padded measurements (``valid`` mask):

1. **predict** every track (constant velocity on the centre, random walk on the shape):
   ``x <- F x``, ``P <- F P F^T + Q``;
2. **measurement validation**: innovation ``nu = z - H x`` (an angle wrapped to
   ``(-pi/2, pi/2]``), ``S_k = H P H^T + R``, Mahalanobis square distance
   ``MSD = nu^T S_k^-1 nu``; a measurement lies in a track's gate when ``MSD <= gate`` (the
   chi-square quantile with ``m`` degrees of freedom of the chosen confidence interval);
3. **association**: "measures are associated to the nearest tracker in whose gate they lie";
   *nearest* in likelihood: the cost is ``MSD + 2 log r_k`` (the Gaussian negative
   log-likelihood up to a constant, with ``|S_k|`` relative to the steady state), not the MSD
   alone, which favours an uncertain new track (wide ``S_k``) over a settled one: on the
   synthetic development scenes (video seeds 0-2, managed low level, their detections) MOTA
   0.85 / 0.91 / 0.89 with the MSD, 0.94 / 0.92 / 0.96 with this cost. A track takes at most
   one measurement: greedily, the gated pair of smallest cost first, then the next smallest
   among the remaining rows and columns (a ``lax`` loop of
   ``min(D, T)`` trips). **Recovery** (a departure): a measurement no track took is then
   offered, in the same greedy order, to the *confirmed* tracks that took none, within the
   wider ``recovery_gate`` (the 99.99 % chi-square quantile by default); only the
   measurements still left are orphans. A settled track's prediction lags a target whose
   size changes steadily (a pedestrian walking away from the camera shrinks by about 1 % of
   its height per frame; the shape is a random walk), so one detection a little further off
   than usual fell outside the 99 % gate; a tentative track was born on it, took the
   target's next detections (the coasting track's gate being no closer), was confirmed
   while the settled track still coasted, and became a new identity: in the scripted group
   walks of the development scenes most identity switches came from this. Development data
   (synthetic video seeds 0-2 and 4-6, full tracker; MOT15's 8 training sequences without
   video, managed low level): README, "Hierarchical tracking";
4. **update** the paired tracks (Joseph form); the others keep their prediction;
5. **track management** by ``|S_k|^1/2`` and the MSD: a tentative track is born on each
   orphan measurement; it is confirmed when the normalised ratio ``r_k``
   (:mod:`~jaxtrack.filters.hier_low_model`) and the track's mean MSD are small on a frame
   with a measurement; any track is removed on a frame without measurement where
   ``r_k > remove_ratio`` (``|S_k|^1/2`` has grown too large).

Detection scores (optional, beyond the paper): with ``strong`` a track is confirmed only once
it has held a strong measurement (``LowState.scored``), and with ``log_odds`` the cost of a
pair falls by twice the measurement's log-odds of being a target, so that the cost is the
pair's negative log-likelihood ratio against clutter (up to a constant). The Hierarchical
tracker passes both from the detection scores (``confirm_score``, ``score_weight``).

The measurement model (``"box"`` or ``"ellipse"``), the scale-dependent noise and ``r_k`` are
in :mod:`~jaxtrack.filters.hier_low_model`; the thresholds derived from the model's steady
state in :mod:`~jaxtrack.filters.hier_low_defaults`.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from jaxtrack.errors import InputError
from jaxtrack.filters.hier_low_model import (
    Measurement,
    ellipse_to_box,
    innovation_covariance,
    low_predict,
    low_update,
    mahalanobis_square_distances,
    measurement_model,
    normalised_ratio,
    scaled_std,
    track_scale,
)


class LowParams(NamedTuple):
    """Parameters of the low level (a PyTree; unit-scale noise, see
    :mod:`~jaxtrack.filters.hier_low_model`; thresholds from
    :func:`~jaxtrack.filters.hier_low_defaults.low_params`).

    Attributes:
        process_std: ``[m]``: per frame, the centre's acceleration (x, y) then each shape
            component's random-walk step; lengths relative to the track size ``s``.
        measurement_std: ``[m]``: measurement noise, lengths relative to ``s``.
        initial_std: ``[n]``: standard deviation of a new track's state (its mean is the
            measurement, zero velocity), lengths relative to ``s``.
        gate: largest MSD of a validated measurement (chi-square quantile, ``m`` dof).
        recovery_gate: largest MSD at which a confirmed track that took no measurement takes
            one that no track took (step 3's recovery; at least ``gate``).
        log_steady_sqrt_det: ``log |S0_inf|^1/2`` of the unit-scale model (normalises ``r_k``).
        confirm_ratio: a track is confirmed when ``r_k <= confirm_ratio`` ...
        confirm_msd: ... and its mean MSD ``<= confirm_msd``, on a frame with a measurement.
        remove_ratio: a track is removed when ``r_k > remove_ratio`` on a frame without one.
    """

    process_std: Float[Array, " m"]
    measurement_std: Float[Array, " m"]
    initial_std: Float[Array, " n"]
    gate: Float[Array, ""]
    recovery_gate: Float[Array, ""]
    log_steady_sqrt_det: Float[Array, ""]
    confirm_ratio: Float[Array, ""]
    confirm_msd: Float[Array, ""]
    remove_ratio: Float[Array, ""]


class LowState(NamedTuple):
    """The track table of the low level (the scan carry).

    Attributes:
        mean: ``[T, n]`` state estimate of each slot.
        cov: ``[T, n, n]`` its covariance.
        alive: slot holds a track (tentative or confirmed).
        confirmed: the track is confirmed (it stays so until removed).
        ids: identity of the slot's track (0, 1, ... in birth order; -1 for a free slot).
        next_id: the identity of the next track born.
        age: frames since the track's birth (1 on its birth frame).
        misses: consecutive frames without a measurement.
        hits: measurements associated since the birth (the birth measurement not counted).
        msd: mean MSD of those ``hits`` measurements (0 before the first).
        ratio: ``r_k`` of the frame's innovation covariance; for a track born on the frame,
            that of its initial covariance, ``H P0 H^T + R``.
        scored: the track has held a measurement marked ``strong`` (a detection scoring at
            least the tracker's ``confirm_score``): a condition of its confirmation.
    """

    mean: Float[Array, "T n"]
    cov: Float[Array, "T n n"]
    alive: Bool[Array, " T"]
    confirmed: Bool[Array, " T"]
    ids: Int[Array, " T"]
    next_id: Int[Array, ""]
    age: Int[Array, " T"]
    misses: Int[Array, " T"]
    hits: Int[Array, " T"]
    msd: Float[Array, " T"]
    ratio: Float[Array, " T"]
    scored: Bool[Array, " T"]


class LowInfo(NamedTuple):
    """Per-frame outputs of :func:`low_step`.

    Attributes:
        assignment: ``[D]``: the slot that took each measurement (a track it updated or the
            tentative track born on it), -1 for an invalid measurement or an overflow.
        born: ``[T]`` a tentative track was born in the slot.
        removed: ``[T]`` the slot's track was removed (its slot is free from the next frame).
        newly_confirmed: ``[T]`` the slot's track was confirmed on this frame.
        overflow: orphan measurements that found no free slot (no track was born on them).
        ratio: ``[T]`` ``r_k`` (0 in free slots).
        msd: ``[T]`` mean MSD of each track's associated measurements (0 in free slots).
    """

    assignment: Int[Array, " D"]
    born: Bool[Array, " T"]
    removed: Bool[Array, " T"]
    newly_confirmed: Bool[Array, " T"]
    overflow: Int[Array, ""]
    ratio: Float[Array, " T"]
    msd: Float[Array, " T"]


def _free_slot(n: int) -> tuple[Float[Array, " n"], Float[Array, "n n"]]:
    """Placeholder mean (zeros) and covariance (identity) of a free slot: finite values."""
    return jnp.zeros(n, jnp.float32), jnp.eye(n, dtype=jnp.float32)


def init_low(capacity: int, measurement: Measurement) -> LowState:
    """An empty table of ``capacity`` slots for the named measurement model."""
    if capacity < 1:
        raise InputError(f"capacity must be positive, got {capacity}")
    n = measurement_model(measurement).transition.shape[0]
    mean, cov = _free_slot(n)
    zeros = jnp.zeros(capacity, jnp.int32)
    return LowState(
        mean=jnp.tile(mean, (capacity, 1)),
        cov=jnp.tile(cov, (capacity, 1, 1)),
        alive=jnp.zeros(capacity, bool),
        confirmed=jnp.zeros(capacity, bool),
        ids=jnp.full(capacity, -1, jnp.int32),
        next_id=jnp.asarray(0, jnp.int32),
        age=zeros,
        misses=zeros,
        hits=zeros,
        msd=jnp.zeros(capacity, jnp.float32),
        ratio=jnp.zeros(capacity, jnp.float32),
        scored=jnp.zeros(capacity, bool),
    )


def nearest_gated_pairs(
    costs: Float[Array, "D T"], gated: Bool[Array, "D T"]
) -> tuple[Int[Array, " D"], Int[Array, " T"]]:
    """Greedy nearest-track association: repeatedly the gated pair with the smallest cost.

    Each pick removes its measurement row and track column; ``min(D, T)`` trips of a
    ``lax.fori_loop`` (ties go to the first pair in row-major order).

    Returns:
        The track of each measurement (-1: none) and the measurement of each track (-1).
    """
    num_measurements, num_tracks = costs.shape
    cost = jnp.where(gated, costs, jnp.inf)

    def pick(_, carry):
        cost, track_of, measurement_of = carry
        flat = jnp.argmin(cost)
        row, col = flat // num_tracks, flat % num_tracks
        found = jnp.isfinite(cost[row, col])
        track_of = track_of.at[row].set(jnp.where(found, col, track_of[row]))
        measurement_of = measurement_of.at[col].set(jnp.where(found, row, measurement_of[col]))
        cost = jnp.where(found, cost.at[row].set(jnp.inf).at[:, col].set(jnp.inf), cost)
        return cost, track_of, measurement_of

    init = (
        cost,
        jnp.full(num_measurements, -1, jnp.int32),
        jnp.full(num_tracks, -1, jnp.int32),
    )
    _, track_of, measurement_of = jax.lax.fori_loop(
        0, min(num_measurements, num_tracks), pick, init
    )
    return track_of, measurement_of


def birth_slots(
    orphan: Bool[Array, " D"], free: Bool[Array, " T"]
) -> tuple[Bool[Array, " T"], Int[Array, " T"], Int[Array, ""]]:
    """The ``k``-th orphan measurement (measurement order) goes to the ``k``-th free slot.

    Returns:
        Slots that receive a birth, the measurement each one takes (0 where none), and the
        number of orphans beyond the free slots.
    """
    num_orphans = jnp.sum(orphan, dtype=jnp.int32)
    order = jnp.nonzero(orphan, size=orphan.shape[0], fill_value=0)[0]
    rank = jnp.cumsum(free, dtype=jnp.int32) - 1
    born = free & (rank < num_orphans)
    source = jnp.where(born, order[jnp.clip(rank, 0, orphan.shape[0] - 1)], 0)
    return born, source, jnp.maximum(num_orphans - jnp.sum(free, dtype=jnp.int32), 0)


def _birth(z: Float[Array, " m"], params: LowParams, measurement: Measurement):
    """A new track on ``z``: mean ``(z, zero velocity)``, ``P0 = diag((s initial_std)^2)``,
    and its ratio, that of ``H P0 H^T + R``."""
    model = measurement_model(measurement)
    mean = jnp.asarray(model.selection.T, z.dtype) @ z
    scale = track_scale(mean, measurement)
    cov = jnp.diag(scaled_std(params.initial_std, model.state_lengths, scale) ** 2)
    innovation_cov, _ = innovation_covariance(cov, params.measurement_std, scale, measurement)
    return (
        mean,
        cov,
        normalised_ratio(innovation_cov, scale, params.log_steady_sqrt_det, measurement),
    )


def low_step(
    state: LowState,
    params: LowParams,
    measurements: Float[Array, "D m"],
    valid: Bool[Array, " D"],
    strong: Bool[Array, " D"] | None = None,
    log_odds: Float[Array, " D"] | None = None,
    *,
    measurement: Measurement,
) -> tuple[LowState, LowInfo]:
    """One frame of the low level (steps 1-5 of the module docstring).

    Removal is decided only on a frame without measurement, when ``r_k`` has grown past
    ``remove_ratio``: a new track's ratio starts high (its initial covariance) and may exceed
    ``remove_ratio`` while it is being updated. Slots freed on a frame receive births from the
    next frame on, so a slot never holds two tracks in one frame's outputs.

    Args:
        state: the table after the previous frame.
        params: see :class:`LowParams`.
        measurements: ``[D, m]`` in the model's measurement space.
        valid: ``[D]`` which rows are measurements (the rest is padding).
        strong: ``[D]`` measurements that may confirm a track (a detection scoring at
            least the tracker's ``confirm_score``); a track is confirmed only once it has
            held one (``LowState.scored``). None: every measurement (the paper's rule).
        log_odds: ``[D]`` the log-odds that each measurement is a target (from its
            detection score); the association cost falls by twice it. None: 0 (the paper's
            cost).
        measurement: static, ``"box"`` or ``"ellipse"``
            (``jax.jit(functools.partial(low_step, measurement="box"))``).

    Returns:
        The new table and the frame's :class:`LowInfo`.
    """
    measurements = measurements.astype(state.mean.dtype)
    if strong is None:
        strong = jnp.ones_like(valid)
    scale = jax.vmap(track_scale, in_axes=(0, None))(state.mean, measurement)
    means, covs = jax.vmap(low_predict, in_axes=(0, 0, None, 0, None))(
        state.mean, state.cov, params.process_std, scale, measurement
    )
    innovation_covs, _ = jax.vmap(innovation_covariance, in_axes=(0, None, 0, None))(
        covs, params.measurement_std, scale, measurement
    )
    ratio = jax.vmap(normalised_ratio, in_axes=(0, 0, None, None))(
        innovation_covs, scale, params.log_steady_sqrt_det, measurement
    )
    distances = jax.vmap(mahalanobis_square_distances, in_axes=(0, 0, None, None), out_axes=1)(
        means, innovation_covs, measurements, measurement
    )
    gated = valid[:, None] & state.alive[None] & (distances <= params.gate)
    # Nearest in likelihood: the MSD plus the log of |S_k| relative to the steady state
    # (2 log r_k), so that an uncertain new track does not take a confirmed track's
    # measurement only because its gate is wider (MSD alone favours it).
    cost = distances + 2.0 * jnp.log(jnp.maximum(ratio, 1e-6))[None, :]
    if log_odds is not None:
        cost = cost - 2.0 * log_odds.astype(cost.dtype)[:, None]
    track_of, measurement_of = nearest_gated_pairs(cost, gated)
    # Recovery: measurements left over go to confirmed tracks left over, in a wider gate.
    left = (
        valid[:, None]
        & (track_of < 0)[:, None]
        & (state.alive & state.confirmed & (measurement_of < 0))[None]
        & (distances <= params.recovery_gate)
    )
    recovered_track, recovered_measurement = nearest_gated_pairs(cost, left)
    track_of = jnp.where(track_of >= 0, track_of, recovered_track)
    measurement_of = jnp.where(measurement_of >= 0, measurement_of, recovered_measurement)

    hit = measurement_of >= 0
    pair = jnp.maximum(measurement_of, 0)
    updated_means, updated_covs = jax.vmap(low_update, in_axes=(0, 0, 0, None, 0, None))(
        means, covs, measurements[pair], params.measurement_std, scale, measurement
    )
    means = jnp.where(hit[:, None], updated_means, means)
    covs = jnp.where(hit[:, None, None], updated_covs, covs)
    hits = state.hits + hit
    pair_msd = distances[pair, jnp.arange(distances.shape[1])]
    mean_msd = jnp.where(hit, state.msd + (pair_msd - state.msd) / jnp.maximum(hits, 1), state.msd)

    removed = state.alive & ~hit & (ratio > params.remove_ratio)
    scored = state.scored | (hit & strong[pair])
    newly_confirmed = (
        state.alive
        & hit
        & ~state.confirmed
        & scored
        & (ratio <= params.confirm_ratio)
        & (mean_msd <= params.confirm_msd)
    )
    alive = state.alive & ~removed

    born, source, overflow = birth_slots(valid & (track_of < 0), ~state.alive)
    birth_means, birth_covs, birth_ratio = jax.vmap(_birth, in_axes=(0, None, None))(
        measurements[source], params, measurement
    )
    born_rank = jnp.cumsum(born, dtype=jnp.int32) - 1
    free_mean, free_cov = _free_slot(means.shape[1])
    new_state = LowState(
        mean=jnp.where(born[:, None], birth_means, jnp.where(alive[:, None], means, free_mean)),
        cov=jnp.where(
            born[:, None, None], birth_covs, jnp.where(alive[:, None, None], covs, free_cov)
        ),
        alive=alive | born,
        confirmed=(state.confirmed | newly_confirmed) & alive,
        ids=jnp.where(born, state.next_id + born_rank, jnp.where(alive, state.ids, -1)),
        next_id=state.next_id + jnp.sum(born, dtype=jnp.int32),
        age=jnp.where(born, 1, jnp.where(alive, state.age + 1, 0)),
        misses=jnp.where(alive & ~hit, state.misses + 1, 0),
        hits=jnp.where(alive, hits, 0),
        msd=jnp.where(alive, mean_msd, 0.0),
        ratio=jnp.where(born, birth_ratio, jnp.where(alive, ratio, 0.0)),
        scored=jnp.where(born, strong[source], alive & scored),
    )
    slots = jnp.arange(born.shape[0], dtype=jnp.int32)
    born_slot = (
        jnp.full(measurements.shape[0], -1, jnp.int32)
        .at[jnp.where(born, source, measurements.shape[0])]
        .set(slots, mode="drop")
    )
    info = LowInfo(
        assignment=jnp.where(track_of >= 0, track_of, born_slot),
        born=born,
        removed=removed,
        newly_confirmed=newly_confirmed,
        overflow=overflow,
        ratio=new_state.ratio,
        msd=new_state.msd,
    )
    return new_state, info


def low_boxes(state: LowState, measurement: Measurement) -> Float[Array, "T 4"]:
    """Top-left ``(x, y, w, h)`` boxes of every slot's estimate (MOTChallenge convention).

    Free slots hold placeholders: mask with ``state.alive``.
    """
    measured = state.mean @ jnp.asarray(
        measurement_model(measurement).selection.T, state.mean.dtype
    )
    box = ellipse_to_box(measured) if measurement == "ellipse" else measured
    return jnp.concatenate([box[:, :2] - box[:, 2:] / 2, box[:, 2:]], -1)


def low_velocity(state: LowState) -> Float[Array, "T 2"]:
    """Centre velocity ``(vx, vy)`` of every slot, pixels per frame (0 in free slots)."""
    return state.mean[:, jnp.array([1, 3])]
