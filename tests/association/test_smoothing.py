"""Fixed-interval (Rauch-Tung-Striebel) smoothing of the offline output."""

from __future__ import annotations

import numpy as np
import pytest

from jaxtrack.association import smoothing
from jaxtrack.association.smoothing import INITIAL_SPEED_STD, smooth_tracks
from jaxtrack.filters.phd_defaults import (
    DEFAULT_MEASUREMENT_NOISE_STD,
    DEFAULT_MOTION_NOISE_STD,
)
from jaxtrack.types import MotTable

Q, R = DEFAULT_MOTION_NOISE_STD, DEFAULT_MEASUREMENT_NOISE_STD


def _oracle_rts(frames, values, transition, noise, measurement_var, first_cov):
    """Textbook Kalman filter + RTS smoother in matrix form (one coordinate of one track).

    ``frames`` (sorted, with gaps), ``values`` the measurements of the state's first
    component there; every frame from the first to the last is a step, measured or not.
    Returns the smoothed first component at ``frames``.
    """
    dim = transition.shape[0]
    steps = np.arange(frames[0], frames[-1] + 1)
    measured = dict(zip(frames.tolist(), values.tolist(), strict=True))
    h = np.zeros((1, dim))
    h[0, 0] = 1.0
    x = np.zeros(dim)
    x[0] = values[0]
    p = first_cov.copy()
    means, covs, predicted_means, predicted_covs = [], [], [], []
    for k, frame in enumerate(steps):
        if k > 0:
            x = transition @ x
            p = transition @ p @ transition.T + noise
        predicted_means.append(x.copy())
        predicted_covs.append(p.copy())
        if k > 0 and int(frame) in measured:
            s = h @ p @ h.T + measurement_var
            gain = p @ h.T @ np.linalg.inv(s)
            x = x + (gain @ (np.array([measured[int(frame)]]) - h @ x)).ravel()
            p = (np.eye(dim) - gain @ h) @ p
        means.append(x.copy())
        covs.append(p.copy())
    smoothed = [None] * len(steps)
    smoothed[-1] = means[-1]
    smoothed_cov = covs[-1]
    for k in range(len(steps) - 2, -1, -1):
        c = covs[k] @ transition.T @ np.linalg.inv(predicted_covs[k + 1])
        smoothed[k] = means[k] + c @ (smoothed[k + 1] - predicted_means[k + 1])
        smoothed_cov = covs[k] + c @ (smoothed_cov - predicted_covs[k + 1]) @ c.T
    index = {int(f): k for k, f in enumerate(steps)}
    return np.array([smoothed[index[int(f)]][0] for f in frames])


def _oracle(rows: MotTable) -> np.ndarray:
    """Every row's smoothed box, from :func:`_oracle_rts` per identity and coordinate."""
    out = np.zeros_like(rows.boxes, dtype=np.float64)
    cv = np.array([[1.0, 1.0], [0.0, 1.0]])
    gain = np.array([[0.5], [1.0]])
    for identity in np.unique(rows.ids):
        own = np.flatnonzero(rows.ids == identity)
        own = own[np.argsort(rows.frames[own])]
        frames, boxes = rows.frames[own], rows.boxes[own].astype(np.float64)
        measured = np.c_[boxes[:, :2] + boxes[:, 2:] / 2, boxes[:, 2:]]
        w, h = np.median(boxes[:, 2]), np.median(boxes[:, 3])
        scale = np.array([w, h, w, h])
        q, r = np.asarray(Q) * scale, np.asarray(R) * scale
        smoothed = np.zeros_like(measured)
        for d in range(2):  # centre: constant velocity
            first_cov = np.diag([r[d] ** 2, (INITIAL_SPEED_STD * scale[d]) ** 2])
            smoothed[:, d] = _oracle_rts(
                frames, measured[:, d], cv, q[d] ** 2 * gain @ gain.T, r[d] ** 2, first_cov
            )
        for d in range(2, 4):  # size: random walk
            smoothed[:, d] = _oracle_rts(
                frames,
                measured[:, d],
                np.eye(1),
                np.array([[q[d] ** 2]]),
                r[d] ** 2,
                np.array([[r[d] ** 2]]),
            )
        out[own] = np.c_[smoothed[:, :2] - smoothed[:, 2:] / 2, smoothed[:, 2:]]
    return out


def _random_rows(seed: int) -> MotTable:
    """Three identities of different lengths, sizes and speeds, with gaps, rows shuffled."""
    rng = np.random.default_rng(seed)
    parts = []
    for identity, (start, length, w, h, speed) in enumerate(
        [(1, 30, 20.0, 50.0, 2.0), (5, 12, 60.0, 120.0, -4.0), (40, 3, 10.0, 25.0, 0.5)],
        start=3,
    ):
        frames = np.arange(start, start + length)
        keep = rng.random(length) > 0.25
        keep[[0, -1]] = True
        frames = frames[keep]
        x = 100 + speed * (frames - start) + rng.normal(0, 0.15 * w, frames.size)
        y = 200 - 0.5 * speed * (frames - start) + rng.normal(0, 0.08 * h, frames.size)
        ws = w + rng.normal(0, 0.1 * w, frames.size)
        hs = h + rng.normal(0, 0.1 * h, frames.size)
        boxes = np.c_[x, y, ws, hs]
        parts.append((frames, np.full(frames.size, identity), boxes))
    frames, ids, boxes = (np.concatenate(column) for column in zip(*parts, strict=True))
    order = rng.permutation(frames.size)
    return MotTable.from_arrays(
        frames[order], ids[order], boxes[order], rng.random(frames.size), None
    )


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("group_cells", [1 << 17, 40])
def test_smoothing_equals_a_matrix_form_rts_smoother(seed, group_cells, monkeypatch):
    # group_cells 40: the identities smoothed in several groups (bounded memory on long runs)
    monkeypatch.setattr(smoothing, "GROUP_CELLS", group_cells)
    rows = _random_rows(seed)
    smoothed = smooth_tracks(rows, Q, R)
    np.testing.assert_allclose(smoothed.boxes, _oracle(rows), rtol=1e-9, atol=1e-7)
    # only the boxes change: same rows, same order, same scores
    np.testing.assert_array_equal(smoothed.frames, rows.frames)
    np.testing.assert_array_equal(smoothed.ids, rows.ids)
    np.testing.assert_array_equal(smoothed.confs, rows.confs)
    assert not np.allclose(smoothed.boxes, rows.boxes)


def test_a_still_box_is_unchanged_and_a_single_row_too():
    frames = np.array([1, 2, 3, 5, 8, 9, 20])
    boxes = np.tile([10.0, 20.0, 30.0, 60.0], (frames.size, 1))
    rows = MotTable.from_arrays(
        np.r_[frames, 4], np.r_[np.ones(frames.size, int), 2], np.r_[boxes, [[1, 2, 3, 4]]]
    )
    smoothed = smooth_tracks(rows, Q, R)
    np.testing.assert_allclose(smoothed.boxes, rows.boxes, atol=1e-9)


def test_smoothing_brings_jittered_boxes_closer_to_the_truth():
    # A synthetic track with known truth: constant velocity, constant size, detections
    # jittered with the measurement noise the model assumes. The smoothed boxes are
    # closer to the truth than the jittered ones (fixed seed; the RMS error falls by more
    # than a third in every coordinate).
    rng = np.random.default_rng(7)
    frames = np.arange(1, 201)
    w, h = 40.0, 100.0
    truth = np.c_[50 + 1.5 * frames, 300 - 0.4 * frames, np.full(200, w), np.full(200, h)]
    noise = rng.normal(size=(200, 4)) * np.asarray(R) * np.array([w, h, w, h])
    rows = MotTable.from_arrays(frames, np.ones(200, int), truth + noise)
    smoothed = smooth_tracks(rows, Q, R)
    before = np.sqrt(np.mean((rows.boxes - truth) ** 2, axis=0))
    after = np.sqrt(np.mean((smoothed.boxes - truth) ** 2, axis=0))
    assert np.all(after < 0.67 * before), (before, after)


def test_empty_rows_are_returned_as_they_are():
    empty = MotTable.from_arrays(np.zeros(0, int), np.zeros(0, int), np.zeros((0, 4)))
    assert len(smooth_tracks(empty, Q, R)) == 0


@pytest.mark.parametrize("tracker", ["phd", "kalman", "cmt", "hierarchical", "fusion"])
def test_online_output_with_smoothing_is_refused_and_the_setting_round_trips(tracker):
    from jaxtrack.errors import InputError
    from jaxtrack.filters.registry import tracker_entry

    config_type = tracker_entry(tracker).config_type
    with pytest.raises(InputError, match="offline"):
        config_type(output="online", smoothing="rts")
    with pytest.raises(InputError, match="smoothing"):
        config_type(smoothing="kalman")
    config = config_type(smoothing="rts")
    assert config_type.from_dict(config.to_dict()) == config
    # off by default, except the Fusion tracker's offline output (session 63)
    assert config_type().smoothing == ("rts" if tracker == "fusion" else "none")
    assert config_type(output="online").smoothing == "none"


def test_kalman_tracker_smooths_under_the_phd_trackers_default_noise(mot15_root):
    """A tracker without SDV noise of its own (the Kalman baseline) is smoothed under the PHD
    tracker's default noise."""
    from jaxtrack.filters.kalman_tracker import KalmanConfig
    from jaxtrack.io import load_sequence
    from jaxtrack.pipelines.tracking import track_sequences

    seq = load_sequence(mot15_root / "TUD-Campus", frames=(1, 40))
    (plain,) = track_sequences([seq], KalmanConfig(), 0)
    (smoothed,) = track_sequences([seq], KalmanConfig(smoothing="rts"), 0)
    expected = smooth_tracks(plain, Q, R)
    np.testing.assert_array_equal(smoothed.ids, plain.ids)
    np.testing.assert_allclose(smoothed.boxes, expected.boxes, rtol=1e-12)
    assert not np.allclose(smoothed.boxes, plain.boxes)


def test_tracker_with_smoothing_smooths_the_plain_output_under_its_noise(mot15_root):
    """TUD-Campus 1:40: ``smoothing="rts"`` gives the plain run's rows with the boxes that
    :func:`smooth_tracks` gives them under the configuration's noise (non-default noise, to
    show which is read), and the smoothed output misses no more boxes than the plain one."""
    from jaxtrack.experiments.common import evaluate_rows
    from jaxtrack.filters.phd_tracker import PHDConfig
    from jaxtrack.io import load_sequence
    from jaxtrack.pipelines.tracking import track_sequences

    seq = load_sequence(mot15_root / "TUD-Campus", frames=(1, 40))
    config = PHDConfig(
        num_particles=512,
        motion_noise_std=(0.06, 0.03, 0.05, 0.04),
        measurement_noise_std=(0.2, 0.1, 0.25, 0.2),
    )
    (plain,) = track_sequences([seq], config, 0)
    (smoothed,) = track_sequences([seq], config.replace(smoothing="rts"), 0)
    expected = smooth_tracks(plain, config.motion_noise_std, config.measurement_noise_std)
    np.testing.assert_array_equal(smoothed.frames, plain.frames)
    np.testing.assert_array_equal(smoothed.ids, plain.ids)
    np.testing.assert_allclose(smoothed.boxes, expected.boxes, rtol=1e-12)
    assert not np.allclose(smoothed.boxes, plain.boxes)
    before, after = evaluate_rows(seq, plain), evaluate_rows(seq, smoothed)
    assert after.summary()["FN"] <= before.summary()["FN"]


def test_birth_run_of_learn_context_ignores_smoothing(mot15_root):
    from jaxtrack.filters.phd_tracker import PHDConfig
    from jaxtrack.io import load_sequence
    from jaxtrack.pipelines.context import uniform_tracker_rows

    seq = load_sequence(mot15_root / "TUD-Campus", frames=(1, 40))
    config = PHDConfig(num_particles=512)
    plain = uniform_tracker_rows(seq, 0, config)
    smoothed = uniform_tracker_rows(seq, 0, config.replace(smoothing="rts"))
    np.testing.assert_array_equal(plain.boxes, smoothed.boxes)
