"""The parameters of a tracker that looks at the images, with what it learns from the scene.

A tracker that uses frames may take, as its context, the scene's entry/exit zones (CMT:
``--zones``, else learned on the fly from the PHD tracker's trajectories,
:func:`~jaxtrack.pipelines.zones.tracker_zones`) or the background model's image (the
Hierarchical tracker: the span's median image,
:func:`~jaxtrack.pipelines.background.median_background`). :func:`streamed_params` builds its
parameters with that context, so that ``jaxtrack track``, ``jaxtrack track-video`` and the
experiments run it the same way.
"""

from __future__ import annotations

from typing import Any

from jaxtrack.configs import TrackerConfig
from jaxtrack.filters.registry import build_tracker, tracker_entry
from jaxtrack.io import MotSequence
from jaxtrack.io.video import VideoReader
from jaxtrack.pipelines.background import BACKGROUND_FRAMES, median_background
from jaxtrack.pipelines.zones import tracker_zones


def streamed_params(
    config: TrackerConfig,
    seq: MotSequence,
    reader: VideoReader,
    seed: int = 0,
    zones: str | None = None,
) -> tuple[Any, dict[str, str]]:
    """A frame tracker's parameters for a sequence (span), and what it used.

    Args:
        config: the tracker's configuration.
        seq: the sequence or span tracked (its detections, for zones learned on the fly).
        reader: its open frames (for the background image).
        seed: PRNG seed of the zones' learning.
        zones: a zones file for a tracker that takes zones (default: learned on the fly).

    Returns:
        The parameters, and ``{"zones": ...}`` or ``{"background": ...}`` saying what was
        used (for ``.config.json``; empty for a tracker that takes neither).

    Raises:
        FileFormatError: an unreadable zones file or frame.
    """
    entry = tracker_entry(config.tracker)
    used: dict[str, str] = {}
    context = None
    if entry.takes_zones:
        context, used["zones"] = tracker_zones(seq, zones, seed)
    elif entry.takes_background:
        span = (seq.first_frame, seq.last_frame)
        context = median_background(reader, span)
        used["background"] = (
            f"per-pixel median of {BACKGROUND_FRAMES} frames spread over {span[0]}:{span[1]}"
        )
    _, params = build_tracker(config, seq.info, context)
    return params, used
