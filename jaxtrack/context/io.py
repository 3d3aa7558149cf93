"""Saving and loading a learned context (birth and clutter intensities) as ``.npz``.

Layout (NumPy ``.npz``, no pickled objects), the same field naming as
``context_truth.npz`` (:mod:`jaxtrack.datasets.context_truth`): every field of the birth
:class:`~jaxtrack.context.intensity.Intensity` as ``birth_<field>`` (``birth_magnitude``,
``birth_uniform_weight``, ``birth_lower``, ``birth_upper``, ``birth_weights``, ``birth_means``,
``birth_covs``), the clutter intensity likewise as ``clutter_<field>``, and
``metadata_json``: a JSON object (a 0-d string array) holding the caller's metadata (e.g. the
source sequence, training frames, sample counts, magnitudes) plus ``format_version``.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import jax.numpy as jnp
import numpy as np

from jaxtrack.context.intensity import Intensity
from jaxtrack.errors import FileFormatError

#: Version written into the metadata; :func:`load_context` reads versions up to this one.
FORMAT_VERSION = 1

PREFIXES = ("birth", "clutter")


def save_context(
    path: str | Path, birth: Intensity, clutter: Intensity, metadata: dict[str, Any] | None = None
) -> None:
    """Writes a learned context to an ``.npz`` file (see the module docstring for the layout).

    Args:
        path: the file to write (parent folders are created).
        birth: the birth intensity ``gamma(x)`` (6-D state space).
        clutter: the clutter intensity ``kappa(z)`` (4-D measurement space).
        metadata: JSON-serialisable values (NumPy scalars and arrays are converted);
            ``format_version`` is added.

    Raises:
        TypeError: the metadata is not JSON-serialisable.
    """
    info = dict(metadata or {})
    info["format_version"] = FORMAT_VERSION
    text = json.dumps(info, default=_to_json, sort_keys=True)
    arrays = {"metadata_json": np.asarray(text)}
    for prefix, intensity in zip(PREFIXES, (birth, clutter), strict=True):
        for field, value in intensity._asdict().items():
            arrays[f"{prefix}_{field}"] = np.asarray(value)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as file:
        np.savez(file, **arrays)


def load_context(path: str | Path) -> tuple[Intensity, Intensity, dict[str, Any]]:
    """Reads a context written by :func:`save_context`, checking it on the way.

    Args:
        path: the ``.npz`` file.

    Returns:
        ``(birth, clutter, metadata)``: the intensities with float32 JAX arrays and the
        metadata dict (with ``format_version``).

    Raises:
        FileFormatError: the file is missing, not an ``.npz`` archive, lacks a field, holds
            invalid metadata, a newer format version, or an invalid intensity (inconsistent
            shapes, non-finite values, magnitude < 0, ``pi_u`` outside ``[0, 1]``, an empty
            volume, negative weights or live weights not summing to one).
    """
    path = Path(path)
    if not path.is_file():
        raise FileFormatError(path, None, "file not found")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as err:
        raise FileFormatError(path, None, f"not a readable .npz archive ({err})") from None
    if "metadata_json" not in arrays:
        raise FileFormatError(path, None, "missing field 'metadata_json'")
    try:
        metadata = json.loads(str(arrays["metadata_json"]))
    except json.JSONDecodeError as err:
        raise FileFormatError(path, None, f"metadata_json is not valid JSON ({err})") from None
    if not isinstance(metadata, dict):
        raise FileFormatError(path, None, "metadata_json must hold a JSON object")
    version = metadata.get("format_version")
    if not isinstance(version, int) or not 1 <= version <= FORMAT_VERSION:
        raise FileFormatError(
            path, None, f"unsupported format_version {version!r} (this reader: {FORMAT_VERSION})"
        )
    intensities = []
    for prefix in PREFIXES:
        fields = {}
        for field in Intensity._fields:
            name = f"{prefix}_{field}"
            if name not in arrays:
                raise FileFormatError(path, None, f"missing field {name!r}")
            fields[field] = arrays[name]
        reason = _invalid_intensity(fields)
        if reason is not None:
            raise FileFormatError(path, None, f"{prefix} intensity: {reason}")
        intensities.append(
            Intensity(**{key: jnp.asarray(value, jnp.float32) for key, value in fields.items()})
        )
    birth, clutter = intensities
    return birth, clutter, metadata


def _invalid_intensity(fields: dict[str, np.ndarray]) -> str | None:
    """Why the arrays do not form a valid :class:`Intensity`, or None when they do."""
    lower = fields["lower"]
    if lower.ndim != 1:
        return f"lower must be 1-D, got shape {lower.shape}"
    weights = fields["weights"]
    if weights.ndim != 1 or weights.shape[0] < 1:
        return f"weights must be 1-D and non-empty, got shape {weights.shape}"
    dim, num = lower.shape[0], weights.shape[0]
    expected = {
        "magnitude": (),
        "uniform_weight": (),
        "upper": (dim,),
        "means": (num, dim),
        "covs": (num, dim, dim),
    }
    for field, shape in expected.items():
        if fields[field].shape != shape:
            return f"{field} has shape {fields[field].shape}, expected {shape} (dim {dim})"
    for field, value in fields.items():
        if not np.issubdtype(value.dtype, np.number) or not np.all(np.isfinite(value)):
            return f"{field} must be finite numbers"
    if fields["magnitude"] < 0:
        return "magnitude must be >= 0"
    if not 0 <= fields["uniform_weight"] <= 1:
        return "uniform_weight must lie in [0, 1]"
    if not np.all(fields["upper"] > lower):
        return "upper must exceed lower on every axis"
    if np.any(weights < 0):
        return "weights must be >= 0"
    if fields["uniform_weight"] < 1 and not np.isclose(weights.sum(), 1.0, atol=1e-4):
        return f"live weights must sum to 1, got {weights.sum()}"
    return None


def _to_json(value):
    """JSON encoder fallback for NumPy / JAX scalars and arrays."""
    if isinstance(value, np.generic | np.ndarray) or hasattr(value, "__array__"):
        return np.asarray(value).tolist()
    raise TypeError(f"metadata value {value!r} of type {type(value).__name__} is not JSON")
