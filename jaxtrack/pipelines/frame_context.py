"""The parameters of a tracker that looks at the images, with what it learns from the scene.

A tracker that uses frames may take, as its context, the scene's entry/exit zones (CMT:
``--zones``, else learned on the fly from the PHD tracker's trajectories,
:func:`~jaxtrack.pipelines.zones.tracker_zones`) or the background model's image (the
Hierarchical tracker: the span's median image,
:func:`~jaxtrack.pipelines.background.median_background`, with the span's detections, on
which it estimates its low level's noise). :func:`streamed_params` builds its
parameters with that context, so that ``jaxtrack track``, ``jaxtrack track-video`` and the
experiments run it the same way; :func:`load_tracked_sequence` loads a sequence with the
detections it is tracked on (its own, a file, or background subtraction on its frames).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from jaxtrack.configs import TrackerConfig
from jaxtrack.detect.pipeline import DetectorConfig, detect_video
from jaxtrack.detect.sequence import video_sequence
from jaxtrack.errors import InputError
from jaxtrack.filters.hierarchical_tracker import HierarchicalContext, low_noise
from jaxtrack.filters.registry import build_tracker, tracker_entry
from jaxtrack.io import MotSequence, load_sequence, parse_frame_span, read_mot_file, read_seqinfo
from jaxtrack.io.video import VideoReader
from jaxtrack.pipelines.background import BACKGROUND_FRAMES, median_background
from jaxtrack.pipelines.fusion_context import learn_fusion_context
from jaxtrack.pipelines.zones import tracker_zones


def streamed_params(
    config: TrackerConfig,
    seq: MotSequence,
    reader: VideoReader,
    seed: int = 0,
    zones: str | None = None,
    train_frames: str | None = None,
    blobs: bool = False,
) -> tuple[Any, dict[str, str]]:
    """A frame tracker's parameters for a sequence (span), and what it used.

    Args:
        config: the tracker's configuration.
        seq: the sequence or span tracked (its detections, for zones learned on the fly).
        reader: its open frames (for the background image).
        seed: PRNG seed of the zones' learning.
        zones: a zones file for a tracker that takes zones (default: learned on the fly).
        train_frames: the training span (``"A:B"``) of a tracker that learns from one
            (default: its configuration's share of the tracked span).
        blobs: the detections are the toolkit's background-subtraction blobs (the
            Hierarchical tracker keeps its a priori noise on them,
            :func:`~jaxtrack.filters.hierarchical_tracker.low_noise`).

    Returns:
        The parameters, and ``{"zones": ...}``, ``{"background": ...}`` or
        ``{"training": ...}`` saying what was used (for ``.config.json``; empty for a tracker
        that takes none of them).

    Raises:
        FileFormatError: an unreadable zones file or frame.
    """
    entry = tracker_entry(config.tracker)
    used: dict[str, str] = {}
    context = None
    if entry.takes_zones:
        context, used["zones"] = tracker_zones(seq, zones, seed)
    elif entry.takes_training:
        context = learn_fusion_context(config, seq, train_frames, seed)
        used["training"] = context.description
    elif entry.takes_background:
        span = (seq.first_frame, seq.last_frame)
        used["background"] = (
            f"per-pixel median of {BACKGROUND_FRAMES} frames spread over {span[0]}:{span[1]}"
        )
        noise, used["low_noise"] = low_noise(config, seq.detections, blobs)
        context = HierarchicalContext(median_background(reader, span), noise)
    _, params = build_tracker(config, seq.info, context)
    return params, used


def load_tracked_sequence(sequence_dir, frames=None, detections: str | None = None, reader=None):
    """A sequence folder (or span) with its ``det/det.txt``, or with ``detections`` instead:
    a detections file, ``"det"`` (the folder's own) or ``"bs"`` (background subtraction on
    the sequence's frames, :func:`~jaxtrack.detect.pipeline.detect_video`, which needs the
    open ``reader``).

    Raises:
        FileFormatError: a missing or malformed ``seqinfo.ini`` or detections file.
        InputError: a bad frame span, or ``"bs"`` for a tracker that reads no frames.
    """
    if detections is None or detections == "det":
        return load_sequence(sequence_dir, frames=frames)
    info = read_seqinfo(Path(sequence_dir) / "seqinfo.ini")
    span = parse_frame_span(frames, info.seq_length)
    if detections == "bs":
        if reader is None:
            raise InputError("--detections bs needs a tracker that reads the frames")
        table = detect_video(reader, span, DetectorConfig()).table
    else:
        table = read_mot_file(detections, "det", info=info)
    return video_sequence(sequence_dir, table, span, info)
