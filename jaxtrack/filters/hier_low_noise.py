"""The low level's noise estimated from the sequence's own detections (host-side NumPy).

The low level's default noise (:data:`~jaxtrack.filters.hier_low_defaults.DEFAULT_NOISE`)
was set a priori for background-subtraction blobs of pedestrians: a centre within 3 % of the
box height, a size within 5 %. A detector's boxes scatter far more (a person detector's box
is placed on the person, not fitted to a silhouette), and with the blobs' noise the gate
(99 % chi-square) rejects a target's own detections: the track coasts, dies, and a new one is
born on the target (an identity switch). So the noise is measured on the detections the
tracker will see, without ground truth:

1. **Links.** Detections of consecutive frames are linked when each is the other's best
   match by IoU and the IoU is at least :data:`LINK_IOU`; linked detections form chains.
2. **Second differences.** For every chain position ``t`` with ``k`` links on either side
   (``k = 1 .. K``, :data:`LAGS`), each box component ``z = (cx, cy, w, h)`` gives
   ``d_k = (z_{t+k} - z_t) - (z_t - z_{t-k})``, divided by the box height ``h_t`` (the
   model's noise is relative to the target's size).
3. **Model.** Under the low level's model (constant velocity with white acceleration of
   standard deviation ``a`` on the centre, a random walk of step ``q`` on the size, white
   measurement noise ``r``; :mod:`~jaxtrack.filters.hier_low_model`)
   ``Var d_k = 6 r^2 + c_k p^2`` with ``p`` the component's process noise and
   ``c_k = 2 sum_{j<k} (j + 1/2)^2`` (= 1/2, 5, 17.5) on the centre, ``c_k = 2k`` on the size.
   The variances are measured robustly (``(1.4826 MAD)^2``: a wrong link is an outlier, not
   a variance) and ``(r^2, p^2)`` fitted by non-negative least squares over the lags
   (relative errors weighted alike). The process noise is at least the a priori default:
   the detections' steps cannot tell a small acceleration from measurement noise.
4. **Gate calibration.** Detector boxes have heavy tails (on the MOT15 training detections
   the 99 % quantile of ``|d_1|`` is 1.3-2x a Gaussian's with the same MAD) and their errors
   persist over frames, so a Gaussian fitted to the core rejects a target's own detections at
   the 99 % gate. Every standard deviation is multiplied by the factor ``f >= 1`` that puts
   the gate's quantile of the lag-1 differences' Mahalanobis square distances (under the
   fitted model) at the gate's chi-square quantile (:func:`gate_calibration`). On Gaussian
   detections (the synthetic scenes) ``f`` is 1.0; on the MOT15 detections 1.4-2.1.
5. **Initial state.** A new track's position and size: the measurement's ``r``; its
   velocity: the spread of the targets' velocities, i.e. the robust variance of the chains'
   per-frame centre displacements less their measurement part ``2 r^2``, at least the a
   priori default. Every initial standard deviation is at least 1.5 times the steady
   state's (after an update): a new track is less certain than a settled one, which the
   low level's confirmation by a falling ``|S_k|^1/2`` needs.

Fewer than :data:`MIN_SAMPLES` chain positions at some lag (a short span, sparse
detections, fast motion at a low frame rate) leave the defaults in place. Estimates are kept
within ``[MIN_STD, MAX_STD]`` (relative to the box height). Only the ``"box"`` measurement is
estimated; the ``"ellipse"`` model keeps its defaults.

Development (the choice of this method over the defaults, over an estimate without the
calibration and over fixed inflations) used the 8 MOT15 training sequences without video and
the synthetic video scenes of seeds 0-2; the three MOT15 videos and the scenes of seeds
101-103 are held out (``experiments/hierarchical.py``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.optimize import nnls
from scipy.stats import chi2, norm

from jaxtrack.boxes import iou_matrix, xywh_to_cxcywh
from jaxtrack.filters.hier_low_defaults import GATE_CONFIDENCE, steady_state

#: Smallest IoU of a link between detections of consecutive frames.
LINK_IOU = 0.5
#: The lags ``k`` of the second differences.
LAGS = (1, 2, 3)
#: Chain positions needed at every lag to estimate (else the defaults).
MIN_SAMPLES = 50
#: Bounds of an estimated standard deviation, relative to the box height.
MIN_STD = 0.005
MAX_STD = 0.5
#: A new track's standard deviations are at least this times the steady state's.
SETTLED_MARGIN = 1.5
#: The median absolute deviation of the standard normal (the MAD's consistency constant is
#: its inverse, 1.4826).
NORMAL_MAD = norm.ppf(0.75)


class BoxNoise(NamedTuple):
    """Unit-scale noise of the ``"box"`` low level (lengths relative to the box height).

    Attributes:
        process_std: ``(a_x, a_y, q_w, q_h)``: the centre's acceleration and the size's
            random-walk step per frame.
        measurement_std: ``(r_cx, r_cy, r_w, r_h)``.
        initial_std: ``(cx, vx, cy, vy, w, h)`` of a new track.
        samples: chain positions used at each lag (0 when the defaults were kept).
        calibration: the gate calibration's factor on the fitted standard deviations
            (:func:`gate_calibration`; 1 when the defaults were kept).
    """

    process_std: tuple[float, ...]
    measurement_std: tuple[float, ...]
    initial_std: tuple[float, ...]
    samples: tuple[int, ...]
    calibration: float


def link_chains(boxes: np.ndarray, mask: np.ndarray, min_iou: float = LINK_IOU) -> np.ndarray:
    """``next[t, i]``: the detection of frame ``t + 1`` linked to detection ``i`` of frame
    ``t`` (mutual best IoU, at least ``min_iou``), -1 when none (and on the last frame)."""
    num_frames, slots = mask.shape
    nxt = np.full((num_frames, slots), -1, np.int64)
    for t in range(num_frames - 1):
        a, b = np.flatnonzero(mask[t]), np.flatnonzero(mask[t + 1])
        if a.size == 0 or b.size == 0:
            continue
        iou = iou_matrix(boxes[t, a], boxes[t + 1, b])
        best_b, best_a = iou.argmax(1), iou.argmax(0)
        for i, j in enumerate(best_b):
            if best_a[j] == i and iou[i, j] >= min_iou:
                nxt[t, a[i]] = b[j]
    return nxt


def second_differences(
    boxes: np.ndarray, mask: np.ndarray, lags=LAGS, min_iou: float = LINK_IOU
) -> tuple[dict[int, np.ndarray], np.ndarray]:
    """The chains' relative second differences per lag (``[samples, 4]`` each) and their
    per-frame relative centre displacements (``[samples, 2]``).

    Args:
        boxes: ``[F, D, 4]`` ``(x, y, w, h)`` padded detections.
        mask: ``[F, D]`` real slots.
        lags: the lags ``k``.
        min_iou: smallest IoU of a link.
    """
    boxes, mask = np.asarray(boxes, np.float64), np.asarray(mask, bool)
    z = xywh_to_cxcywh(boxes)
    nxt = link_chains(boxes, mask, min_iou)
    num_frames, slots = mask.shape
    prev = np.full_like(nxt, -1)
    t_idx, i_idx = np.nonzero(nxt >= 0)
    prev[t_idx + 1, nxt[t_idx, i_idx]] = i_idx
    out = {}
    for k in lags:
        rows = []
        for t in range(k, num_frames - k):
            fwd = np.where(mask[t], np.arange(slots), -1)
            back = fwd.copy()
            for step in range(k):
                fwd = np.where(fwd >= 0, nxt[t + step, np.clip(fwd, 0, None)], -1)
                back = np.where(back >= 0, prev[t - step, np.clip(back, 0, None)], -1)
            ok = (fwd >= 0) & (back >= 0)
            if not ok.any():
                continue
            here = z[t, ok]
            diff = (z[t + k, fwd[ok]] - here) - (here - z[t - k, back[ok]])
            rows.append(diff / np.maximum(here[:, 3:4], 1.0))
        out[k] = np.concatenate(rows) if rows else np.zeros((0, 4))
    here = z[t_idx, i_idx]
    steps = (z[t_idx + 1, nxt[t_idx, i_idx]] - here)[:, :2] / np.maximum(here[:, 3:4], 1.0)
    return out, steps


def robust_var(x: np.ndarray, axis: int = 0) -> np.ndarray:
    """``(1.4826 MAD)^2`` along ``axis`` (the variance of Gaussian data, outliers ignored)."""
    med = np.median(x, axis=axis, keepdims=True)
    return (np.median(np.abs(x - med), axis=axis) / NORMAL_MAD) ** 2


def process_coefficients(k: int) -> np.ndarray:
    """``c_k`` of ``(cx, cy, w, h)``: the variance of a lag-``k`` second difference per unit
    process variance (white acceleration on the centre, random walk on the size)."""
    centre = 2.0 * sum((j + 0.5) ** 2 for j in range(k))
    return np.array([centre, centre, 2.0 * k, 2.0 * k])


def estimate_box_noise(
    boxes: np.ndarray,
    mask: np.ndarray,
    default: tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]],
    gate_confidence: float = GATE_CONFIDENCE,
    lags=LAGS,
    min_samples: int = MIN_SAMPLES,
) -> BoxNoise:
    """The ``"box"`` low level's unit-scale noise measured on padded detections (module
    docstring).

    Args:
        boxes: ``[F, D, 4]`` ``(x, y, w, h)`` padded detections.
        mask: ``[F, D]`` real slots.
        default: ``(process_std, measurement_std, initial_std)`` a priori: kept when the
            detections are too few; its process noise and initial velocity are floors.
        gate_confidence: the low level's gate probability (the calibration's quantile).
        lags: the lags ``k`` of the second differences.
        min_samples: chain positions needed at every lag.
    """
    diffs, steps = second_differences(boxes, mask, lags)
    counts = tuple(int(diffs[k].shape[0]) for k in lags)
    process, measurement, initial = (np.asarray(v, np.float64) for v in default)
    if min(counts) < min_samples:
        return BoxNoise(
            tuple(map(float, process)),
            tuple(map(float, measurement)),
            tuple(map(float, initial)),
            (0,) * len(lags),
            1.0,
        )
    variances = np.stack([robust_var(diffs[k]) for k in lags])  # [K, 4]
    coefficients = np.stack([process_coefficients(k) for k in lags])
    measurement_var, process_var = np.zeros(4), np.zeros(4)
    for c in range(4):
        weight = 1.0 / np.maximum(variances[:, c], 1e-12)  # relative errors
        design = np.stack([np.full(len(lags), 6.0), coefficients[:, c]], axis=1)
        (measurement_var[c], process_var[c]), _ = nnls(
            design * weight[:, None], variances[:, c] * weight
        )
    measurement_var = np.clip(measurement_var, MIN_STD**2, MAX_STD**2)
    process_var = np.clip(np.maximum(process_var, process**2), MIN_STD**2, MAX_STD**2)
    factor = gate_calibration(
        diffs[lags[0]], 6.0 * measurement_var + coefficients[0] * process_var, gate_confidence
    )
    measurement_std = np.clip(factor * np.sqrt(measurement_var), MIN_STD, MAX_STD)
    process_std = np.clip(factor * np.sqrt(process_var), MIN_STD, MAX_STD)
    spread = robust_var(steps) - 2.0 * np.square(measurement_std[:2])  # less the noise
    velocity = np.clip(np.sqrt(np.maximum(spread, 0.0)), initial[[1, 3]], MAX_STD)
    initial_std = np.array(
        [measurement_std[0], velocity[0], measurement_std[1], velocity[1], *measurement_std[2:]]
    )
    # A new track is at least as uncertain as a settled one (else |S_k| would not fall while
    # it is updated, and no ratio threshold could confirm it).
    settled, _ = steady_state("box", process_std, measurement_std)
    initial_std = np.maximum(initial_std, np.sqrt(np.diag(settled)) * SETTLED_MARGIN)
    return BoxNoise(
        tuple(map(float, process_std)),
        tuple(map(float, measurement_std)),
        tuple(map(float, initial_std)),
        counts,
        float(factor),
    )


def gate_calibration(
    diffs: np.ndarray, variance: np.ndarray, gate_confidence: float = GATE_CONFIDENCE
) -> float:
    """The factor ``f`` on every standard deviation that puts the ``gate_confidence``
    quantile of the second differences' Mahalanobis square distances
    ``D_i = sum_c d_ic^2 / (f^2 variance_c)`` at the chi-square gate (``m = 4`` dof): the
    gate then holds the share of the detections' steps it claims to. ``f`` is at least 1
    (the fit's spread is not shrunk)."""
    distances = np.sum(diffs**2 / variance, axis=1)
    ratio = np.quantile(distances, gate_confidence) / chi2.ppf(gate_confidence, diffs.shape[1])
    return float(max(np.sqrt(ratio), 1.0))
