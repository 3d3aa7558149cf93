"""The background model's image of a frame span, for trackers that compare targets with it.

The Hierarchical tracker ranks its colour features by how well they tell a target from the
background behind it (Sec. 5.2: the background histogram ``q`` comes "from the background
model"). Its background image is the per-pixel median of :data:`BACKGROUND_FRAMES` frames
spread evenly over the tracked span, the robust mean that the Horprasert detector's model
starts from (:mod:`jaxtrack.detect.horprasert`): people walking through a few of the frames
do not enter it. It is computed once per run, host side, and given to the tracker as its
context (:attr:`~jaxtrack.filters.registry.TrackerEntry.takes_background`).
"""

from __future__ import annotations

import numpy as np

from jaxtrack.detect.pipeline import training_frames
from jaxtrack.io.video import VideoReader

#: Frames whose per-pixel median is the background image (the detector's default
#: ``train_frames``).
BACKGROUND_FRAMES = 25


def median_background(
    reader: VideoReader, span: tuple[int, int], count: int = BACKGROUND_FRAMES
) -> np.ndarray:
    """The per-pixel median of ``count`` frames spread evenly over ``span`` (all of them if it
    is shorter), RGB ``uint8`` ``[height, width, 3]``.

    Args:
        reader: the open frames.
        span: ``(first, last)`` 1-based inclusive.
        count: frames to take the median of.

    Raises:
        FileFormatError: a frame that does not decode.
    """
    frames = training_frames(reader, span, count, 1.0)
    return np.median(frames, axis=0).round().astype(np.uint8)
