"""The Hierarchical low level against a NumPy loop reference, its steady state and known scenes."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg

from jaxtrack.errors import InputError
from jaxtrack.filters.hier_low import LowState, init_low, low_boxes, low_step, low_velocity
from jaxtrack.filters.hier_low_defaults import (
    DEFAULT_NOISE,
    default_low_params,
    low_params,
    ratio_sequences,
    steady_state,
)
from jaxtrack.filters.hier_low_model import (
    box_to_ellipse,
    ellipse_to_box,
    innovation_covariance,
    low_predict,
    mahalanobis_square_distances,
    track_scale,
    wrap_angle,
)

MODELS = ("box", "ellipse")

# --- an independent NumPy reference of one step, one track and one pair at a time ---------


def _reference_model(measurement):
    """``F, G, H``, length flags of the measurement and the state, the size's state index."""
    if measurement == "box":
        n, shape, scale_index = 6, 2, 5
        lengths_m, lengths_n = np.ones(4), np.ones(6)
    else:
        n, shape, scale_index = 7, 3, 4
        lengths_m, lengths_n = np.array([1, 1, 1, 1, 0.0]), np.array([1, 1, 1, 1, 1, 1, 0.0])
    transition = np.eye(n)
    transition[0, 1] = transition[2, 3] = 1
    gain = np.zeros((n, 2 + shape))
    gain[0, 0], gain[1, 0], gain[2, 1], gain[3, 1] = 0.5, 1, 0.5, 1
    for i in range(shape):
        gain[4 + i, 2 + i] = 1
    selection = np.zeros((2 + shape, n))
    for row, col in enumerate([0, 2, *range(4, n)]):
        selection[row, col] = 1
    return transition, gain, selection, lengths_m, lengths_n, scale_index


def _wrap(residual, measurement):
    residual = residual.copy()
    if measurement == "ellipse":
        while residual[-1] > np.pi / 2:
            residual[-1] -= np.pi
        while residual[-1] <= -np.pi / 2:
            residual[-1] += np.pi
    return residual


def reference_step(state, params, measurements, valid, measurement, recovered=None):
    """One frame with Python loops in float64; ``state`` is a dict of NumPy arrays;
    ``recovered[0]`` counts the recovery pass's pairs."""
    recovered = [0] if recovered is None else recovered
    F, G, H, len_m, len_n, scale_index = _reference_model(measurement)
    p = {k: np.asarray(v, float) for k, v in params._asdict().items()}
    num_tracks, num_meas = len(state["alive"]), len(measurements)
    norm = np.exp(p["log_steady_sqrt_det"])
    means, covs, noises, innovations, ratios, scales = [], [], [], [], [], []
    for t in range(num_tracks):
        s = max(state["mean"][t][scale_index], 1.0)
        q = p["process_std"] * s**len_m
        mean = F @ state["mean"][t]
        cov = F @ state["cov"][t] @ F.T + G @ np.diag(q**2) @ G.T
        noise = np.diag((p["measurement_std"] * s**len_m) ** 2)
        innovation_cov = H @ cov @ H.T + noise
        means.append(mean), covs.append(cov), noises.append(noise), scales.append(s)
        innovations.append(innovation_cov)
        ratios.append(np.sqrt(np.linalg.det(innovation_cov)) / (s**4 * norm))
    msd = np.zeros((num_meas, num_tracks))
    pairs = []
    for j in range(num_meas):
        for t in range(num_tracks):
            nu = _wrap(measurements[j] - H @ means[t], measurement)
            msd[j, t] = nu @ np.linalg.solve(innovations[t], nu)
            if valid[j] and state["alive"][t] and msd[j, t] <= p["gate"]:
                pairs.append((msd[j, t] + 2 * np.log(ratios[t]), j, t))
    track_of, meas_of = [-1] * num_meas, [-1] * num_tracks
    for _, j, t in sorted(pairs):
        if track_of[j] < 0 and meas_of[t] < 0:
            track_of[j], meas_of[t] = t, j
    # Recovery: left-over measurements, left-over confirmed tracks, the wider gate.
    recovery = [
        (msd[j, t] + 2 * np.log(ratios[t]), j, t)
        for j in range(num_meas)
        for t in range(num_tracks)
        if valid[j]
        and track_of[j] < 0
        and state["alive"][t]
        and state["confirmed"][t]
        and meas_of[t] < 0
        and msd[j, t] <= p["recovery_gate"]
    ]
    for _, j, t in sorted(recovery):
        if track_of[j] < 0 and meas_of[t] < 0:
            track_of[j], meas_of[t] = t, j
            recovered[0] += 1
    new = {k: np.array(v, copy=True) for k, v in state.items()}
    info = {
        "born": np.zeros(num_tracks, bool),
        "removed": np.zeros(num_tracks, bool),
        "newly_confirmed": np.zeros(num_tracks, bool),
    }
    for t in range(num_tracks):
        if not state["alive"][t]:
            continue
        hit = meas_of[t] >= 0
        mean, cov = means[t], covs[t]
        if hit:
            j = meas_of[t]
            gain = cov @ H.T @ np.linalg.inv(innovations[t])
            mean = mean + gain @ _wrap(measurements[j] - H @ mean, measurement)
            if measurement == "ellipse":
                mean[-1] = _wrap(np.array([mean[-1]]), measurement)[0]
            reduction = np.eye(len(mean)) - gain @ H
            cov = reduction @ cov @ reduction.T + gain @ noises[t] @ gain.T
            new["hits"][t] += 1
            new["msd"][t] += (msd[j, t] - state["msd"][t]) / new["hits"][t]
            if (
                not state["confirmed"][t]
                and ratios[t] <= p["confirm_ratio"]
                and new["msd"][t] <= p["confirm_msd"]
            ):
                new["confirmed"][t] = info["newly_confirmed"][t] = True
            new["misses"][t] = 0
        else:
            new["misses"][t] += 1
            if ratios[t] > p["remove_ratio"]:
                info["removed"][t] = True
        new["mean"][t], new["cov"][t], new["ratio"][t] = mean, cov, ratios[t]
        new["age"][t] += 1
        if info["removed"][t]:
            new["alive"][t] = new["confirmed"][t] = False
            new["ids"][t], new["age"][t], new["misses"][t], new["hits"][t] = -1, 0, 0, 0
            new["msd"][t] = new["ratio"][t] = 0.0
            new["mean"][t], new["cov"][t] = np.zeros(len(mean)), np.eye(len(mean))
    free = [t for t in range(num_tracks) if not state["alive"][t]]
    orphans = [j for j in range(num_meas) if valid[j] and track_of[j] < 0]
    assignment = list(track_of)
    for t, j in zip(free, orphans, strict=False):
        z = measurements[j]
        mean = H.T @ z
        s = max(mean[scale_index], 1.0)
        cov = np.diag((p["initial_std"] * s**len_n) ** 2)
        noise = np.diag((p["measurement_std"] * s**len_m) ** 2)
        new["mean"][t], new["cov"][t], new["alive"][t], new["confirmed"][t] = mean, cov, 1, 0
        new["ids"][t], new["age"][t], new["misses"][t], new["hits"][t] = new["next_id"], 1, 0, 0
        new["next_id"] += 1
        new["msd"][t] = 0.0
        new["ratio"][t] = np.sqrt(np.linalg.det(H @ cov @ H.T + noise)) / (s**4 * norm)
        info["born"][t] = True
        assignment[j] = t
    info["assignment"] = np.array(assignment)
    info["overflow"] = max(len(orphans) - len(free), 0)
    return new, info


def _numpy_state(state: LowState) -> dict:
    return {
        k: np.array(v, dtype=float if v.dtype == jnp.float32 else v.dtype)
        for k, v in state._asdict().items()
    }


def _random_frames(rng, measurement, num_frames, num_meas):
    """Three targets walking at constant velocity and ``num_meas - 3`` clutter rows, each row
    missing at random (probability 0.2)."""
    starts = np.array([[100.0, 120.0, 30.0, 80.0], [300.0, 200.0, 40.0, 100.0], [500, 90, 20, 60]])
    velocity = np.array([[3.0, 1.0], [-2.0, 0.5], [0.5, 2.5]])
    frames, masks = [], []
    for k in range(num_frames):
        boxes = starts.copy()
        boxes[:, :2] += k * velocity
        boxes += rng.normal(0, 1.0, boxes.shape)
        clutter = rng.uniform([0, 0, 20, 50], [640, 480, 40, 100], (num_meas - 3, 4))
        rows = np.vstack([boxes, clutter])
        if measurement == "ellipse":
            rows = np.asarray(box_to_ellipse(jnp.asarray(rows)), float)
            rows[:, 4] += rng.normal(0, 0.05, len(rows))
        frames.append(rows)
        masks.append(rng.uniform(size=num_meas) < 0.8)
    return np.array(frames), np.array(masks)


@pytest.mark.parametrize("measurement", MODELS)
def test_step_matches_loop_reference(measurement):
    """Gating, greedy association, updates, births, overflow, confirmation and removal."""
    params = default_low_params(measurement, confirm_updates=2, coast_frames=1)
    rng = np.random.default_rng(0)
    frames, masks = _random_frames(rng, measurement, num_frames=10, num_meas=5)
    step = jax.jit(functools.partial(low_step, measurement=measurement))
    state = init_low(4, measurement)
    reference = _numpy_state(state)
    seen = {"born": 0, "removed": 0, "newly_confirmed": 0, "overflow": 0, "updated": 0}
    for z, valid in zip(frames, masks, strict=True):
        state, info = step(state, params, jnp.asarray(z, jnp.float32), jnp.asarray(valid))
        reference, expected = reference_step(reference, params, z, valid, measurement)
        for key in ("alive", "confirmed", "ids", "next_id", "age", "misses", "hits"):
            np.testing.assert_array_equal(np.asarray(getattr(state, key)), reference[key], key)
        for key in ("mean", "cov", "msd", "ratio"):
            np.testing.assert_allclose(
                getattr(state, key), reference[key], rtol=2e-3, atol=2e-3, err_msg=key
            )
        for key in ("assignment", "born", "removed", "newly_confirmed", "overflow"):
            np.testing.assert_array_equal(np.asarray(getattr(info, key)), expected[key], key)
        np.testing.assert_allclose(info.ratio, reference["ratio"], rtol=2e-3, atol=2e-3)
        for key in ("born", "removed", "newly_confirmed"):
            seen[key] += int(expected[key].sum())
        seen["overflow"] += expected["overflow"]
        seen["updated"] += int(
            np.sum(
                (expected["assignment"] >= 0)
                & ~np.isin(expected["assignment"], np.flatnonzero(expected["born"]))
            )
        )
    assert all(count > 0 for count in seen.values()), seen


@pytest.mark.parametrize("measurement", MODELS)
def test_step_matches_loop_reference_with_recoveries(measurement):
    """As above, with the recovery gate wide open (every left-over pair is a recovery
    candidate), so that the recovery pass is exercised on every kind of frame."""
    params = default_low_params(measurement, confirm_updates=2, coast_frames=1)
    params = params._replace(recovery_gate=jnp.float32(1e4))
    rng = np.random.default_rng(0)
    frames, masks = _random_frames(rng, measurement, num_frames=10, num_meas=5)
    step = jax.jit(functools.partial(low_step, measurement=measurement))
    state = init_low(4, measurement)
    reference = _numpy_state(state)
    recovered = [0]
    for z, valid in zip(frames, masks, strict=True):
        state, info = step(state, params, jnp.asarray(z, jnp.float32), jnp.asarray(valid))
        reference, expected = reference_step(reference, params, z, valid, measurement, recovered)
        for key in ("alive", "confirmed", "ids", "next_id", "hits"):
            np.testing.assert_array_equal(np.asarray(getattr(state, key)), reference[key], key)
        np.testing.assert_allclose(state.mean, reference["mean"], rtol=2e-3, atol=2e-3)
        np.testing.assert_array_equal(np.asarray(info.assignment), expected["assignment"])
    assert recovered[0] > 0


# --- single tracks: steady state and the derived thresholds --------------------------------

_JITTED = {m: jax.jit(functools.partial(low_step, measurement=m)) for m in MODELS}
#: Every test but the reference one runs 16 slots and 8 measurement rows: one compile per model.
CAPACITY, ROWS = 16, 8


def _step(measurement, state, params, z, valid):
    """The jitted step on ``z`` padded to :data:`ROWS` rows; the assignment trimmed back."""
    z, valid = np.asarray(z, np.float32), np.asarray(valid, bool)
    padded = np.zeros((ROWS, z.shape[1]), np.float32)
    padded[: len(z)] = z
    state, info = _JITTED[measurement](
        state, params, jnp.asarray(padded), jnp.asarray(np.pad(valid, (0, ROWS - len(z))))
    )
    return state, info._replace(assignment=info.assignment[: len(z)])


def _walk(measurement, num_frames, scale=1.0):
    """Exact measurements of one target at constant velocity ``(2, 1)`` pixels per frame."""
    k = np.arange(num_frames)[:, None]
    boxes = np.hstack([100 + 2 * k, 200 + k, np.full_like(k, 40), np.full_like(k, 100)]) * scale
    rows = boxes if measurement == "box" else np.asarray(box_to_ellipse(jnp.asarray(boxes)))
    return rows.astype(np.float32)[:, None]


def _run(measurement, params, rows, valid):
    """Runs the jitted step over frames; returns the final state and the stacked infos."""
    state, infos = init_low(CAPACITY, measurement), []
    for z, mask in zip(rows, valid, strict=True):
        state, info = _step(measurement, state, params, z, mask)
        infos.append(info)
    return state, jax.tree.map(lambda *x: np.stack(x), *infos)


@pytest.mark.parametrize("measurement", MODELS)
def test_steady_state_matches_dare_and_ratio_converges_to_one(measurement):
    """S0_inf equals SciPy's DARE solution; exact measurements drive r_k to 1 (to 1e-3)."""
    process_std, measurement_std, _ = DEFAULT_NOISE[measurement]
    F, G, H, *_ = _reference_model(measurement)
    Q, R = G @ np.diag(np.square(process_std)) @ G.T, np.diag(np.square(measurement_std))
    prior = scipy.linalg.solve_discrete_are(F.T, H.T, Q, R)
    _, innovation_cov = steady_state(measurement, process_std, measurement_std)
    np.testing.assert_allclose(innovation_cov, H @ prior @ H.T + R, rtol=1e-8, atol=1e-15)

    params = default_low_params(measurement)
    rows = _walk(measurement, 40)
    state, info = _run(measurement, params, rows, np.ones((40, 1), bool))
    assert abs(float(state.ratio[0]) - 1.0) < 1e-3
    assert np.all(np.diff(info.ratio[1:, 0]) <= 1e-6)  # falls after the birth (float32 plateau)
    updating, _ = ratio_sequences(measurement, *DEFAULT_NOISE[measurement], count=10)
    np.testing.assert_allclose(info.ratio[1:11, 0], updating, rtol=1e-4)
    np.testing.assert_allclose(low_velocity(state)[0], [2.0, 1.0], atol=1e-3)
    np.testing.assert_allclose(low_boxes(state, measurement)[0], [158, 189, 40, 100], atol=1e-2)


@pytest.mark.parametrize("measurement", MODELS)
@pytest.mark.parametrize(("confirm_updates", "coast_frames"), [(2, 2), (4, 12), (6, 5)])
def test_confirms_on_the_chosen_update_and_is_removed_after_coasting(
    measurement, confirm_updates, coast_frames
):
    """Born on frame 0, confirmed on update ``U`` (frame U); after 40 updates, kept through
    ``C`` missed frames and removed on the next."""
    params = default_low_params(
        measurement, confirm_updates=confirm_updates, coast_frames=coast_frames
    )
    num_frames = 41 + coast_frames + 3
    valid = (np.arange(num_frames) <= 40)[:, None]
    _, info = _run(measurement, params, _walk(measurement, num_frames), valid)
    assert np.flatnonzero(info.newly_confirmed[:, 0]).tolist() == [confirm_updates]
    assert np.flatnonzero(info.removed[:, 0]).tolist() == [40 + coast_frames + 1]
    assert info.born[:, 0].sum() == 1


@pytest.mark.parametrize("measurement", MODELS)
def test_ratio_and_decisions_are_scale_free(measurement):
    """The same scene at twice the size gives the same ratios, MSDs and decisions."""
    params = default_low_params(measurement, confirm_updates=2, coast_frames=1)
    frames, masks = _random_frames(np.random.default_rng(1), measurement, 8, 5)
    doubled = frames.copy()
    doubled[..., :4] *= 2.0
    results = [_run(measurement, params, f.astype(np.float32), masks)[1] for f in (frames, doubled)]
    np.testing.assert_allclose(results[0].ratio, results[1].ratio, rtol=1e-4)
    np.testing.assert_allclose(results[0].msd, results[1].msd, rtol=1e-3, atol=1e-5)
    for key in ("assignment", "born", "removed", "newly_confirmed", "overflow"):
        np.testing.assert_array_equal(getattr(results[0], key), getattr(results[1], key))
    assert results[0].newly_confirmed.any() and results[0].removed.any()


# --- association ------------------------------------------------------------------------------


def _settled(measurement, params, centres, frames=12):
    """Tracks settled on static targets at the given x centres (y 200, 40 x 100 boxes)."""
    boxes = np.array([[x, 200.0, 40.0, 100.0] for x in centres], np.float32)
    rows = boxes if measurement == "box" else np.asarray(box_to_ellipse(jnp.asarray(boxes)))
    rows = np.repeat(rows[None], frames, axis=0)
    state, _ = _run(measurement, params, rows, np.ones(rows.shape[:2], bool))
    return state, rows[0]


@pytest.mark.parametrize("measurement", MODELS)
def test_a_measurement_in_two_gates_goes_to_the_nearer_track(measurement):
    params = default_low_params(measurement)
    state, rows = _settled(measurement, params, [100.0, 110.0])
    z = rows[:1].copy()
    z[0, 0] = 106.0  # 6 px from track 0, 4 px from track 1
    new, info = _step(measurement, state, params, z, [True])
    assert info.assignment.tolist() == [1]
    assert new.misses[:2].tolist() == [1, 0] and not info.born.any()
    # Without the nearer track the measurement falls in the other track's gate.
    alone = state._replace(alive=state.alive.at[1].set(False))
    _, info = _step(measurement, alone, params, z, [True])
    assert info.assignment.tolist() == [0]


def test_association_takes_the_globally_nearest_pair_first():
    """Measurement 1 is nearest to track 1 (1 px), so measurement 0 goes to track 0 (7 px)
    although track 1 is nearer to it (3 px); taking measurements in order would swap them."""
    params = default_low_params("box")
    state, rows = _settled("box", params, [100.0, 110.0])
    z = np.repeat(rows[:1], 2, axis=0)
    z[:, 0] = [107.0, 111.0]
    _, info = _step("box", state, params, z, [True, True])
    assert info.assignment.tolist() == [0, 1]


@pytest.mark.parametrize("measurement", MODELS)
def test_two_measurements_in_one_gate_the_other_starts_a_tentative_track(measurement):
    params = default_low_params(measurement)
    state, rows = _settled(measurement, params, [100.0])
    z = np.repeat(rows[:1], 2, axis=0)
    z[:, 0] = [105.0, 101.0]  # both in the gate; the second is nearer
    new, info = _step(measurement, state, params, z, [True, True])
    assert info.assignment.tolist() == [1, 0]
    assert np.flatnonzero(info.born).tolist() == [1]
    assert np.flatnonzero(new.alive).tolist() == [0, 1]
    assert np.flatnonzero(new.confirmed).tolist() == [0]
    assert new.ids[:2].tolist() == [0, 1] and int(new.next_id) == 2
    np.testing.assert_allclose(new.mean[1, 0], 105.0)


def test_orphans_beyond_capacity_are_counted():
    params = default_low_params("box")
    z = np.array([[100.0 * i, 50.0, 20.0, 50.0] for i in range(1, 6)])
    valid = [True, False, True, True, True]  # 4 orphans, 2 free slots (3 and 11)
    full = init_low(CAPACITY, "box")._replace(alive=jnp.arange(CAPACITY) % 8 != 3)
    state, info = _step("box", full, params, z, valid)
    assert info.assignment.tolist() == [3, -1, 11, -1, -1]
    assert int(info.overflow) == 2 and state.ids[jnp.array([3, 11])].tolist() == [0, 1]


def test_ellipse_angle_innovation_wraps_at_half_turn():
    """An orientation just below pi/2 and a measurement just above -pi/2 are 0.04 rad apart."""
    params = default_low_params("ellipse")
    rows = np.repeat(np.array([[[100.0, 200.0, 115.0, 46.0, 1.55]]], np.float32), 12, axis=0)
    state, _ = _run("ellipse", params, rows, np.ones((12, 1), bool))
    z = np.array([[100.0, 200.0, 115.0, 46.0, -1.55]])
    new, info = _step("ellipse", state, params, z, [True])
    assert info.assignment.tolist() == [0] and float(info.msd[0]) < 1.0
    angle = float(new.mean[0, 6])
    assert -np.pi / 2 < angle <= np.pi / 2 and abs(abs(angle) - np.pi / 2) < 0.03


# --- jit, vmap, conversions, errors --------------------------------------------------------


def test_jit_matches_eager_and_vmap_over_params_matches_loop():
    frames, masks = _random_frames(np.random.default_rng(2), "box", 3, ROWS)
    frames = frames.astype(np.float32)
    params = default_low_params("box", confirm_updates=2)
    state = _run("box", params, frames[:2], masks[:2])[0]
    eager = low_step(state, params, frames[2], masks[2], measurement="box")
    jitted = _JITTED["box"](state, params, jnp.asarray(frames[2]), jnp.asarray(masks[2]))
    close = functools.partial(np.testing.assert_allclose, rtol=1e-5, atol=1e-4)
    jax.tree.map(close, eager, jitted)
    process_std, measurement_std, initial_std = DEFAULT_NOISE["box"]
    noisier = low_params(
        "box", process_std, 2 * np.array(measurement_std), 2 * np.array(initial_std)
    )
    sets = [params, noisier._replace(confirm_ratio=params.confirm_ratio)]
    stacked = jax.tree.map(lambda *x: jnp.stack(x), *sets)
    z, valid = jnp.asarray(frames[2]), jnp.asarray(masks[2])
    batched = jax.vmap(_JITTED["box"], in_axes=(None, 0, None, None))(state, stacked, z, valid)
    for i, one in enumerate(sets):
        jax.tree.map(
            close, jax.tree.map(lambda x, i=i: x[i], batched), _JITTED["box"](state, one, z, valid)
        )
    assert not np.allclose(batched[1].msd[0], batched[1].msd[1])  # the sets differ


def test_box_ellipse_round_trip_and_moments():
    rng = np.random.default_rng(3)
    boxes = np.column_stack([rng.uniform(0, 500, (20, 2)), rng.uniform(5, 150, (20, 2))])
    np.testing.assert_allclose(ellipse_to_box(box_to_ellipse(jnp.asarray(boxes))), boxes, rtol=1e-5)
    # Full axes are 4 standard deviations of points drawn uniformly in the box (2e5 samples).
    points = rng.uniform([-15, -40], [15, 40], (200_000, 2))
    axes = 4 * np.sqrt(np.sort(np.linalg.eigvalsh(np.cov(points.T)))[::-1])
    ellipse = np.asarray(box_to_ellipse(jnp.array([0.0, 0.0, 30.0, 80.0])))
    np.testing.assert_allclose(ellipse[2:4], axes, rtol=5e-3)
    assert ellipse[4] == pytest.approx(np.pi / 2) and box_to_ellipse(jnp.ones(4) * 9)[4] == 0
    # A rotated ellipse: the bounding box of the rotated equivalent rectangle's corners.
    theta, sides = 0.6, np.array([60.0, 20.0])
    corners = np.array([[sx, sy] for sx in (-1, 1) for sy in (-1, 1)]) * sides / 2
    rotation = np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    extent = np.ptp(corners @ rotation.T, axis=0)
    ellipse = jnp.array([5.0, 7.0, *(sides * 2 / np.sqrt(3)), theta])
    np.testing.assert_allclose(ellipse_to_box(ellipse), [5.0, 7.0, *extent], rtol=1e-5)
    angles = jnp.array([np.pi / 2, -np.pi / 2, np.pi, 0.75 * np.pi, -0.75 * np.pi, 0.1])
    expected = [np.pi / 2, np.pi / 2, 0.0, -np.pi / 4, np.pi / 4, 0.1]
    np.testing.assert_allclose(wrap_angle(angles), expected, atol=1e-6)


def test_bad_arguments_raise_input_errors():
    box_noise = DEFAULT_NOISE["box"]
    with pytest.raises(InputError, match="measurement must be one of"):
        default_low_params("circle")
    with pytest.raises(InputError, match="capacity"):
        init_low(0, "box")
    with pytest.raises(InputError, match="confirm_updates"):
        default_low_params("box", confirm_updates=1)
    with pytest.raises(InputError, match="coast_frames"):
        default_low_params("box", coast_frames=0)
    with pytest.raises(InputError, match="gate_confidence"):
        default_low_params("box", gate_confidence=1.0)
    with pytest.raises(InputError, match="measurement_std must hold 4"):
        low_params("box", box_noise[0], (0.1, 0.1, 0.1), box_noise[2])
    with pytest.raises(InputError, match="do not fall"):
        low_params("box", box_noise[0], box_noise[1], np.full(6, 1e-4))


# --- a synthetic scene with known truth ----------------------------------------------------


def _scene(seed, measurement, num_frames=40, clutter_rate=2.0, max_clutter=5):
    """Three constant-velocity targets (rows 0-2, always detected, model noise) and Poisson
    clutter (mean ``clutter_rate`` per frame, uniform over 640 x 480) in rows 3 on."""
    rng = np.random.default_rng(seed)
    starts = np.array([[100.0, 150, 30, 80], [500, 300, 40, 110], [300, 400, 25, 60]])
    velocity = np.array([[3.0, 1.0], [-2.5, -1.0], [1.0, -2.0]])
    measurement_std = np.array(DEFAULT_NOISE["box"][1])
    frames, masks = [], []
    for k in range(num_frames):
        truth = starts.copy()
        truth[:, :2] += k * velocity
        boxes = truth + rng.normal(size=truth.shape) * measurement_std * truth[:, 3:]
        clutter = rng.uniform([0, 0, 20, 50], [640, 480, 40, 110], (max_clutter, 4))
        rows = np.vstack([boxes, clutter])
        if measurement == "ellipse":
            rows = np.asarray(box_to_ellipse(jnp.asarray(rows)), float)
            rows[:, 4] += rng.normal(0, DEFAULT_NOISE["ellipse"][1][4], len(rows))
        frames.append(rows)
        num_clutter = min(rng.poisson(clutter_rate), max_clutter)
        masks.append(np.r_[np.ones(3, bool), np.arange(max_clutter) < num_clutter])
    return np.array(frames, np.float32), np.array(masks)


@pytest.mark.parametrize("measurement", MODELS)
def test_scene_targets_confirmed_and_clutter_not(measurement):
    """Seeds 0-2: each target's first track is confirmed by frame ``U + 2`` and keeps >= 90 %
    of its target's measurements; no track born on clutter is confirmed unless it took
    measurements of a target (such duplicates: at most 1 per scene)."""
    params = default_low_params(measurement)  # confirm_updates U = 4
    for seed in range(3):
        frames, masks = _scene(seed, measurement)
        state = init_low(CAPACITY, measurement)
        confirmed_ids, clutter_ids, target_ids = set(), set(), [[] for _ in range(3)]
        for k, (z, valid) in enumerate(zip(frames, masks, strict=True)):
            state, info = _JITTED[measurement](state, params, jnp.asarray(z), jnp.asarray(valid))
            ids, slots = np.asarray(state.ids), np.asarray(info.assignment)
            for j in range(3):
                target_ids[j].append(int(ids[slots[j]]) if slots[j] >= 0 else -1)
            born = np.asarray(info.born)
            clutter_ids |= {int(ids[s]) for s in slots[3:][masks[k][3:]] if s >= 0 and born[s]}
            confirmed_ids |= set(ids[np.asarray(state.confirmed)].tolist())
            if k == 4 + 2:
                assert {t[0] for t in target_ids} <= confirmed_ids
        for j in range(3):
            assert np.mean(np.array(target_ids[j]) == target_ids[j][0]) >= 0.9
        assert target_ids[0][0] == 0 and len(clutter_ids) > 40  # clutter kept coming
        duplicates = clutter_ids & confirmed_ids
        assert duplicates <= {i for track in target_ids for i in track} and len(duplicates) <= 1


def test_an_uncertain_new_track_does_not_take_a_settled_tracks_measurement():
    """A measurement 8 px from a settled track and 6 px from a tentative one (larger S, so a
    smaller MSD) goes to the settled track: the cost is MSD + 2 log r_k, not the MSD alone."""
    params = default_low_params("box")
    state, rows = _settled("box", params, [100.0])
    birth = rows[:1].copy()
    birth[0, 0] = 114.0
    state, _ = _step("box", state, params, np.concatenate([rows[:1], birth]), [True, True])
    assert int(state.alive.sum()) == 2
    z = rows[:1].copy()
    z[0, 0] = 108.0
    _, info = _step("box", state, params, z, [True])
    settled = int(np.flatnonzero(np.asarray(state.confirmed))[0])
    assert info.assignment.tolist() == [settled]


@pytest.mark.parametrize("measurement", MODELS)
def test_recovery_a_confirmed_track_takes_a_left_over_measurement_in_the_wider_gate(
    measurement,
):
    """A measurement outside a settled track's 99 % gate but inside its 99.99 % one, which no
    other track takes, updates the track instead of starting a tentative one; with the
    recovery gate at the gate (recovery off) it starts one, as the paper's low level does."""
    params = default_low_params(measurement)
    state, rows = _settled(measurement, params, [100.0])
    scale = track_scale(state.mean[0], measurement)
    mean, cov = low_predict(state.mean[0], state.cov[0], params.process_std, scale, measurement)
    innovation_cov, _ = innovation_covariance(cov, params.measurement_std, scale, measurement)
    z = rows[:1].copy()
    chosen = None  # the first x offset whose MSD lies between the two gates
    for offset in np.arange(1.0, 40.0, 0.25):
        z[0, 0] = 100.0 + offset
        msd = float(mahalanobis_square_distances(mean, innovation_cov, z, measurement)[0])
        if float(params.gate) < msd <= float(params.recovery_gate):
            chosen = offset
            break
    assert chosen is not None
    new, info = _step(measurement, state, params, z, [True])
    assert info.assignment.tolist() == [0] and not info.born.any()
    assert int(new.misses[0]) == 0 and int(new.alive.sum()) == 1
    off = params._replace(recovery_gate=params.gate)
    new, info = _step(measurement, state, off, z, [True])
    assert info.born.sum() == 1 and int(new.misses[0]) == 1 and int(new.alive.sum()) == 2


def test_recovery_only_for_confirmed_tracks_and_only_left_overs():
    """A tentative track takes nothing through the recovery gate; a confirmed track that took
    a measurement in its gate takes no second one; the nearer track still wins a measurement
    in both gates."""
    params = default_low_params("box")
    wide = params._replace(recovery_gate=jnp.float32(1e4))
    # Tentative: one birth, then a measurement far outside its gate is a new birth.
    state = init_low(CAPACITY, "box")
    box = np.array([[100.0, 200.0, 40.0, 100.0]], np.float32)
    state, _ = _step("box", state, wide, box, [True])
    far = box.copy()
    far[0, 0] = 300.0
    new, info = _step("box", state, wide, far, [True])
    assert not bool(state.confirmed[0]) and info.born.sum() == 1 and int(new.misses[0]) == 1
    # Confirmed and updated: a second measurement is an orphan, not a recovery.
    settled, rows = _settled("box", params, [100.0])
    z = np.concatenate([rows[:1], far])
    new, info = _step("box", settled, wide, z, [True, True])
    assert info.assignment[0] == 0 and info.born.sum() == 1 and int(new.alive.sum()) == 2
    # Two confirmed tracks, one measurement near the first: only the first takes it.
    two, rows = _settled("box", params, [100.0, 300.0])
    _, info = _step("box", two, wide, rows[:1], [True])
    assert info.assignment.tolist() == [0]


def test_recovery_confidence_below_the_gate_is_refused():
    with pytest.raises(InputError, match="recovery_confidence"):
        default_low_params("box", recovery_confidence=0.9)
    with pytest.raises(InputError, match="recovery_confidence"):
        default_low_params("box", recovery_confidence=1.0)
    params = default_low_params("box", recovery_confidence=0.99)
    assert float(params.recovery_gate) == float(params.gate)
