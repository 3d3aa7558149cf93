"""Fixed-interval smoothing of the offline output: every track's boxes re-estimated with hindsight.

A filter's estimate on frame ``k`` uses the detections up to ``k``; with the whole run in hand,
each box can use the detections after it too. The PHD tracker's estimates follow its
detections' jitter (measurement noise 0.15 of the box width, motion noise 0.05 of it per
frame), so a box may miss its object by more than the CLEAR threshold on one frame and
match it on the next: a false positive and a miss for one jittered box. The
Rauch-Tung-Striebel smoother under the tracker's own dynamics removes that jitter.

The model is the PHD tracker's (:func:`~jaxtrack.models.dynamics.sample_constant_velocity`,
PHD-context Sec. III), per identity and per box dimension, with the SDV noise frozen at the
identity's median width ``w`` and height ``h``:

* centre ``c`` (x and y), constant velocity: ``[c, v]_k = F [c, v]_{k-1} + G n_k``, ``F =
  [[1, 1], [0, 1]]``, ``G = [1/2, 1]``, ``n_k ~ N(0, q^2)``, ``q = sigma_n1 w`` (x) or
  ``sigma_n2 h`` (y);
* width and height, random walks: ``s_k = s_{k-1} + n_k``, ``q = sigma_nw w``, ``sigma_nh h``;
* each output box is a measurement of ``(c_x, c_y, w, h)`` with the tracker's measurement
  noise ``(s_1 w, s_2 h, s_w w, s_h h)``.

The boxes are treated as independent measurements, which they are not (a filter's estimates
are correlated in time and less noisy than a detection): the smoother is the one the
tracker's model implies for its detections, applied to its estimates. The first state is
the first box with zero velocity, the velocity's standard deviation
:data:`INITIAL_SPEED_STD` box sizes per frame. Frames inside a track without a row
are predicted (no measurement). Only the boxes change: every row stays, with its frame,
identity and score.

Host-side post-processing of the offline output (NumPy, float64, vectorised over identities
and dimensions, one pass per frame; identities in groups of bounded size), like the gap
interpolation and retrodiction. The ``smoothing`` setting of every tracker's configuration
turns it on (:func:`jaxtrack.pipelines.tracking.output_rows`,
:func:`jaxtrack.pipelines.sweep.sweep`); trackers without SDV noise of their own (Kalman,
CMT, hierarchical, fusion) are smoothed under the PHD tracker's default noise
(:func:`jaxtrack.pipelines.tracking.smoothing_noise`).
"""

from __future__ import annotations

import numpy as np

from jaxtrack.types import MotTable

#: Most identity x frame cells smoothed at once (about 40 MB of float64 work arrays).
GROUP_CELLS = 1 << 17
#: Standard deviation of a track's first velocity, in box sizes (w or h) per frame: loose,
#: so that the data decide it.
INITIAL_SPEED_STD = 1.0


def smooth_tracks(
    rows: MotTable,
    motion_noise_std: np.ndarray | tuple,
    measurement_noise_std: np.ndarray | tuple,
) -> MotTable:
    """Every identity's boxes replaced by their Rauch-Tung-Striebel smoothed values.

    Args:
        rows: a tracker's (offline) output.
        motion_noise_std: ``(sigma_n1, sigma_n2, sigma_nw, sigma_nh)``, relative to the box
            size (the tracker's ``motion_noise_std``), positive.
        measurement_noise_std: ``(s_1, s_2, s_w, s_h)``, relative to the box size (the
            tracker's ``measurement_noise_std``), positive.

    Returns:
        ``rows`` with the smoothed boxes, in the same order.
    """
    motion = np.asarray(motion_noise_std, np.float64).reshape(4)
    measurement = np.asarray(measurement_noise_std, np.float64).reshape(4)
    if len(rows) == 0:
        return rows
    identities, index = np.unique(rows.ids, return_inverse=True)
    first = np.full(identities.size, np.iinfo(np.int64).max)
    np.minimum.at(first, index, rows.frames)
    last = np.zeros(identities.size, np.int64)
    np.maximum.at(last, index, rows.frames)
    lifetime = last - first + 1
    step = rows.frames - first[index]
    boxes = np.asarray(rows.boxes, np.float64)
    # (c_x, c_y, w, h) per row
    measured = np.c_[boxes[:, :2] + boxes[:, 2:] / 2, boxes[:, 2:]]
    by_identity = np.argsort(index, kind="stable")
    starts = np.searchsorted(index[by_identity], np.arange(identities.size))
    size = np.stack(
        [np.median(boxes[part, 2:], axis=0) for part in np.split(by_identity, starts[1:])]
    )  # [identities, 2]: (w, h)
    smoothed = np.zeros_like(measured)
    for group in _groups(lifetime):
        member = np.full(identities.size, -1)
        member[group] = np.arange(group.size)
        mine = np.flatnonzero(member[index] >= 0)
        slot, at = member[index[mine]], step[mine]
        length = int(lifetime[group].max())
        observed = np.zeros((group.size, length), bool)
        observed[slot, at] = True
        z = np.zeros((group.size, length, 4))
        z[slot, at] = measured[mine]
        scale = np.concatenate([size[group], size[group]], axis=1)  # (w, h, w, h)
        q, r = motion * scale, measurement * scale
        alive = np.arange(length)[None, :] < lifetime[group][:, None]
        centre = _smooth_constant_velocity(
            z[..., :2], observed, alive, q[:, :2], r[:, :2], INITIAL_SPEED_STD * size[group]
        )
        extent = _smooth_random_walk(z[..., 2:], observed, alive, q[:, 2:], r[:, 2:])
        smoothed[mine] = np.concatenate([centre, extent], axis=-1)[slot, at]
    out = np.c_[smoothed[:, :2] - smoothed[:, 2:] / 2, smoothed[:, 2:]]
    return MotTable.from_arrays(rows.frames, rows.ids, out, rows.confs, rows.extra)


def _groups(lifetime: np.ndarray) -> list[np.ndarray]:
    """Identities in groups smoothed together: sorted by lifetime, each group's identities x
    its longest lifetime at most :data:`GROUP_CELLS` (or one identity), so that memory stays
    bounded on long runs with many identities."""
    order = np.argsort(lifetime, kind="stable")
    groups, current = [], []
    for identity in order:
        if current and (len(current) + 1) * lifetime[identity] > GROUP_CELLS:
            groups.append(np.asarray(current))
            current = []
        current.append(identity)
    groups.append(np.asarray(current))
    return groups


def _smooth_constant_velocity(z, observed, alive, q, r, speed_std):
    """RTS smoother of independent constant-velocity coordinates.

    ``z``: ``[n, T, d]`` measurements of the positions, ``observed`` / ``alive``: ``[n, T]``,
    ``q``, ``r``, ``speed_std``: ``[n, d]``. Returns the smoothed positions ``[n, T, d]``.
    """
    n, length, d = z.shape
    # state (position, velocity) and covariance (p00, p01, p11) per [n, d]
    mean = np.zeros((length, n, d, 2))
    cov = np.zeros((length, n, d, 3))
    predicted_mean = np.zeros_like(mean)
    predicted_cov = np.zeros_like(cov)
    q2, r2 = q**2, r**2
    x = np.stack([z[:, 0], np.zeros((n, d))], axis=-1)
    p = np.stack([r2, np.zeros((n, d)), speed_std**2], axis=-1)
    for k in range(length):
        if k > 0:
            x = np.stack([x[..., 0] + x[..., 1], x[..., 1]], axis=-1)
            p00, p01, p11 = p[..., 0], p[..., 1], p[..., 2]
            p = np.stack(
                [
                    p00 + 2 * p01 + p11 + 0.25 * q2,
                    p01 + p11 + 0.5 * q2,
                    p11 + q2,
                ],
                axis=-1,
            )
        predicted_mean[k], predicted_cov[k] = x, p
        if k > 0:
            update = observed[:, k][:, None]
            innovation = z[:, k] - x[..., 0]
            s = p[..., 0] + r2
            gain = np.stack([p[..., 0] / s, p[..., 1] / s], axis=-1)
            updated_x = x + gain * innovation[..., None]
            updated_p = np.stack(
                [
                    p[..., 0] - gain[..., 0] * p[..., 0],
                    p[..., 1] - gain[..., 0] * p[..., 1],
                    p[..., 2] - gain[..., 1] * p[..., 1],
                ],
                axis=-1,
            )
            x = np.where(update[..., None], updated_x, x)
            p = np.where(update[..., None], updated_p, p)
        mean[k], cov[k] = x, p
    smoothed = mean[-1].copy()
    smoothed_cov = cov[-1].copy()
    result = np.zeros((length, n, d))
    result[-1] = smoothed[..., 0]
    for k in range(length - 2, -1, -1):
        # C = P_k F^T (P_{k+1|k})^-1, 2x2 per [n, d]
        p00, p01, p11 = cov[k][..., 0], cov[k][..., 1], cov[k][..., 2]
        a00, a01, a11 = (predicted_cov[k + 1][..., i] for i in range(3))
        det = a00 * a11 - a01 * a01
        i00, i01, i11 = a11 / det, -a01 / det, a00 / det
        # P F^T = [[p00 + p01, p01], [p01 + p11, p11]]
        b00, b01, b10, b11 = p00 + p01, p01, p01 + p11, p11
        c00, c01 = b00 * i00 + b01 * i01, b00 * i01 + b01 * i11
        c10, c11 = b10 * i00 + b11 * i01, b10 * i01 + b11 * i11
        dx = smoothed - predicted_mean[k + 1]
        new = mean[k] + np.stack(
            [c00 * dx[..., 0] + c01 * dx[..., 1], c10 * dx[..., 0] + c11 * dx[..., 1]],
            axis=-1,
        )
        # P_s = P + C (P_s' - P_pred) C^T
        e00 = smoothed_cov[..., 0] - a00
        e01 = smoothed_cov[..., 1] - a01
        e11 = smoothed_cov[..., 2] - a11
        f00, f01 = c00 * e00 + c01 * e01, c00 * e01 + c01 * e11
        f10, f11 = c10 * e00 + c11 * e01, c10 * e01 + c11 * e11
        new_cov = np.stack(
            [
                p00 + f00 * c00 + f01 * c01,
                p01 + f00 * c10 + f01 * c11,
                p11 + f10 * c10 + f11 * c11,
            ],
            axis=-1,
        )
        keep = alive[:, k + 1][:, None, None]
        smoothed = np.where(keep, new, mean[k])
        smoothed_cov = np.where(keep, new_cov, cov[k])
        result[k] = smoothed[..., 0]
    return np.transpose(result, (1, 0, 2))


def _smooth_random_walk(z, observed, alive, q, r):
    """RTS smoother of independent random-walk coordinates (shapes as the constant-velocity
    one's)."""
    n, length, d = z.shape
    mean = np.zeros((length, n, d))
    var = np.zeros((length, n, d))
    q2, r2 = q**2, r**2
    x, p = z[:, 0].copy(), r2.copy()
    for k in range(length):
        if k > 0:
            p = p + q2
            gain = p / (p + r2)
            update = observed[:, k][:, None]
            x = np.where(update, x + gain * (z[:, k] - x), x)
            p = np.where(update, (1 - gain) * p, p)
        mean[k], var[k] = x, p
    result = np.zeros((length, n, d))
    smoothed, smoothed_var = mean[-1].copy(), var[-1].copy()
    result[-1] = smoothed
    for k in range(length - 2, -1, -1):
        predicted = var[k] + q2
        gain = var[k] / predicted
        keep = alive[:, k + 1][:, None]
        smoothed = np.where(keep, mean[k] + gain * (smoothed - mean[k]), mean[k])
        smoothed_var = np.where(keep, var[k] + gain**2 * (smoothed_var - predicted), var[k])
        result[k] = smoothed
    return np.transpose(result, (1, 0, 2))
