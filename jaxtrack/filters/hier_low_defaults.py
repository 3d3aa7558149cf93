"""Thresholds of the low level derived from its model's steady state (host-side NumPy).

The Hierarchical paper (Sec. 4) confirms a track "when ``|S_k|^1/2`` and the MSD value
indicate that the track is stable" and removes it "if ``|S_k|^1/2`` grows far beyond
reasonable values": ``|S_k|^1/2`` "is a reliable indicator of how many observations have been
consecutively associated", "the time taken depends only on the system model". This module
turns that remark into numbers for the unit-scale model of :mod:`~jaxtrack.filters.hier_low`
(``s = 1``; the ratio ``r_k`` is scale free):

* **steady state**: iterate the Riccati recursion ``P <- F (P - P H^T S^-1 H P) F^T + Q``,
  ``S = H P H^T + R``, to convergence; ``S0_inf`` gives ``log_steady_sqrt_det =
  log |S0_inf|^1/2``;
* **confirm_ratio**: a track born with ``P0 = diag(initial_std^2)`` and updated on each of
  the next frames has ratios ``c_1 > c_2 > ...`` (``c_j`` on the frame of its ``j``-th
  update, from the prediction after ``j - 1`` updates). With ``U = confirm_updates`` the
  threshold is ``sqrt(c_{U-1} c_U)``: the ``U``-th consecutive update confirms (the
  geometric midpoint keeps float32 rounding from moving the decision by a frame);
* **remove_ratio**: from the steady state (after an update), a track with no measurement has
  ratios ``g_1 = 1 < g_2 < ...`` on its 1st, 2nd, ... missed frame (``g_j`` after ``j``
  predictions). With ``C = coast_frames`` the threshold is ``sqrt(g_C g_{C+1})``: a settled
  track coasts through ``C`` missed frames and is removed on the next one (a track that was
  not settled is less certain and goes sooner). The default ``C = 12`` is half a second at
  25 fps: it bridges a blob lost for a few frames (a thin occluder, a segmentation drop-out)
  while a pedestrian's constant-velocity prediction is still within about a body width of
  where they walk; at another frame rate scale it (e.g. 4 at PETS09's 7 fps);
* **confirm_msd**: the track's mean MSD over its ``hits`` updates. Under the model each MSD
  is chi-square with ``m`` dof and independent of the others, so the mean of ``U`` of them is
  ``chi2(U m) / U``; the threshold is its ``msd_confidence`` quantile;
* **gate**: the ``gate_confidence`` quantile of chi-square with ``m`` dof (the paper's
  Mahalanobis radius of the gate's confidence interval);
* **recovery_gate**: the ``recovery_confidence`` quantile (99.99 %), within which a confirmed
  track that took no measurement takes one no track took (:mod:`~jaxtrack.filters.hier_low`,
  step 3's recovery); ``recovery_confidence = gate_confidence`` turns the recovery off.

Default noise (unit scale, relative to the box height or the ellipse's major axis; chosen a
priori for pedestrians in background-subtraction blobs, not tuned): acceleration 0.01 s per
frame^2, shape random walk 0.01 s per frame (angle 0.05 rad), measurement noise 0.03 s on the
centre and 0.05 s on the axes (angle 0.1 rad), a new track's velocity 0.05 s per frame.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from scipy.stats import chi2

from jaxtrack.errors import InputError
from jaxtrack.filters.hier_low import LowParams
from jaxtrack.filters.hier_low_model import Measurement, MeasurementModel, measurement_model

#: Unit-scale ``(process_std, measurement_std, initial_std)`` of each measurement model.
DEFAULT_NOISE: dict[str, tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]] = {
    "box": (
        (0.01, 0.01, 0.01, 0.01),
        (0.03, 0.03, 0.05, 0.05),
        (0.03, 0.05, 0.03, 0.05, 0.05, 0.05),
    ),
    "ellipse": (
        (0.01, 0.01, 0.01, 0.01, 0.05),
        (0.03, 0.03, 0.05, 0.05, 0.1),
        (0.03, 0.05, 0.03, 0.05, 0.05, 0.05, 0.1),
    ),
}
#: Default probability mass of the validation gate (``gate_confidence``).
GATE_CONFIDENCE = 0.99
#: Default probability mass of the recovery gate (``recovery_confidence``): a measurement no
#: track took is offered to a confirmed track that took none within this wider gate.
RECOVERY_CONFIDENCE = 0.9999
#: Riccati iterations of :func:`steady_state` (converged to float64 precision long before).
RICCATI_ITERATIONS = 2000


def _matrices(model: MeasurementModel, process_std, measurement_std):
    """``F, Q, H, R`` of the unit-scale model (float64)."""
    gain = model.noise_gain
    process = gain @ np.diag(np.square(process_std)) @ gain.T
    return model.transition, process, model.selection, np.diag(np.square(measurement_std))


def _predict(cov, transition, process):
    return transition @ cov @ transition.T + process


def _update(cov, selection, noise):
    innovation_cov = selection @ cov @ selection.T + noise
    gain = np.linalg.solve(innovation_cov, selection @ cov).T
    reduction = np.eye(cov.shape[0]) - gain @ selection
    return reduction @ cov @ reduction.T + gain @ noise @ gain.T


def _sqrt_det(cov, selection, noise) -> float:
    return float(np.sqrt(np.linalg.det(selection @ cov @ selection.T + noise)))


def steady_state(
    measurement: Measurement, process_std, measurement_std
) -> tuple[np.ndarray, np.ndarray]:
    """The unit-scale model's steady-state posterior covariance and innovation covariance.

    Returns:
        ``P_inf`` (after an update) and ``S0_inf = H (F P_inf F^T + Q) H^T + R``.
    """
    transition, process, selection, noise = _matrices(
        measurement_model(measurement), process_std, measurement_std
    )
    cov = np.eye(transition.shape[0])
    for _ in range(RICCATI_ITERATIONS):
        cov = _update(_predict(cov, transition, process), selection, noise)
    predicted = _predict(cov, transition, process)
    return cov, selection @ predicted @ selection.T + noise


def ratio_sequences(
    measurement: Measurement,
    process_std,
    measurement_std,
    initial_std,
    count: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Unit-scale ratios ``c_1..c_count`` (consecutive updates from the birth) and
    ``g_1..g_count`` (consecutive misses from the steady state); see the module docstring."""
    transition, process, selection, noise = _matrices(
        measurement_model(measurement), process_std, measurement_std
    )
    steady, steady_innovation = steady_state(measurement, process_std, measurement_std)
    norm = float(np.sqrt(np.linalg.det(steady_innovation)))
    updating, coasting = np.diag(np.square(initial_std)), steady
    confirm, remove = [], []
    for _ in range(count):
        updating = _predict(updating, transition, process)
        coasting = _predict(coasting, transition, process)
        confirm.append(_sqrt_det(updating, selection, noise) / norm)
        remove.append(_sqrt_det(coasting, selection, noise) / norm)
        updating = _update(updating, selection, noise)
    return np.array(confirm), np.array(remove)


def low_params(
    measurement: Measurement,
    process_std,
    measurement_std,
    initial_std,
    *,
    confirm_updates: int = 4,
    coast_frames: int = 12,
    gate_confidence: float = GATE_CONFIDENCE,
    msd_confidence: float = 0.99,
    recovery_confidence: float = RECOVERY_CONFIDENCE,
) -> LowParams:
    """:class:`~jaxtrack.filters.hier_low.LowParams` with thresholds derived from the noise.

    Args:
        measurement: ``"box"`` or ``"ellipse"``.
        process_std: ``[m]`` unit-scale process noise.
        measurement_std: ``[m]`` unit-scale measurement noise.
        initial_std: ``[n]`` unit-scale initial state standard deviation.
        confirm_updates: ``U >= 2``: a track updated on each frame after its birth is
            confirmed on its ``U``-th update (given a small mean MSD).
        coast_frames: ``C >= 1``: a settled track is removed on its ``C + 1``-th consecutive
            frame without measurement.
        gate_confidence: probability mass of the validation gate, in (0, 1).
        msd_confidence: quantile of the mean MSD of ``U`` updates that still confirms.
        recovery_confidence: probability mass of the recovery gate, in
            ``[gate_confidence, 1)``.

    Raises:
        InputError: a count or probability out of range (``recovery_confidence`` below
            ``gate_confidence``), a noise vector of the wrong length
            or not positive, or ratios that do not fall while updating (an initial
            covariance below the steady state), so that no ratio threshold confirms on the
            ``U``-th update.
    """
    model = measurement_model(measurement)
    m, n = model.selection.shape
    if confirm_updates < 2:
        raise InputError(f"confirm_updates must be at least 2, got {confirm_updates}")
    if coast_frames < 1:
        raise InputError(f"coast_frames must be positive, got {coast_frames}")
    for name, value in (
        ("gate_confidence", gate_confidence),
        ("msd_confidence", msd_confidence),
        ("recovery_confidence", recovery_confidence),
    ):
        if not 0.0 < value < 1.0:
            raise InputError(f"{name} must be in (0, 1), got {value}")
    if recovery_confidence < gate_confidence:
        raise InputError(
            f"recovery_confidence ({recovery_confidence}) must be at least gate_confidence "
            f"({gate_confidence})"
        )
    stds = {"process_std": process_std, "measurement_std": measurement_std}
    for name, value, size in (
        *((k, v, m) for k, v in stds.items()),
        ("initial_std", initial_std, n),
    ):
        array = np.asarray(value, float)
        if array.shape != (size,) or not np.all(array > 0):
            raise InputError(f"{name} must hold {size} positive numbers, got {value}")
    confirm, remove = ratio_sequences(
        measurement,
        process_std,
        measurement_std,
        initial_std,
        max(confirm_updates, coast_frames + 1),
    )
    if not np.all(np.diff(confirm[:confirm_updates]) < 0):
        raise InputError(
            f"initial_std gives ratios {np.round(confirm[:confirm_updates], 4).tolist()} that do "
            "not fall with consecutive updates; raise it above the steady state"
        )
    _, steady_innovation = steady_state(measurement, process_std, measurement_std)
    u, c = confirm_updates, coast_frames
    return LowParams(
        process_std=jnp.asarray(process_std, jnp.float32),
        measurement_std=jnp.asarray(measurement_std, jnp.float32),
        initial_std=jnp.asarray(initial_std, jnp.float32),
        gate=jnp.asarray(chi2.ppf(gate_confidence, m), jnp.float32),
        recovery_gate=jnp.asarray(chi2.ppf(recovery_confidence, m), jnp.float32),
        log_steady_sqrt_det=jnp.asarray(0.5 * np.linalg.slogdet(steady_innovation)[1], jnp.float32),
        confirm_ratio=jnp.asarray(np.sqrt(confirm[u - 2] * confirm[u - 1]), jnp.float32),
        confirm_msd=jnp.asarray(chi2.ppf(msd_confidence, u * m) / u, jnp.float32),
        remove_ratio=jnp.asarray(np.sqrt(remove[c - 1] * remove[c]), jnp.float32),
    )


def default_low_params(
    measurement: Measurement = "box",
    *,
    confirm_updates: int = 4,
    coast_frames: int = 12,
    gate_confidence: float = GATE_CONFIDENCE,
    msd_confidence: float = 0.99,
    recovery_confidence: float = RECOVERY_CONFIDENCE,
) -> LowParams:
    """:func:`low_params` with the default pedestrian noise :data:`DEFAULT_NOISE`."""
    measurement_model(measurement)  # an unknown name is an InputError, not a KeyError
    process_std, measurement_std, initial_std = DEFAULT_NOISE[measurement]
    return low_params(
        measurement,
        process_std,
        measurement_std,
        initial_std,
        confirm_updates=confirm_updates,
        coast_frames=coast_frames,
        gate_confidence=gate_confidence,
        msd_confidence=msd_confidence,
        recovery_confidence=recovery_confidence,
    )
