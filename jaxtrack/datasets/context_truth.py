"""``context_truth.npz``: true birth and clutter intensities saved beside a synthetic sequence.

Layout (NumPy ``.npz``, no pickled objects): every field of the birth
:class:`~jaxtrack.context.intensity.Intensity` as ``birth_<field>`` (``birth_magnitude``,
``birth_uniform_weight``, ``birth_lower``, ``birth_upper``, ``birth_weights``, ``birth_means``,
``birth_covs``), the clutter intensity likewise as ``clutter_<field>``, plus metadata arrays
written by the generator (``seed``, ``config_json``, ``image_size``, ``zone_names``,
``zone_exit``, ``source_names``, ``source_rates``, ``uniform_clutter_rate``). Mixture
component ``m`` of the birth intensity is entry zone ``m``; component ``s`` of the clutter
intensity is clutter source ``s``.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from jaxtrack.context.intensity import Intensity
from jaxtrack.errors import FileFormatError

PREFIXES = ("birth", "clutter")


def save_context_truth(
    path: str | Path,
    birth: Intensity,
    clutter: Intensity,
    metadata: dict[str, np.ndarray] | None = None,
) -> None:
    """Writes the true intensities (and metadata arrays) to an ``.npz`` file.

    Args:
        path: the file to write.
        birth: true birth intensity (6-D state space).
        clutter: true clutter intensity (4-D measurement space).
        metadata: extra named arrays (no object arrays); names must not start with
            ``birth_`` or ``clutter_``.
    """
    arrays = {}
    for prefix, intensity in zip(PREFIXES, (birth, clutter), strict=True):
        for field, value in intensity._asdict().items():
            arrays[f"{prefix}_{field}"] = np.asarray(value)
    for name, value in (metadata or {}).items():
        if name.startswith(tuple(f"{prefix}_" for prefix in PREFIXES)):
            raise ValueError(f"metadata name {name!r} clashes with the intensity fields")
        arrays[name] = np.asarray(value)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as file:
        np.savez(file, **arrays)


def load_context_truth(path: str | Path) -> tuple[Intensity, Intensity]:
    """Reads the true intensities written by :func:`save_context_truth`.

    Args:
        path: a ``context_truth.npz`` file.

    Returns:
        ``(birth_intensity, clutter_intensity)`` with float32 JAX arrays.

    Raises:
        FileFormatError: the file is missing, not an ``.npz`` archive, or lacks a field.
    """
    path = Path(path)
    if not path.is_file():
        raise FileFormatError(path, None, "file not found")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except (OSError, ValueError, zipfile.BadZipFile) as err:
        raise FileFormatError(path, None, f"not a readable .npz archive ({err})") from None
    intensities = []
    for prefix in PREFIXES:
        fields = {}
        for field in Intensity._fields:
            name = f"{prefix}_{field}"
            if name not in arrays:
                raise FileFormatError(path, None, f"missing array {name!r}")
            fields[field] = jnp.asarray(arrays[name], jnp.float32)
        intensities.append(Intensity(**fields))
    return intensities[0], intensities[1]
