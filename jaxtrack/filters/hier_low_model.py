"""Measurement models and Kalman stages of the Hierarchical low level (pure JAX, float32).

Hierarchical paper, Sec. 4 (SPEC section 4): a bank of Kalman filters on blob measurements.

* ``"box"``: ``z = (cx, cy, w, h)`` (box centre and size), state
  ``x = (cx, vx, cy, vy, w, h)``;
* ``"ellipse"``: ``z = (cx, cy, major, minor, angle)`` (full axes; angle in radians from the
  image x axis to the major axis, period ``pi``), state ``x = (cx, vx, cy, vy, major, minor,
  angle)``.

The centre follows a constant-velocity model with white acceleration noise (the paper's
"constant-speed approach, where the acceleration is modelled as WAGN"); the shape components
follow a random walk: a blob's size and orientation change with the gait, the pose and the
segmentation, none of which a shape velocity would predict (a fitted shape velocity would
extrapolate segmentation noise). The noise scales with the target: with ``s`` the track's
size (box height or ellipse major axis, at the previous estimate) every length component's
standard deviation is ``s`` times a unit-scale one (``Q = s^2 Q0``, ``R = s^2 R0``, ``P0 =
s^2 P00`` on the lengths; the angle's are in radians, unscaled). Then ``|S_k|^1/2 = s^L
|S0_k|^1/2`` with ``L = 4`` length components in both models, and the normalised ratio

    ``r_k = |S_k|^1/2 / (s^L |S0_inf|^1/2)``

(``S0_inf`` the steady-state innovation covariance of the unit-scale model,
:func:`~jaxtrack.filters.hier_low_defaults.steady_state`) is scale free: 1 at the steady
state of consecutive updates, above 1 while the track is uncertain (new or coasting). ``L``
counts lengths only: the SPEC's ``s^m`` would also scale the angle, which has no unit of
length. Every function here handles one track; :func:`~jaxtrack.filters.hier_low.low_step`
vmaps them over the slots.
"""

from __future__ import annotations

from typing import Literal, NamedTuple

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from jaxtrack.errors import InputError
from jaxtrack.linalg import cholesky, solve_lower, solve_spd
from jaxtrack.models.dynamics import MIN_SIZE

#: The measurement models of :func:`~jaxtrack.filters.hier_low.low_step`.
Measurement = Literal["box", "ellipse"]


class MeasurementModel(NamedTuple):
    """The static matrices of one measurement model (NumPy, float64; unit time step).

    Attributes:
        transition: ``F``, ``[n, n]``: constant velocity on the centre, identity on the shape.
        noise_gain: ``G``, ``[n, m]``: ``Q = G diag(q^2) G^T``; the centre's acceleration
            noise enters position and velocity as ``(1/2, 1)``, the shape's random walk as 1.
        selection: ``H``, ``[m, n]``: the measured components of the state.
        state_lengths: ``[n]``, 1 where a state component is a length (scales with ``s``).
        measurement_lengths: ``[m]``, the same for the measurement components.
        scale_index: the state component that is the track's size ``s``.
        angle_index: the measurement component that is an angle (period ``pi``), or None.
    """

    transition: np.ndarray
    noise_gain: np.ndarray
    selection: np.ndarray
    state_lengths: np.ndarray
    measurement_lengths: np.ndarray
    scale_index: int
    angle_index: int | None


def _constant_velocity_model(num_shape: int, scale_shape: int, angle: bool) -> MeasurementModel:
    """Centre ``(cx, vx, cy, vy)`` at constant velocity, then ``num_shape`` random walks."""
    n, m = 4 + num_shape, 2 + num_shape
    transition = np.eye(n)
    transition[0, 1] = transition[2, 3] = 1.0
    gain = np.zeros((n, m))
    gain[0:2, 0] = gain[2:4, 1] = (0.5, 1.0)
    gain[4:, 2:] = np.eye(num_shape)
    selection = np.zeros((m, n))
    selection[np.arange(m), [0, 2, *range(4, n)]] = 1.0
    measurement_lengths = np.ones(m)
    state_lengths = np.ones(n)
    if angle:
        measurement_lengths[-1] = state_lengths[-1] = 0.0
    return MeasurementModel(
        transition=transition,
        noise_gain=gain,
        selection=selection,
        state_lengths=state_lengths,
        measurement_lengths=measurement_lengths,
        scale_index=4 + scale_shape,
        angle_index=m - 1 if angle else None,
    )


MEASUREMENT_MODELS: dict[str, MeasurementModel] = {
    "box": _constant_velocity_model(num_shape=2, scale_shape=1, angle=False),
    "ellipse": _constant_velocity_model(num_shape=3, scale_shape=0, angle=True),
}


def measurement_model(measurement: str) -> MeasurementModel:
    """The :class:`MeasurementModel` named ``measurement`` (``"box"`` or ``"ellipse"``).

    Raises:
        InputError: an unknown name.
    """
    if measurement not in MEASUREMENT_MODELS:
        raise InputError(
            f"measurement must be one of {sorted(MEASUREMENT_MODELS)}, got {measurement!r}"
        )
    return MEASUREMENT_MODELS[measurement]


def wrap_angle(angle: Float[Array, "*batch"]) -> Float[Array, "*batch"]:
    """``angle`` modulo ``pi`` in ``(-pi/2, pi/2]`` (an ellipse's orientation has period pi)."""
    return jnp.pi / 2 - jnp.mod(jnp.pi / 2 - angle, jnp.pi)


def track_scale(mean: Float[Array, " n"], measurement: Measurement) -> Float[Array, ""]:
    """The track size ``s``: box height or ellipse major axis, at least ``MIN_SIZE``."""
    return jnp.maximum(mean[measurement_model(measurement).scale_index], MIN_SIZE)


def scaled_std(std: Float[Array, " k"], lengths: np.ndarray, scale: Float[Array, ""]):
    """``std * s`` on the length components, ``std`` on the others."""
    return std * scale ** jnp.asarray(lengths, std.dtype)


def low_predict(
    mean: Float[Array, " n"],
    cov: Float[Array, "n n"],
    process_std: Float[Array, " m"],
    scale: Float[Array, ""],
    measurement: Measurement,
) -> tuple[Float[Array, " n"], Float[Array, "n n"]]:
    """``x <- F x``, ``P <- F P F^T + G diag(q^2) G^T``, ``q = s * process_std`` on lengths."""
    model = measurement_model(measurement)
    transition = jnp.asarray(model.transition, mean.dtype)
    gain = jnp.asarray(model.noise_gain, mean.dtype)
    std = scaled_std(process_std, model.measurement_lengths, scale)
    return transition @ mean, transition @ cov @ transition.T + (gain * std**2) @ gain.T


def innovation_covariance(
    cov: Float[Array, "n n"],
    measurement_std: Float[Array, " m"],
    scale: Float[Array, ""],
    measurement: Measurement,
) -> tuple[Float[Array, "m m"], Float[Array, "m m"]]:
    """``S = H P H^T + R`` and ``R = diag((s * measurement_std)^2)`` (lengths scaled)."""
    model = measurement_model(measurement)
    selection = jnp.asarray(model.selection, cov.dtype)
    noise = jnp.diag(scaled_std(measurement_std, model.measurement_lengths, scale) ** 2)
    return selection @ cov @ selection.T + noise, noise


def innovation(
    mean: Float[Array, " n"], z: Float[Array, "... m"], measurement: Measurement
) -> Float[Array, "... m"]:
    """``nu = z - H x``, an angle component wrapped to ``(-pi/2, pi/2]``."""
    model = measurement_model(measurement)
    residual = z - jnp.asarray(model.selection, mean.dtype) @ mean
    if model.angle_index is None:
        return residual
    return residual.at[..., model.angle_index].set(wrap_angle(residual[..., model.angle_index]))


def low_update(
    mean: Float[Array, " n"],
    cov: Float[Array, "n n"],
    z: Float[Array, " m"],
    measurement_std: Float[Array, " m"],
    scale: Float[Array, ""],
    measurement: Measurement,
) -> tuple[Float[Array, " n"], Float[Array, "n n"]]:
    """Kalman update, Joseph form: ``K = P H^T S^-1``, ``x <- x + K nu``,
    ``P <- (I - K H) P (I - K H)^T + K R K^T`` (the state's angle wrapped again)."""
    model = measurement_model(measurement)
    selection = jnp.asarray(model.selection, mean.dtype)
    innovation_cov, noise = innovation_covariance(cov, measurement_std, scale, measurement)
    gain = solve_spd(innovation_cov[None], cov @ selection.T)  # rows of P H^T S^-1
    posterior = mean + gain @ innovation(mean, z, measurement)
    if model.angle_index is not None:
        posterior = posterior.at[-1].set(wrap_angle(posterior[-1]))
    reduction = jnp.eye(mean.shape[0], dtype=mean.dtype) - gain @ selection
    posterior_cov = reduction @ cov @ reduction.T + gain @ noise @ gain.T
    return posterior, 0.5 * (posterior_cov + posterior_cov.T)


def normalised_ratio(
    innovation_cov: Float[Array, "m m"],
    scale: Float[Array, ""],
    log_steady_sqrt_det: Float[Array, ""],
    measurement: Measurement,
) -> Float[Array, ""]:
    """``r = |S|^1/2 / (s^L |S0_inf|^1/2)`` (``L`` length components), in log space."""
    lengths = float(measurement_model(measurement).measurement_lengths.sum())
    half_log_det = jnp.sum(jnp.log(jnp.diag(cholesky(innovation_cov))))
    return jnp.exp(half_log_det - lengths * jnp.log(scale) - log_steady_sqrt_det)


def mahalanobis_square_distances(
    mean: Float[Array, " n"],
    innovation_cov: Float[Array, "m m"],
    measurements: Float[Array, "D m"],
    measurement: Measurement,
) -> Float[Array, " D"]:
    """``MSD = nu^T S^-1 nu`` of every measurement against one predicted track."""
    whitened = solve_lower(cholesky(innovation_cov), innovation(mean, measurements, measurement))
    return jnp.sum(whitened**2, axis=-1)


def box_to_ellipse(box: Float[Array, "... 4"]) -> Float[Array, "... 5"]:
    """The ellipse with the second moments of a uniform box ``(cx, cy, w, h)``.

    A side ``a`` has variance ``a^2 / 12``; full axes are ``4 sigma = 2 a / sqrt(3)``. The
    major axis lies along the longer side: angle ``pi/2`` for a tall box, 0 otherwise.
    """
    centre, width, height = box[..., :2], box[..., 2], box[..., 3]
    factor = 2.0 / jnp.sqrt(3.0)
    tall = height > width
    major = factor * jnp.maximum(width, height)
    minor = factor * jnp.minimum(width, height)
    angle = jnp.where(tall, jnp.pi / 2, 0.0).astype(box.dtype)
    return jnp.concatenate([centre, jnp.stack([major, minor, angle], -1)], -1)


def ellipse_to_box(ellipse: Float[Array, "... 5"]) -> Float[Array, "... 4"]:
    """The bounding box ``(cx, cy, w, h)`` of the moment-equivalent rectangle of an ellipse.

    The rectangle has sides ``sqrt(3)/2`` times the full axes, rotated by the angle; its
    bounding box is ``w = |a cos t| + |b sin t|``, ``h = |a sin t| + |b cos t|`` (the inverse
    of :func:`box_to_ellipse` for axis-aligned ellipses).
    """
    factor = jnp.sqrt(3.0) / 2.0
    major, minor, angle = factor * ellipse[..., 2], factor * ellipse[..., 3], ellipse[..., 4]
    cos, sin = jnp.abs(jnp.cos(angle)), jnp.abs(jnp.sin(angle))
    size = jnp.stack([major * cos + minor * sin, major * sin + minor * cos], -1)
    return jnp.concatenate([ellipse[..., :2], size], -1)
