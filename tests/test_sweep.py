"""The sweep engine: vmapped == loop of single runs; sharded == unsharded; input errors."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import jax
import numpy as np
import pytest

from jaxtrack.association.offline import finalise_tracks, track_rows
from jaxtrack.association.retrodiction import detection_rows, retrodict
from jaxtrack.association.smoothing import smooth_tracks
from jaxtrack.errors import InputError
from jaxtrack.filters.base import run
from jaxtrack.filters.phd import phd_filter
from jaxtrack.filters.phd_tracker import PHDConfig, phd_params
from jaxtrack.io import load_sequence
from jaxtrack.metrics.evaluate import evaluate_sequence
from jaxtrack.pipelines.sweep import (
    BIRTH_RATE,
    CLUTTER_RATE,
    _config_keys,
    batch_params,
    magnitude_grid,
    pad_components,
    product_grid,
    sweep,
)

FRAMES = (11, 40)
CLUTTER_RATES = np.array([0.3, 3.0], np.float32)
BIRTH_RATES = np.array([0.05, 0.2, 0.8], np.float32)


@pytest.fixture(scope="module")
def campus(mot15_root):
    return load_sequence(mot15_root / "TUD-Campus", frames=FRAMES)


@pytest.fixture(scope="module")
def small_filter():
    return phd_filter(128, births_per_detection=8)


@pytest.fixture(scope="module")
def single_run(campus, small_filter):
    """One configuration, jitted once for the module: ``(key, params) -> info``."""
    return jax.jit(lambda key, params: run(small_filter, key, params, campus.detections)[1])


def test_magnitude_grid_is_a_c_order_product():
    grid = magnitude_grid(CLUTTER_RATES, BIRTH_RATES)
    assert set(grid) == {CLUTTER_RATE, BIRTH_RATE}
    np.testing.assert_array_equal(grid[CLUTTER_RATE], np.repeat(CLUTTER_RATES, 3))
    np.testing.assert_array_equal(grid[BIRTH_RATE], np.tile(BIRTH_RATES, 2))
    both = product_grid({"a": [1, 2], "b": [3, 4, 5], "c": [6]})
    assert [(a, b, c) for a, b, c in zip(*both.values(), strict=True)] == [
        (1, 3, 6), (1, 4, 6), (1, 5, 6), (2, 3, 6), (2, 4, 6), (2, 5, 6)
    ]  # fmt: skip


def test_vmapped_sweep_equals_loop_of_single_runs(campus, small_filter, single_run):
    params = phd_params(PHDConfig(), campus.info)
    updates = magnitude_grid(CLUTTER_RATES, BIRTH_RATES)
    key = jax.random.PRNGKey(3)
    # chunk_size 4: the six configurations as two chunks of three.
    result = sweep(
        small_filter,
        params,
        key,
        campus.detections,
        updates,
        ground_truth=campus.gt_table,
        first_frame=campus.first_frame,
        chunk_size=4,
    )
    batched = batch_params(params, updates)
    assert len(result.rows) == 6
    for b in range(6):
        info = single_run(key, jax.tree.map(lambda x, b=b: x[b], batched))
        expected = finalise_tracks(info.tracks, info.candidates, 8, campus.first_frame)
        got = result.rows[b]
        np.testing.assert_array_equal(got.frames, expected.frames)
        np.testing.assert_array_equal(got.ids, expected.ids)
        np.testing.assert_allclose(got.boxes, expected.boxes, rtol=1e-5, atol=1e-3)
        np.testing.assert_allclose(result.log_likelihood[b], np.sum(info.log_likelihood), rtol=1e-5)
        scores = evaluate_sequence(campus.gt_table, expected, FRAMES).summary()
        for name in ("MOTA", "MOTP", "MODA", "MODP", "IDF1", "HOTA"):
            np.testing.assert_allclose(result.scores[name][b], scores[name], atol=1e-6)
    # The grid matters: the magnitudes change the output.
    assert len({len(rows.frames) for rows in result.rows}) > 1
    assert np.ptp(result.log_likelihood) > 1.0
    # Where the wall time went: every phase measured, and the phases (which run one after
    # another on the host) add up to no more than the total.
    phases = ("trace", "compile", "wait", "score")
    assert set(result.seconds) == {*phases, "total"}
    assert all(result.seconds[name] > 0 for name in phases)
    assert sum(result.seconds[name] for name in phases) <= result.seconds["total"]


def test_sweep_online_output_and_per_configuration_keys(campus, small_filter, single_run):
    params = phd_params(PHDConfig(), campus.info)
    keys = jax.random.split(jax.random.PRNGKey(1), 2)
    updates = {CLUTTER_RATE: np.array([1.0, 1.0], np.float32)}
    result = sweep(
        small_filter, params, keys, campus.detections, updates, output="online", chunk_size=4
    )
    assert result.scores == {}
    for b in range(2):
        info = single_run(keys[b], params)
        expected = track_rows(info.tracks, 1)
        np.testing.assert_array_equal(result.rows[b].ids, expected.ids)
        np.testing.assert_allclose(result.rows[b].boxes, expected.boxes, rtol=1e-5, atol=1e-3)
    # Different keys, same parameters: different runs.
    assert not np.isclose(result.log_likelihood[0], result.log_likelihood[1])


def test_sweep_retrodiction_equals_the_single_runs_retrodicted(campus, small_filter, single_run):
    params = phd_params(PHDConfig(), campus.info)
    key = jax.random.PRNGKey(3)
    updates = {BIRTH_RATE: np.array([0.05, 0.8], np.float32)}
    options = {"first_frame": campus.first_frame, "retrodiction": 10, "chunk_size": 4}
    result = sweep(small_filter, params, key, campus.detections, updates, **options)
    detections = detection_rows(campus.detections, campus.first_frame)
    batched = batch_params(params, updates)
    added = 0
    for b in range(2):
        info = single_run(key, jax.tree.map(lambda x, b=b: x[b], batched))
        plain = finalise_tracks(info.tracks, info.candidates, 8, campus.first_frame)
        expected = retrodict(plain, detections, campus.first_frame, 10)
        np.testing.assert_array_equal(result.rows[b].frames, expected.frames)
        np.testing.assert_array_equal(result.rows[b].ids, expected.ids)
        np.testing.assert_allclose(result.rows[b].boxes, expected.boxes, rtol=1e-5, atol=1e-3)
        added += len(expected) - len(plain)
    assert added > 0


def test_sweep_smoothing_uses_each_configurations_noise(campus, small_filter, single_run):
    params = phd_params(PHDConfig(), campus.info)
    key = jax.random.PRNGKey(3)
    noise = np.array([[0.05, 0.02, 0.05, 0.05], [0.1, 0.05, 0.02, 0.02]], np.float32)
    updates = {"motion_noise_std": noise}
    options = {"first_frame": campus.first_frame, "smoothing": "rts", "chunk_size": 4}
    result = sweep(small_filter, params, key, campus.detections, updates, **options)
    batched = batch_params(params, updates)
    for b in range(2):
        info = single_run(key, jax.tree.map(lambda x, b=b: x[b], batched))
        plain = finalise_tracks(info.tracks, info.candidates, 8, campus.first_frame)
        expected = smooth_tracks(plain, noise[b], params.measurement_noise_std)
        np.testing.assert_array_equal(result.rows[b].frames, expected.frames)
        np.testing.assert_array_equal(result.rows[b].ids, expected.ids)
        np.testing.assert_allclose(result.rows[b].boxes, expected.boxes, rtol=1e-5, atol=1e-3)
        assert not np.allclose(result.rows[b].boxes, plain.boxes, atol=1e-2)
    with pytest.raises(InputError, match="online output would ignore it"):
        sweep(
            small_filter, params, key, campus.detections, updates, output="online", smoothing="rts"
        )
    with pytest.raises(InputError, match="smoothing must be one of"):
        sweep(small_filter, params, key, campus.detections, updates, smoothing="kalman")


def test_typed_keys_are_passed_as_key_data():
    typed = jax.random.split(jax.random.key(7), 3)
    data, impl = _config_keys(typed, 3)
    np.testing.assert_array_equal(data, jax.random.key_data(typed))
    assert impl == "threefry2x32"
    single, impl = _config_keys(jax.random.PRNGKey(7), 3)
    assert single.shape == (3, 2) and impl is None
    np.testing.assert_array_equal(single[2], jax.random.PRNGKey(7))


def test_pad_components_leaves_the_intensity_unchanged(campus):
    params = phd_params(PHDConfig(), campus.info)
    from jaxtrack.context.intensity import log_intensity

    clutter = params.clutter_intensity._replace(uniform_weight=np.float32(0.5))
    clutter = clutter._replace(weights=np.ones(1, np.float32))
    padded = pad_components(clutter, 4)
    assert padded.weights.shape == (4,) and padded.covs.shape == (4, 4, 4)
    points = np.array([[100.0, 200.0, 40.0, 90.0], [1.0, 5.0, 30.0, 30.0]], np.float32)
    np.testing.assert_allclose(log_intensity(padded, points), log_intensity(clutter, points))
    with pytest.raises(InputError, match="cannot pad"):
        pad_components(padded, 2)


def test_sweep_input_errors(campus, small_filter):
    params = phd_params(PHDConfig(), campus.info)
    key = jax.random.PRNGKey(0)
    detections = campus.detections
    with pytest.raises(InputError, match="same leading batch size"):
        batch_params(params, {CLUTTER_RATE: np.ones(3), BIRTH_RATE: np.ones(2)})
    with pytest.raises(InputError, match=r"unknown parameter.*clutter_intensity\.magnitude"):
        batch_params(params, {"clutter_intensity.magnitude": np.ones(3)})
    with pytest.raises(InputError, match=r"unknown parameter.*mass_threshold"):
        batch_params(params, {"mass_threshold": np.ones(3)})
    with pytest.raises(InputError, match=r"shape \[batch, 4\]"):
        batch_params(params, {"motion_noise_std": np.ones(3)})
    with pytest.raises(InputError, match="empty"):
        batch_params(params, {CLUTTER_RATE: np.ones(0)})
    with pytest.raises(InputError, match="positive"):
        magnitude_grid([1.0, -1.0], [0.1])
    with pytest.raises(InputError, match="one key or one per configuration"):
        sweep(
            small_filter,
            params,
            jax.random.split(key, 3),
            detections,
            magnitude_grid([1.0], [0.1, 0.2]),
        )
    with pytest.raises(InputError, match="same non-zero leading batch size"):
        sweep(small_filter, params, key, detections)
    with pytest.raises(InputError, match="output"):
        sweep(small_filter, params, key, detections, magnitude_grid([1.0], [0.1]), output="x")
    with pytest.raises(InputError, match="chunk_size"):
        sweep(small_filter, params, key, detections, magnitude_grid([1.0], [0.1]), chunk_size=0)
    grid = magnitude_grid([1.0], [0.1])
    with pytest.raises(InputError, match="online output would ignore it"):
        sweep(small_filter, params, key, detections, grid, output="online", retrodiction=5)
    with pytest.raises(InputError, match="retrodiction must be >= 0"):
        sweep(small_filter, params, key, detections, grid, retrodiction=-1)


def test_sweep_refuses_calls_that_need_more_memory_than_the_machine_has(
    campus, small_filter, monkeypatch
):
    import jaxtrack.resources
    from jaxtrack.resources import ResourceError

    params = phd_params(PHDConfig(), campus.info)
    key, detections = jax.random.PRNGKey(0), campus.detections
    grid = magnitude_grid([1.0, 2.0], [0.1, 0.2])
    monkeypatch.setattr(jaxtrack.resources, "available_memory_bytes", lambda: 1000)
    with pytest.raises(ResourceError, match=r"sweep call of 2 configurations .*chunk_size"):
        sweep(small_filter, params, key, detections, grid, chunk_size=2, devices=jax.devices()[:1])
    monkeypatch.setattr(jaxtrack.resources, "available_memory_bytes", lambda: 10**12)
    done = sweep(small_filter, params, key, detections, grid, chunk_size=2)
    assert len(done.rows) == 4


_SHARD_SCRIPT = textwrap.dedent(
    """
    import json, sys
    import jax, numpy as np
    from jaxtrack.filters.phd import phd_filter
    from jaxtrack.filters.phd_tracker import PHDConfig, phd_params
    from jaxtrack.io import load_sequence
    from jaxtrack.pipelines.sweep import magnitude_grid, sweep

    assert jax.device_count() == 4, jax.devices()
    seq = load_sequence(sys.argv[1], frames=(11, 40))
    filt = phd_filter(128, births_per_detection=8)
    args = (filt, phd_params(PHDConfig(), seq.info), jax.random.PRNGKey(5), seq.detections,
            magnitude_grid([0.3, 3.0], [0.05, 0.2, 0.8]))
    kwargs = dict(ground_truth=seq.gt_table, first_frame=seq.first_frame, chunk_size=3)
    sharded = sweep(*args, **kwargs)
    single = sweep(*args, devices=jax.devices()[:1], **kwargs)
    print(json.dumps({
        "ids_equal": all(np.array_equal(a.ids, b.ids) and np.array_equal(a.frames, b.frames)
                         for a, b in zip(sharded.rows, single.rows)),
        "max_box_diff": max(float(np.max(np.abs(a.boxes - b.boxes), initial=0))
                            for a, b in zip(sharded.rows, single.rows)),
        "mota": [sharded.scores["MOTA"].tolist(), single.scores["MOTA"].tolist()],
        "hota": [sharded.scores["HOTA"].tolist(), single.scores["HOTA"].tolist()],
        "log_likelihood": [sharded.log_likelihood.tolist(), single.log_likelihood.tolist()],
    }))
    """
)


def test_sharded_sweep_on_four_devices_equals_unsharded(mot15_root):
    env = {**os.environ, "XLA_FLAGS": "--xla_force_host_platform_device_count=4"}
    env["JAX_PLATFORMS"] = "cpu"
    done = subprocess.run(
        [sys.executable, "-c", _SHARD_SCRIPT, str(mot15_root / "TUD-Campus")],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    # Each device runs a group of the single device's size (two groups of 3 on two of the
    # four devices, against two calls of 3 on one): the same programs, bit for bit.
    assert report["ids_equal"]
    assert report["max_box_diff"] == 0.0
    assert report["mota"][0] == report["mota"][1]
    assert report["hota"][0] == report["hota"][1]
    assert report["log_likelihood"][0] == report["log_likelihood"][1]
    assert len(set(report["mota"][0])) > 1


_CORES_SCRIPT = textwrap.dedent(
    """
    import json, os, sys
    import jax
    from jaxtrack import use_cpu_cores
    made = use_cpu_cores(int(sys.argv[1]))
    again = use_cpu_cores(3)  # before anything ran: a later call may still change it
    count = jax.device_count()
    late = use_cpu_cores(5)  # the backends now exist: too late, nothing changes
    print(json.dumps({"made": made, "again": again, "count": count, "late": late,
                      "after": jax.device_count()}))
    """
)


@pytest.mark.parametrize(
    ("env", "expected"),
    [
        ({}, {"made": 2, "again": 0, "count": 2, "late": 0, "after": 2}),
        # the user's own choice is kept
        (
            {"XLA_FLAGS": "--xla_force_host_platform_device_count=4"},
            {"made": 0, "again": 0, "count": 4, "late": 0, "after": 4},
        ),
        ({"JAX_NUM_CPU_DEVICES": "1"}, {"made": 0, "again": 0, "count": 1, "late": 0, "after": 1}),
    ],
)
def test_use_cpu_cores_sets_devices_once_and_keeps_the_users_choice(env, expected):
    base = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "JAX_NUM_CPU_DEVICES")}
    done = subprocess.run(
        [sys.executable, "-c", _CORES_SCRIPT, "2"],
        env={**base, "JAX_PLATFORMS": "cpu", **env},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert json.loads(done.stdout.strip().splitlines()[-1]) == expected


def test_chunks_are_even_and_padding_is_least():
    from jaxtrack.pipelines.sweep import _chunking

    assert _chunking(162, 28, 1) == (6, 27, 1)  # not five of 28 and a sixth padded by six
    assert _chunking(162, 28, 2) == (3, 27, 2)  # the same groups of 27, two per call
    assert _chunking(162, 28, 16) == (1, 27, 6)  # six groups: six devices
    assert _chunking(6, 4, 1) == (2, 3, 1)
    assert _chunking(7, 4, 1) == (2, 4, 1)  # the second chunk padded by one
    assert _chunking(5, 16, 1) == (1, 5, 1)
    assert _chunking(6, 3, 4) == (1, 3, 2)
    for batch in range(1, 60):
        for size in range(1, 20):
            one = _chunking(batch, size, 1)
            for devices in (1, 2, 3, 4):
                num_calls, per_device, used = _chunking(batch, size, devices)
                # the group size is the single device's, whatever the number of devices
                assert per_device == one[1] <= size
                assert 1 <= used <= devices
                assert num_calls * per_device * used >= batch
                assert (num_calls - 1) * per_device * used < batch
                # the fewest groups of at most `size`, no device left without a group
                groups = -(-batch // size)
                assert -(-batch // per_device) == groups and used == min(devices, groups)
