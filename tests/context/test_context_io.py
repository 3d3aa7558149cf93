"""Saving and loading a learned context: round trip, metadata, and every kind of bad file."""

from __future__ import annotations

import json

import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.context.intensity import log_intensity, uniform_intensity
from jaxtrack.context.io import FORMAT_VERSION, load_context, load_context_parts, save_context
from jaxtrack.context.map_em import (
    fit,
    grid_init_birth,
    grid_init_clutter,
    map_em_learner,
    to_intensity,
)
from jaxtrack.errors import FileFormatError


@pytest.fixture(scope="module")
def learned():
    """A learned clutter intensity (some dead components) and a grid birth intensity."""
    rng = np.random.default_rng(0)
    samples = np.array([130.0, 130.0, 34.0, 60.0]) + [12.0, 10.0, 6.0, 10.0] * rng.normal(
        size=(300, 4)
    )
    clutter_state = fit(map_em_learner(), grid_init_clutter(768, 576, (30.0, 60.0)), samples)
    assert not bool(clutter_state.alive.all())
    birth = to_intensity(grid_init_birth(768, 576, (30.0, 60.0)), 0.06)
    return birth, to_intensity(clutter_state, 1.9)


def test_round_trip(tmp_path, learned):
    birth, clutter = learned
    metadata = {
        "sequence": "synthetic-0",
        "frames": [1, 400],
        "num_samples": np.int64(300),  # NumPy scalars are converted
        "magnitudes": {"birth": 0.06, "clutter": 1.9},
    }
    path = tmp_path / "sub" / "context.npz"
    save_context(path, birth, clutter, metadata)
    birth2, clutter2, metadata2 = load_context(path)
    for original, loaded in ((birth, birth2), (clutter, clutter2)):
        for field, value in original._asdict().items():
            np.testing.assert_array_equal(np.asarray(getattr(loaded, field)), np.asarray(value))
    assert metadata2 == {
        "sequence": "synthetic-0",
        "frames": [1, 400],
        "num_samples": 300,
        "magnitudes": {"birth": 0.06, "clutter": 1.9},
        "format_version": FORMAT_VERSION,
    }
    z = jnp.array([[130.0, 130.0, 34.0, 60.0], [600.0, 100.0, 30.0, 60.0]])
    np.testing.assert_array_equal(log_intensity(clutter2, z), log_intensity(clutter, z))
    # the file holds no pickled objects
    with np.load(path, allow_pickle=False) as data:
        assert "metadata_json" in data.files and "clutter_covs" in data.files


def test_the_first_frame_intensity_round_trips_and_is_optional(tmp_path, learned):
    birth, clutter = learned
    initial = to_intensity(grid_init_birth(768, 576, (30.0, 60.0)), 6.5)._replace(
        uniform_weight=jnp.asarray(0.03, jnp.float32)
    )
    path = tmp_path / "with.npz"
    save_context(path, birth, clutter, {"initial": {"magnitude": 6.5}}, initial)
    *_, loaded = load_context_parts(path)
    for field, value in initial._asdict().items():
        np.testing.assert_array_equal(np.asarray(getattr(loaded, field)), np.asarray(value))
    assert len(load_context(path)) == 3  # the three-part reader is unchanged
    older = tmp_path / "without.npz"
    save_context(older, birth, clutter)
    assert load_context_parts(older)[3] is None
    with np.load(older, allow_pickle=False) as data:
        assert not any(name.startswith("initial_") for name in data.files)


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda a: a.pop("initial_covs"), "missing field 'initial_covs'"),
        (lambda a: a.update(initial_uniform_weight=np.asarray(-0.5)), "initial_uniform_weight"),
        (
            lambda a: a.update(
                metadata_json=np.asarray('{"format_version": 1, "initial": {"magnitude": -2}}')
            ),
            "initial.magnitude",
        ),
    ],
)
def test_a_bad_first_frame_intensity_is_refused(tmp_path, learned, mutate, message):
    arrays = valid_arrays(learned)
    for field, value in learned[0]._asdict().items():
        arrays[f"initial_{field}"] = np.asarray(value)
    path = tmp_path / "bad.npz"
    write_raw(path, arrays)
    assert load_context_parts(path)[3] is not None  # the unmutated file is valid
    mutate(arrays)
    write_raw(path, arrays)
    with pytest.raises(FileFormatError, match=message):
        load_context_parts(path)


def test_a_first_frame_intensity_outside_the_birth_space_is_refused(tmp_path, learned):
    arrays = valid_arrays(learned)
    for field, value in learned[1]._asdict().items():  # the 4-D clutter intensity
        arrays[f"initial_{field}"] = np.asarray(value)
    path = tmp_path / "bad.npz"
    write_raw(path, arrays)
    with pytest.raises(FileFormatError, match=r"initial_lower has shape \(4,\)"):
        load_context_parts(path)


def test_unserialisable_metadata_is_rejected(tmp_path, learned):
    with pytest.raises(TypeError, match="not JSON"):
        save_context(tmp_path / "c.npz", *learned, {"bad": object()})
    assert not (tmp_path / "c.npz").exists()


def write_raw(path, arrays):
    with path.open("wb") as file:
        np.savez(file, **arrays)


def valid_arrays(learned, metadata=None):
    arrays = {"metadata_json": np.asarray(json.dumps(metadata or {"format_version": 1}))}
    for prefix, intensity in zip(("birth", "clutter"), learned, strict=True):
        for field, value in intensity._asdict().items():
            arrays[f"{prefix}_{field}"] = np.asarray(value)
    return arrays


def test_missing_and_corrupt_files(tmp_path):
    with pytest.raises(FileFormatError, match="file not found") as info:
        load_context(tmp_path / "nope.npz")
    assert info.value.path.endswith("nope.npz") and info.value.line is None
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"PK\x03\x04 this is not a zip archive")
    with pytest.raises(FileFormatError, match=r"not a readable \.npz"):
        load_context(garbage)
    truncated = tmp_path / "truncated.npz"
    save_context(truncated, uniform_intensity(1.0, [0, 0], [1, 1]), uniform_intensity(1, [0], [1]))
    truncated.write_bytes(truncated.read_bytes()[:200])
    with pytest.raises(FileFormatError):
        load_context(truncated)


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda a: a.pop("clutter_covs"), "missing field 'clutter_covs'"),
        (lambda a: a.pop("metadata_json"), "missing field 'metadata_json'"),
        (lambda a: a.update(metadata_json=np.asarray("{oops")), "not valid JSON"),
        (lambda a: a.update(metadata_json=np.asarray("[1, 2]")), "JSON object"),
        (lambda a: a.update(metadata_json=np.asarray("{}")), "format_version"),
        (
            lambda a: a.update(metadata_json=np.asarray('{"format_version": 99}')),
            "format_version 99",
        ),
        (lambda a: a.update(birth_means=a["birth_means"][:, :4]), "birth_means has shape"),
        (lambda a: a.update(clutter_lower=np.zeros((2, 2))), "lower must be 1-D"),
        (lambda a: a.update(clutter_weights=np.zeros(0)), "non-empty"),
        (lambda a: a.update(clutter_magnitude=np.asarray(np.nan)), "finite"),
        (lambda a: a.update(clutter_magnitude=np.asarray(-1.0)), "magnitude"),
        (lambda a: a.update(birth_uniform_weight=np.asarray(1.5)), "uniform_weight"),
        (lambda a: a.update(birth_upper=a["birth_lower"]), "upper must exceed"),
        (lambda a: a.update(clutter_weights=-a["clutter_weights"]), "weights must be >= 0"),
        (lambda a: a.update(clutter_weights=2 * a["clutter_weights"]), "sum to 1"),
    ],
)
def test_invalid_contents(tmp_path, learned, mutate, message):
    arrays = valid_arrays(learned)
    path = tmp_path / "bad.npz"
    write_raw(path, arrays)
    load_context(path)  # the unmutated file is valid
    mutate(arrays)
    write_raw(path, arrays)
    with pytest.raises(FileFormatError, match=message):
        load_context(path)


def _set_cov(arrays, key, index, cov):
    covs = np.array(arrays[key], dtype=np.float64)
    covs[index] = cov
    arrays[key] = covs


def _skewed(arrays):
    cov = np.diag([4.0, 9.0, 1.0, 1.0])
    cov[0, 1] = 1.0  # the lower triangle (read by the filters) says 0
    _set_cov(arrays, "clutter_covs", 2, cov)


def _indefinite(arrays):
    _set_cov(arrays, "clutter_covs", 1, np.diag([4.0, -1.0, 1.0, 1.0]))


def _float32_singular(arrays):
    # positive definite in float64 (eigenvalues 2 and 1e-9) but singular once cast to float32
    block = np.array([[1.0, 1.0 - 1e-9], [1.0 - 1e-9, 1.0]])
    cov = np.eye(4)
    cov[:2, :2] = block
    assert np.all(np.linalg.eigvalsh(cov) > 0)
    _set_cov(arrays, "clutter_covs", 0, cov)


def _tiny_volume(arrays):
    lower = np.array(arrays["clutter_lower"], dtype=np.float64)
    upper = np.array(arrays["clutter_upper"], dtype=np.float64)
    upper[3] = lower[3] + 1e-12  # exceeds in float64, not in float32
    arrays["clutter_upper"] = upper


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (_skewed, r"clutter_covs\[2\] is not symmetric"),
        (_indefinite, r"clutter_covs\[1\] is not positive definite"),
        (_float32_singular, r"clutter_covs\[0\] is not positive definite in float32"),
        (_tiny_volume, "clutter_upper must exceed clutter_lower on every axis"),
        (lambda a: a.update(birth_magnitude=np.asarray(2e4)), r"birth_magnitude must lie in"),
        (lambda a: a.update(birth_magnitude=np.asarray(1e-40)), r"birth_magnitude must lie in"),
        (lambda a: a.update(clutter_means=a["clutter_means"] + 2e6), "clutter_means must lie"),
        (lambda a: a.update(birth_lower=a["birth_lower"] - 1e7), "birth_lower must lie within"),
        (lambda a: a.update(clutter_covs=np.float64(1e300) * a["clutter_covs"]), "beyond float32"),
        (lambda a: a.update(birth_weights=a["birth_weights"] + 0j), "real numbers"),
        (lambda a: a.update(birth_means=np.full_like(a["birth_means"], np.inf)), "birth_means"),
    ],
)
def test_covariances_bounds_and_magnitudes_are_checked_by_key(tmp_path, learned, mutate, message):
    arrays = valid_arrays(learned)
    mutate(arrays)
    path = tmp_path / "bad.npz"
    write_raw(path, arrays)
    with pytest.raises(FileFormatError, match=message) as info:
        load_context(path)
    assert info.value.path == str(path)


def test_dead_components_and_zero_magnitude_load(tmp_path, learned):
    """A learned context with dead components, and a context without clutter, are valid."""
    birth, clutter = learned
    path = tmp_path / "ok.npz"
    save_context(path, birth, clutter._replace(magnitude=jnp.asarray(0.0)))
    _, loaded, _ = load_context(path)
    assert float(loaded.magnitude) == 0.0


@pytest.mark.parametrize("value", ["NaN", "1e300", '"many"', "-1"])
def test_recorded_magnitudes_are_checked(tmp_path, learned, value):
    metadata = f'{{"format_version": 1, "clutter": {{"magnitude": {value}}}}}'
    arrays = valid_arrays(learned)
    arrays["metadata_json"] = np.asarray(metadata)
    path = tmp_path / "meta.npz"
    write_raw(path, arrays)
    with pytest.raises(FileFormatError, match=r"metadata_json clutter\.magnitude must"):
        load_context(path)
