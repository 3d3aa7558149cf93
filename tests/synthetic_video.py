"""A synthetic image folder: one coloured rectangle walking right over a textured background."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

NUM_FRAMES = 40
SIZE = (240, 120)  # width, height
PERSON = (12, 32)  # width, height of the walking rectangle


def person_box(frame: int) -> tuple[int, int, int, int]:
    """``(x, y, w, h)`` of the synthetic person in 1-based frame ``frame``."""
    return 10 + 5 * (frame - 1), 60, *PERSON


def write_synthetic_folder(folder: Path) -> Path:
    """Textured static background with one coloured rectangle walking right."""
    rng = np.random.default_rng(0)
    background = rng.uniform(70, 180, size=(SIZE[1], SIZE[0], 3))
    folder.mkdir()
    for k in range(1, NUM_FRAMES + 1):
        image = background + rng.normal(0, 2, background.shape)
        x, y, w, h = person_box(k)
        image[y : y + h, x : x + w] = (200, 30, 40)
        cv2.imwrite(str(folder / f"{k:06d}.png"), np.clip(image, 0, 255).astype(np.uint8))
    return folder
