"""The Kalman data-association tracker against a NumPy loop reference and on crossing targets."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from jaxtrack.filters.base import run
from jaxtrack.filters.kalman import (
    KALMAN_PRESETS,
    MAX_CONFIRM_WINDOW,
    KalmanParams,
    default_kalman_params,
    kalman_filter,
    sort_kalman_params,
)
from tests.filters.phd_scenes import padded_detections, walking_scene

# --- an independent, slow NumPy reference of the whole tracker (one track at a time) -------

_F = np.array(
    [
        [1, 1, 0, 0, 0, 0],
        [0, 1, 0, 0, 0, 0],
        [0, 0, 1, 1, 0, 0],
        [0, 0, 0, 1, 0, 0],
        [0, 0, 0, 0, 1, 0],
        [0, 0, 0, 0, 0, 1],
    ],
    float,
)
_NOISE_INPUT = np.array(
    [[0.5, 0, 0, 0], [1, 0, 0, 0], [0, 0.5, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
)
_H = np.zeros((4, 6))
_H[0, 0] = _H[1, 2] = _H[2, 4] = _H[3, 5] = 1.0


def _relative(std, box_size):
    """Pixels of relative standard deviations ``(s1, s2, sw, sh)`` for a box ``(w, h)``."""
    w, h = box_size
    return np.asarray(std) * np.array([w, h, w, h])


def _iou(a, b):
    """IoU of two top-left ``(x, y, w, h)`` boxes."""
    left, top = max(a[0], b[0]), max(a[1], b[1])
    right, bottom = min(a[0] + a[2], b[0] + b[2]), min(a[1] + a[3], b[1] + b[3])
    inter = max(right - left, 0.0) * max(bottom - top, 0.0)
    return inter / (a[2] * a[3] + b[2] * b[3] - inter)


def _corner_box(mean):
    cx, cy, w, h = _H @ mean
    return np.array([cx - w / 2, cy - h / 2, w, h])


def reference_tracker(params, cost, boxes, scores, mask):
    """Tracks frame by frame with per-track Python loops; returns per-frame track tables.

    Returns:
        For each frame, ``{id: (mean, cov, confirmed)}`` of the live tracks and
        ``{id: box}`` of the output (confirmed tracks detected on that frame).
    """
    p = {name: np.asarray(value, float) for name, value in params._asdict().items()}
    tracks, next_id, history = {}, 1, []
    for t in range(boxes.shape[0]):
        dets = [
            (np.asarray(boxes[t, j], float), float(scores[t, j]))
            for j in range(boxes.shape[1])
            if mask[t, j] and scores[t, j] >= p["min_score"]
        ]
        ids = list(tracks)
        predicted = {}
        for i in ids:
            mean, cov = tracks[i]["mean"], tracks[i]["cov"]
            q = _relative(p["motion_noise_std"], mean[4:])
            predicted[i] = (
                _F @ mean,
                _F @ cov @ _F.T + _NOISE_INPUT @ np.diag(q**2) @ _NOISE_INPUT.T,
            )
        big = 1e9
        pair = np.full((len(ids), len(dets)), big)
        allowed = np.zeros((len(ids), len(dets)), bool)
        for r, i in enumerate(ids):
            mean, cov = predicted[i]
            noise = np.diag(_relative(p["measurement_noise_std"], mean[4:]) ** 2)
            s = _H @ cov @ _H.T + noise
            for c, (box, _) in enumerate(dets):
                z = np.array([box[0] + box[2] / 2, box[1] + box[3] / 2, box[2], box[3]])
                nu = z - _H @ mean
                d2 = nu @ np.linalg.solve(s, nu)
                overlap = _iou(_corner_box(mean), box)
                if d2 <= p["gate"] and overlap >= p["min_iou"]:
                    allowed[r, c] = True
                    pair[r, c] = d2 + np.linalg.slogdet(s)[1] if cost == "likelihood" else -overlap
        matched = {}
        if ids and dets:
            rows, cols = linear_sum_assignment(pair)
            matched = {ids[r]: c for r, c in zip(rows, cols, strict=True) if allowed[r, c]}
        output = {}
        for i in ids:
            mean, cov = predicted[i]
            track = tracks[i]
            if i in matched:
                box, _ = dets[matched[i]]
                z = np.array([box[0] + box[2] / 2, box[1] + box[3] / 2, box[2], box[3]])
                noise = np.diag(_relative(p["measurement_noise_std"], mean[4:]) ** 2)
                s = _H @ cov @ _H.T + noise
                gain = cov @ _H.T @ np.linalg.inv(s)
                mean = mean + gain @ (z - _H @ mean)
                cov = (np.eye(6) - gain @ _H) @ cov
                track["missed"] = 0
            else:
                track["missed"] += 1
            track["mean"], track["cov"] = mean, cov
            track["hits"].append(i in matched)
            window = int(p["confirm_window"])
            track["confirmed"] |= sum(track["hits"][-window:]) >= p["confirm_hits"]
            too_old = not track["confirmed"] and len(track["hits"]) >= window
            if track["missed"] > p["max_missed_frames"] or too_old:
                del tracks[i]
            elif i in matched and track["confirmed"]:
                output[i] = _corner_box(mean)
        taken = set(matched.values())
        for c, (box, _) in enumerate(dets):
            if c in taken:
                continue
            w, h = box[2], box[3]
            mean = np.array([box[0] + w / 2, 0, box[1] + h / 2, 0, w, h])
            r = _relative(p["measurement_noise_std"], (w, h))
            v = p["initial_velocity_std"] * np.array([w, h])
            cov = np.diag([r[0] ** 2, v[0] ** 2, r[1] ** 2, v[1] ** 2, r[2] ** 2, r[3] ** 2])
            confirmed = p["confirm_hits"] <= 1
            tracks[next_id] = {
                "mean": mean,
                "cov": cov,
                "missed": 0,
                "hits": [True],
                "confirmed": confirmed,
            }
            if confirmed:
                output[next_id] = box
            next_id += 1
        table = {i: (k["mean"].copy(), k["cov"].copy(), k["confirmed"]) for i, k in tracks.items()}
        history.append((table, output))
    return history


def random_scenario(seed, num_frames=25, capacity=10):
    """Four well-separated walkers with random misses plus random clutter, shuffled slots."""
    rng = np.random.default_rng(seed)
    starts = np.array([[60.0, 40], [360, 50], [80, 300], [380, 320]]) + rng.uniform(-10, 10, (4, 2))
    velocities = rng.uniform(-3, 3, (4, 2))
    sizes = rng.uniform([30, 80], [50, 120], (4, 2))
    frames, frame_scores = [], []
    for t in range(num_frames):
        frame = []
        for i in range(4):
            if rng.random() < 0.15:
                continue
            xy = starts[i] + velocities[i] * t + rng.normal(0, 2.0, 2)
            frame.append((*xy, *(sizes[i] * rng.uniform(0.95, 1.05, 2))))
        for _ in range(rng.integers(0, 3)):
            frame.append((*rng.uniform(0, 600, 2), *rng.uniform([20, 50], [60, 150])))
        order = rng.permutation(len(frame))
        frames.append([frame[k] for k in order])
        frame_scores.append(rng.uniform(0.5, 1.0, len(frame)))
    detections = padded_detections(frames, capacity)
    scores = np.zeros_like(detections.scores)
    for t, values in enumerate(frame_scores):
        scores[t, : len(values)] = values
    return detections._replace(scores=scores)


@pytest.mark.parametrize("preset", ["default", "sort"])
def test_matches_numpy_reference(preset):
    chosen = KALMAN_PRESETS[preset]
    params = chosen.params()._replace(min_score=jnp.asarray(0.6))
    detections = random_scenario(seed=1 if preset == "default" else 2)
    history = reference_tracker(params, chosen.cost, *detections)
    with jax.enable_x64(True):
        filt = kalman_filter(16, chosen.cost)
        params64 = jax.tree.map(lambda x: jnp.asarray(x, jnp.float64), params)
        dets64 = detections._replace(boxes=np.asarray(detections.boxes, np.float64))
        step = jax.jit(filt.step)
        state = filt.init(jax.random.PRNGKey(0), params64)
        births = deaths = 0
        for t, (table, output) in enumerate(history):
            previous = set(np.asarray(state.table.ids)[np.asarray(state.table.active)].tolist())
            state, info = step(
                jax.random.PRNGKey(t), state, params64, jax.tree.map(lambda x, t=t: x[t], dets64)
            )
            active = np.asarray(state.table.active)
            ids = np.asarray(state.table.ids)
            assert sorted(ids[active].tolist()) == sorted(table), f"frame {t}"
            for slot in np.nonzero(active)[0]:
                mean, cov, confirmed = table[int(ids[slot])]
                np.testing.assert_allclose(state.means[slot], mean, rtol=1e-5, atol=1e-5)
                np.testing.assert_allclose(state.covs[slot], cov, rtol=1e-5, atol=1e-5)
                assert bool(state.table.confirmed[slot]) == confirmed
            out_mask = np.asarray(info.tracks.mask)
            out = dict(
                zip(
                    np.asarray(info.tracks.ids)[out_mask].tolist(),
                    info.tracks.boxes[out_mask],
                    strict=True,
                )
            )
            assert sorted(out) == sorted(output), f"frame {t}"
            for identity, box in out.items():
                np.testing.assert_allclose(box, output[identity], rtol=1e-5, atol=1e-5)
            births += len(set(table) - previous)
            deaths += len(previous - set(table))
    # The scenario exercises births, deletions (of clutter tracks) and confirmed output.
    assert births > 4 and deaths > 0 and sum(len(o) for _, o in history) > 30


def _identities(tracks, truth):
    """Per true target, the identities of the output boxes that overlap it best (IoU > 0.5)."""
    found = [set() for _ in range(truth.shape[1])]
    for t in range(truth.shape[0]):
        for slot in np.nonzero(np.asarray(tracks.mask[t]))[0]:
            overlaps = [_iou(np.asarray(tracks.boxes[t, slot]), box) for box in truth[t]]
            best = int(np.argmax(overlaps))
            if overlaps[best] > 0.5:
                found[best].add(int(tracks.ids[t, slot]))
    return found


@pytest.mark.parametrize(
    ("preset", "hidden"), [("default", {}), ("default", {1: range(18, 22)}), ("sort", {})]
)
def test_crossing_targets_keep_their_identities(preset, hidden):
    """Two walkers cross (boxes overlap fully around frame 20), one possibly occluded."""
    missed = {t: {target} for target, frames in hidden.items() for t in frames}
    detections, truth = walking_scene(
        40, [(100.0, 200.0), (400.0, 215.0)], [(7.5, 0.0), (-7.5, 0.0)], missed=missed, seed=3
    )
    chosen = KALMAN_PRESETS[preset]
    _, info = jax.jit(
        lambda d: run(kalman_filter(8, chosen.cost), jax.random.PRNGKey(0), chosen.params(), d)
    )(detections)
    found = _identities(info.tracks, truth)
    assert [len(ids) for ids in found] == [1, 1] and found[0] != found[1]
    # Both are output on (almost) every frame where they are detected and confirmed.
    assert int(np.sum(info.tracks.mask)) >= 2 * 40 - 2 * 3 - sum(len(f) for f in hidden.values())


def test_sort_preset_confirmation_and_deletion():
    """3 hits confirm; a track survives one missed frame and is deleted after the second."""
    box = (100.0, 100.0, 40.0, 100.0)
    present = [t for t in range(16) if t not in (6, 7, 10)]
    detections = padded_detections([[box] if t in present else [] for t in range(16)], 2)
    _, info = run(kalman_filter(4, "iou"), jax.random.PRNGKey(0), sort_kalman_params(), detections)
    ids = np.where(
        np.asarray(info.tracks.mask).any(axis=1), np.asarray(info.tracks.ids).max(axis=1), 0
    )
    # Frames 0-5: confirmed on its third hit (frame 2). Missed 6 and 7: deleted at 7. Frames
    # 8, 9: track 2, missed at 10, so 2 hits in its first 3 frames: dropped. Frame 11: track
    # 3, confirmed by its third hit at frame 13.
    np.testing.assert_array_equal(ids, [0, 0, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0, 3, 3, 3])
    candidates = np.asarray(info.candidates.mask).any(axis=1)
    np.testing.assert_array_equal(candidates, [t in present for t in range(16)])


def test_vmap_over_params_matches_a_loop():
    detections = random_scenario(seed=4)
    base = default_kalman_params()
    batch = jax.tree.map(lambda *xs: jnp.stack(xs), base, base._replace(min_score=jnp.asarray(0.8)))
    filt = kalman_filter(16)
    batched = jax.jit(jax.vmap(lambda p: run(filt, jax.random.PRNGKey(0), p, detections)[1]))(batch)
    for b, params in enumerate([base, base._replace(min_score=jnp.asarray(0.8))]):
        _, single = run(filt, jax.random.PRNGKey(0), params, detections)
        np.testing.assert_array_equal(batched.tracks.ids[b], single.tracks.ids)
        np.testing.assert_allclose(batched.tracks.boxes[b], single.tracks.boxes, rtol=1e-5)
    assert not np.array_equal(batched.tracks.ids[0], batched.tracks.ids[1])


def test_track_table_overflow_is_reported():
    frames = [[(50.0 * j, 10.0, 30.0, 60.0) for j in range(5)]]
    _, info = run(
        kalman_filter(3),
        jax.random.PRNGKey(0),
        default_kalman_params(),
        padded_detections(frames, 5),
    )
    assert bool(info.track_overflow[0]) and int(np.sum(info.candidates.mask)) == 3


def check_kalman_params(params: KalmanParams) -> None:
    """Raises ValueError when (concrete) ``params`` are out of range."""
    for name in ("motion_noise_std", "measurement_noise_std", "initial_velocity_std"):
        if not bool(jnp.all(getattr(params, name) > 0)):
            raise ValueError(f"{name} must be positive, got {getattr(params, name)}")
    hits, window = float(params.confirm_hits), float(params.confirm_window)
    if not 1 <= hits <= window <= MAX_CONFIRM_WINDOW:
        raise ValueError(
            f"need 1 <= confirm_hits <= confirm_window <= {MAX_CONFIRM_WINDOW}, "
            f"got {hits:g} and {window:g}"
        )
    if not 0 <= float(params.min_iou) < 1:
        raise ValueError(f"min_iou must be in [0, 1), got {float(params.min_iou)}")
    if not float(params.gate) > 0:
        raise ValueError(f"gate must be positive, got {float(params.gate)}")
    if float(params.max_missed_frames) < 0:
        raise ValueError(f"max_missed_frames must be >= 0, got {float(params.max_missed_frames)}")


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"measurement_noise_std": jnp.array([0.1, 0.0, 0.1, 0.1])}, "measurement_noise_std"),
        ({"confirm_hits": jnp.asarray(4.0), "confirm_window": jnp.asarray(3.0)}, "confirm_hits"),
        ({"confirm_window": jnp.asarray(40.0)}, "confirm_window"),
        ({"min_iou": jnp.asarray(1.0)}, "min_iou"),
        ({"gate": jnp.asarray(0.0)}, "gate"),
        ({"max_missed_frames": jnp.asarray(-1.0)}, "max_missed_frames"),
    ],
)
def test_bad_params_are_refused(change, message):
    with pytest.raises(ValueError, match=message):
        check_kalman_params(default_kalman_params()._replace(**change))
    check_kalman_params(sort_kalman_params())


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="max_tracks"):
        kalman_filter(0)
    with pytest.raises(ValueError, match="cost"):
        kalman_filter(8, "euclidean")
