"""``context_truth.npz``: the true intensities saved beside a synthetic sequence.

The file is an ordinary context file (:func:`jaxtrack.context.io.save_context` layout), so the
true context can be used wherever a learned one can; its metadata holds the seed, the scene
configuration, zone and clutter-source names and rates. Mixture component ``m`` of the birth
intensity is entry zone ``m``; component ``s`` of the clutter intensity is clutter source ``s``.
"""

from __future__ import annotations

from pathlib import Path

from jaxtrack.context.intensity import Intensity
from jaxtrack.context.io import load_context


def load_context_truth(path: str | Path) -> tuple[Intensity, Intensity]:
    """Reads the true ``(birth_intensity, clutter_intensity)`` of a synthetic scene.

    Raises:
        FileFormatError: the file is missing, unreadable or invalid.
    """
    birth, clutter, _ = load_context(path)
    return birth, clutter
