"""Saving and loading a learned context (birth and clutter intensities) as ``.npz``.

Layout (NumPy ``.npz``, no pickled objects), the same field naming as
``context_truth.npz`` (:mod:`jaxtrack.datasets.context_truth`): every field of the birth
:class:`~jaxtrack.context.intensity.Intensity` as ``birth_<field>`` (``birth_magnitude``,
``birth_uniform_weight``, ``birth_lower``, ``birth_upper``, ``birth_weights``, ``birth_means``,
``birth_covs``), the clutter intensity likewise as ``clutter_<field>``, and
``metadata_json``: a JSON object (a 0-d string array) holding the caller's metadata (e.g. the
source sequence, training frames, sample counts, magnitudes) plus ``format_version``. A
context learned with ground truth also records the detector's score calibration there
(``score_calibration``: ``scores`` and ``probabilities`` at the knots, and a summary;
:mod:`jaxtrack.context.scores`), checked on loading. A context may also hold the first
frame's intensity (the targets in view, :mod:`jaxtrack.context.learn`) as ``initial_<field>``;
files without it (written before it was learned) still load, with no first-frame intensity.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import jax.numpy as jnp
import numpy as np

from jaxtrack.context.intensity import Intensity
from jaxtrack.context.scores import invalid_calibration
from jaxtrack.context.target_clutter import METADATA_KEY, invalid_target_clutter
from jaxtrack.errors import FileFormatError, InputError
from jaxtrack.limits import FLOAT32_MAX, MAX_COORDINATE, Rule, float32_trouble
from jaxtrack.linalg import cholesky

#: Largest magnitude (events per frame) of a context part: the tracker configuration's limit
#: on its rates (:data:`jaxtrack.filters.phd_tracker.MAX_RATE`, 10^4).
MAX_CONTEXT_MAGNITUDE = 1e4
#: The rule of a magnitude recorded in the metadata (the A3-A5 variants track with it).
MAGNITUDE = Rule("events per frame", float, 0.0, MAX_CONTEXT_MAGNITUDE)

#: Version written into the metadata; :func:`load_context` reads versions up to this one.
FORMAT_VERSION = 1

PREFIXES = ("birth", "clutter")
#: The optional part: the first frame's intensity.
INITIAL = "initial"


def save_context(
    path: str | Path,
    birth: Intensity,
    clutter: Intensity,
    metadata: dict[str, Any] | None = None,
    initial: Intensity | None = None,
) -> None:
    """Writes a learned context to an ``.npz`` file (see the module docstring for the layout).

    Args:
        path: the file to write (parent folders are created).
        birth: the birth intensity ``gamma(x)`` (6-D state space).
        clutter: the clutter intensity ``kappa(z)`` (4-D measurement space).
        metadata: JSON-serialisable values (NumPy scalars and arrays are converted);
            ``format_version`` is added.
        initial: the first frame's intensity (6-D state space), or None.

    Raises:
        TypeError: the metadata is not JSON-serialisable.
    """
    info = dict(metadata or {})
    info["format_version"] = FORMAT_VERSION
    text = json.dumps(info, default=_to_json, sort_keys=True)
    arrays = {"metadata_json": np.asarray(text)}
    parts = [*zip(PREFIXES, (birth, clutter), strict=True)]
    if initial is not None:
        parts.append((INITIAL, initial))
    for prefix, intensity in parts:
        for field, value in intensity._asdict().items():
            arrays[f"{prefix}_{field}"] = np.asarray(value)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as file:
        np.savez(file, **arrays)


def load_context(path: str | Path) -> tuple[Intensity, Intensity, dict[str, Any]]:
    """Reads a context written by :func:`save_context`: ``(birth, clutter, metadata)``
    (:func:`load_context_parts` without the first frame's intensity)."""
    birth, clutter, metadata, _ = load_context_parts(path)
    return birth, clutter, metadata


def load_context_parts(
    path: str | Path,
) -> tuple[Intensity, Intensity, dict[str, Any], Intensity | None]:
    """Reads a context written by :func:`save_context`, checking it on the way.

    Args:
        path: the ``.npz`` file.

    Returns:
        ``(birth, clutter, metadata, initial)``: the intensities with float32 JAX arrays, the
        metadata dict (with ``format_version``) and the first frame's intensity (None when
        the file has no ``initial_*`` field).

    Raises:
        FileFormatError: naming the file and the field, when the file is missing, not an
            ``.npz`` archive, lacks a field, holds invalid metadata, a newer format version, or
            an invalid intensity (an ``initial_*`` field without the others counts as missing
            them). The rules: a magnitude recorded in the metadata (``birth``, ``clutter`` or
            ``initial`` ``magnitude``) in ``[0, 1e4]``; arrays of real numbers with consistent
            shapes, finite and within float32; magnitude in ``[0, 1e4]`` events per frame (0 or a
            normal float32); ``pi_u`` in ``[0, 1]``; ``lower``, ``upper`` and ``means`` within
            ``+-2^20``; ``upper > lower`` on every axis in float32; weights ``>= 0`` with the
            live ones summing to one; every covariance symmetric and positive definite in
            float64 and in float32 (as the filters factor it).
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
    prefixes = [*PREFIXES]
    if any(name.startswith(f"{INITIAL}_") for name in arrays):
        prefixes.append(INITIAL)
    for prefix in (*PREFIXES, INITIAL):
        recorded = metadata.get(prefix)
        if isinstance(recorded, dict) and "magnitude" in recorded:
            try:
                MAGNITUDE.check(f"metadata_json {prefix}.magnitude", recorded["magnitude"])
            except InputError as err:
                raise FileFormatError(path, None, str(err)) from None
    if "score_calibration" in metadata:
        reason = invalid_calibration(metadata["score_calibration"])
        if reason is not None:
            raise FileFormatError(path, None, f"metadata_json: {reason}")
    if METADATA_KEY in metadata:
        reason = invalid_target_clutter(metadata[METADATA_KEY])
        if reason is not None:
            raise FileFormatError(path, None, f"metadata_json: {reason}")
    intensities = []
    for prefix in prefixes:
        fields = {}
        for field in Intensity._fields:
            name = f"{prefix}_{field}"
            if name not in arrays:
                raise FileFormatError(path, None, f"missing field {name!r}")
            fields[field] = arrays[name]
        reason = _invalid_intensity(prefix, fields)
        if reason is not None:
            raise FileFormatError(path, None, reason)
        intensities.append(
            Intensity(**{key: jnp.asarray(value, jnp.float32) for key, value in fields.items()})
        )
    birth, clutter, *initial = intensities
    if initial and initial[0].lower.shape != birth.lower.shape:
        raise FileFormatError(
            path,
            None,
            f"initial_lower has shape {tuple(initial[0].lower.shape)}, expected "
            f"{tuple(birth.lower.shape)} (the first frame's intensity lives in the birth "
            "state space)",
        )
    return birth, clutter, metadata, initial[0] if initial else None


def _invalid_intensity(prefix: str, fields: dict[str, np.ndarray]) -> str | None:
    """Why the arrays do not form a valid :class:`Intensity`, or None when they do.

    The reason starts with the offending field's key in the file (e.g. ``birth_covs[2]``).
    """
    lower = fields["lower"]
    if lower.ndim != 1:
        return f"{prefix}_lower must be 1-D, got shape {lower.shape}"
    weights = fields["weights"]
    if weights.ndim != 1 or weights.shape[0] < 1:
        return f"{prefix}_weights must be 1-D and non-empty, got shape {weights.shape}"
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
            return f"{prefix}_{field} has shape {fields[field].shape}, expected {shape} (dim {dim})"
    for field, value in fields.items():
        if not np.issubdtype(value.dtype, np.number) or np.iscomplexobj(value):
            return f"{prefix}_{field} must hold real numbers, got dtype {value.dtype}"
        if not np.all(np.isfinite(value)):
            return f"{prefix}_{field} must be finite"
        if np.any(np.abs(value.astype(np.float64)) > FLOAT32_MAX):
            return f"{prefix}_{field} holds values beyond float32 (|v| > 3.4e38)"
    fields = {field: value.astype(np.float64) for field, value in fields.items()}
    magnitude, uniform_weight = float(fields["magnitude"]), float(fields["uniform_weight"])
    if not 0 <= magnitude <= MAX_CONTEXT_MAGNITUDE or float32_trouble(magnitude):
        return (
            f"{prefix}_magnitude must lie in [0, {MAX_CONTEXT_MAGNITUDE:g}] events per frame "
            f"(0 or >= 1.2e-38), got {magnitude:g}"
        )
    if not 0 <= uniform_weight <= 1:
        return f"{prefix}_uniform_weight must lie in [0, 1], got {uniform_weight:g}"
    for field in ("lower", "upper", "means"):
        if np.any(np.abs(fields[field]) > MAX_COORDINATE):
            return f"{prefix}_{field} must lie within +-2^20, got {np.abs(fields[field]).max():g}"
    upper32, lower32 = fields["upper"].astype(np.float32), lower.astype(np.float32)
    if not np.all(upper32 > lower32):
        return f"{prefix}_upper must exceed {prefix}_lower on every axis (in float32)"
    if np.any(weights < 0):
        return f"{prefix}_weights must be >= 0"
    total = fields["weights"].sum()
    if uniform_weight < 1 and not np.isclose(total, 1.0, atol=1e-4):
        return f"{prefix}_weights: live weights must sum to 1, got {total}"
    for m, cov in enumerate(fields["covs"]):
        reason = _invalid_covariance(cov)
        if reason is not None:
            return f"{prefix}_covs[{m}] {reason}"
    return None


def _invalid_covariance(cov: np.ndarray) -> str | None:
    """Why ``cov`` is no covariance the filters can factor, or None.

    It must be symmetric (to a relative 1e-5) and positive definite both in float64
    (``numpy.linalg.cholesky``) and in float32 as the filters factor it
    (:func:`jaxtrack.linalg.cholesky`, with a finite log-determinant).
    """
    scale = np.abs(cov).max()
    if np.any(np.abs(cov - cov.T) > 1e-5 * scale):
        return "is not symmetric"
    try:
        np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        return "is not positive definite"
    factor = np.asarray(cholesky(jnp.asarray(cov, jnp.float32)))
    pivots = np.diagonal(factor)
    if not (np.all(np.isfinite(factor)) and np.all(pivots > 0)):
        return "is not positive definite in float32 (too ill-conditioned)"
    if not np.isfinite(np.sum(np.log(pivots.astype(np.float32)))):
        return "has a log-determinant beyond float32"
    return None


def _to_json(value):
    """JSON encoder fallback for NumPy / JAX scalars and arrays."""
    if isinstance(value, np.generic | np.ndarray) or hasattr(value, "__array__"):
        return np.asarray(value).tolist()
    raise TypeError(f"metadata value {value!r} of type {type(value).__name__} is not JSON")
