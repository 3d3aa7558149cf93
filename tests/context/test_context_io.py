"""Saving and loading a learned context: round trip, metadata, and every kind of bad file."""

from __future__ import annotations

import json

import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.context.intensity import log_intensity, uniform_intensity
from jaxtrack.context.io import FORMAT_VERSION, load_context, save_context
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
