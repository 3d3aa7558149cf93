"""Running a tracker that looks at the images: its frames streamed through the chunked runner.

A tracker whose registry entry ``uses_frames`` steps on
:class:`~jaxtrack.types.FrameInputs` (the padded detections and the frame, ``uint8 H x W x
3``). :func:`track_streamed` runs it like :func:`~jaxtrack.pipelines.tracking.track_sequences`
runs the others (the same key, per-chunk detection capacities, per-frame outputs and result
rows), with :func:`~jaxtrack.filters.base.run`'s ``frames`` read from a
:class:`~jaxtrack.io.frame_stream.FrameStream`: the next chunk is decoded in a background
thread while the current one runs, and a run holds about
:func:`~jaxtrack.io.frame_stream.stream_bytes` of images whatever the video's length. One
compile per frame size, chunk length and detection capacity.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax

from jaxtrack.configs import TrackerConfig
from jaxtrack.errors import InputError
from jaxtrack.filters.base import FrameOutput, run
from jaxtrack.filters.registry import build_tracker, tracker_entry, writes_events
from jaxtrack.io import MotSequence
from jaxtrack.io.frame_stream import FrameStream
from jaxtrack.io.video import VideoReader
from jaxtrack.metrics.events import EventRows
from jaxtrack.pipelines.events import event_outputs, event_rows, merge_identities
from jaxtrack.pipelines.tracking import (
    check_tracking_memory,
    output_rows,
    track_outputs,
    warn_if_no_tracks,
    warn_if_overflow,
)
from jaxtrack.types import MotTable

#: Frames per compiled call of a streamed run: 32 frames of 768x576 are 42 MB of images, and
#: a run holds at most four chunks of them (``stream_bytes``). Chunks of 16, 32 and 128
#: frames streamed vtest.avi equally fast (870-910 frames/s), 128 with 0.5 GB more memory
#: (``benchmarks/stream_speed.py``).
STREAM_CHUNK_FRAMES = 32


def track_streamed(
    seq: MotSequence,
    video: VideoReader,
    config: TrackerConfig,
    seed: int = 0,
    params: Any = None,
    chunk_frames: int = STREAM_CHUNK_FRAMES,
) -> MotTable:
    """Tracks a sequence (or span) with a tracker that uses frames, its frames streamed.

    :func:`track_streamed_events` without the event rows (a tracker's merged identities are
    merged all the same).

    Args:
        seq: the loaded sequence; its ``seqinfo.ini`` size is the frames' size.
        video: its open frames, frame ``k`` being MOT frame ``k`` (e.g.
            :func:`~jaxtrack.io.video.open_sequence_frames`); read from ``seq.first_frame``
            to ``seq.last_frame`` and left open.
        config: the tracker's configuration (its registry entry must use frames).
        seed: PRNG seed (key ``PRNGKey(seed)``, as
            :func:`~jaxtrack.pipelines.tracking.track_sequences` uses).
        params: the tracker's parameters (default: the registry's for the sequence).
        chunk_frames: frames per compiled call, and frames decoded ahead.

    Returns:
        The result rows (the configuration's ``output``); a sequence with detections but no
        rows warns (:func:`~jaxtrack.pipelines.tracking.warn_if_no_tracks`).

    Raises:
        InputError: a tracker that does not use frames, or frames of another size than
            ``seq.info`` says.
        ResourceError: the run would need more memory than the machine has, before it runs.
        FileFormatError: a frame that does not decode.
    """
    return track_streamed_events(seq, video, config, seed, params, chunk_frames, events=False)[0]


def track_streamed_events(
    seq: MotSequence,
    video: VideoReader,
    config: TrackerConfig,
    seed: int = 0,
    params: Any = None,
    chunk_frames: int = STREAM_CHUNK_FRAMES,
    events: bool = True,
) -> tuple[MotTable, EventRows | None]:
    """:func:`track_streamed`, and for a tracker that ``writes_events`` the event state of
    every result row (:func:`~jaxtrack.pipelines.events.event_rows`; None for the others,
    or without ``events``): :func:`streamed_rows` of the run's outputs.

    Raises:
        InputError, ResourceError, FileFormatError: as :func:`track_streamed`.
    """
    outputs = streamed_outputs(seq, video, config, seed, params, chunk_frames, rows_output(config))
    return streamed_rows(outputs, seq, config, events)[:2]


def rows_output(config: TrackerConfig) -> FrameOutput:
    """The per-frame output :func:`streamed_rows` needs of the configuration's tracker: the
    event outputs for a tracker that ``writes_events``, else the tracks and candidates."""
    return event_outputs if writes_events(config) else track_outputs


def check_frame_tracker(
    seq: MotSequence, video: VideoReader, config: TrackerConfig, instead: str
) -> None:
    """Refuses a tracker that reads no frames (naming the function to use ``instead``) and
    frames of another size than the sequence's ``seqinfo.ini`` says.

    Raises:
        InputError: naming the tracker, or the video and both sizes.
    """
    if not tracker_entry(config.tracker).uses_frames:
        raise InputError(f"the {config.tracker} tracker reads no frames; use {instead}")
    if (video.width, video.height) != (seq.info.im_width, seq.info.im_height):
        raise InputError(
            f"{video.path}: frames are {video.width}x{video.height} but {seq.info.name} is "
            f"{seq.info.im_width}x{seq.info.im_height}"
        )


class StreamedRows(NamedTuple):
    """What :func:`streamed_rows` makes of a run: the result rows, the event rows (or
    None) and the per-frame outputs with merged identities merged (for drawing)."""

    rows: MotTable
    events: EventRows | None
    outputs: Any


def streamed_rows(
    outputs: Any, seq: MotSequence, config: TrackerConfig, events: bool = True, warn: bool = True
) -> StreamedRows:
    """The result rows of a streamed run's per-frame outputs and, for a tracker that
    ``writes_events`` (with ``events``), the event state of every row.

    For such a tracker the identities its re-associations merged are merged first
    (:func:`~jaxtrack.pipelines.events.merge_identities`); with ``warn``, a sequence with
    detections but no rows warns (:func:`~jaxtrack.pipelines.tracking.warn_if_no_tracks`).
    """
    if writes_events(config):
        outputs = merge_identities(jax.device_get(outputs))
    rows = output_rows(outputs, config, seq.first_frame, seq.detections)
    if warn:
        warn_if_no_tracks(seq, rows, config)
        warn_if_overflow(seq, getattr(outputs, "overflow", None), config)
    if not (events and writes_events(config)):
        return StreamedRows(rows, None, outputs)
    size = (seq.info.im_width, seq.info.im_height)
    written = event_rows(outputs, rows, seq.first_frame, seq.info.frame_rate, size)
    return StreamedRows(rows, written, outputs)


def streamed_outputs(
    seq: MotSequence,
    video: VideoReader,
    config: TrackerConfig,
    seed: int = 0,
    params: Any = None,
    chunk_frames: int = STREAM_CHUNK_FRAMES,
    frame_output: FrameOutput = track_outputs,
) -> Any:
    """Runs a tracker that uses frames on a sequence (or span), its frames streamed, and
    returns what ``frame_output`` keeps of each frame, stacked over frames.

    Args:
        seq, video, config, seed, params, chunk_frames: as :func:`track_streamed`.
        frame_output: the per-frame output (``frame_output`` of
            :func:`~jaxtrack.filters.base.run`; e.g. one that keeps the particles to draw
            them); :func:`~jaxtrack.pipelines.tracking.output_rows` reads its ``tracks`` and
            ``candidates``.

    Returns:
        The per-frame outputs, stacked over the span's frames.

    Raises:
        InputError, ResourceError, FileFormatError: as :func:`track_streamed`.
    """
    check_frame_tracker(seq, video, config, "track_sequences")
    check_tracking_memory([seq], config, chunk_frames)
    filt, default_params = build_tracker(config, seq.info)
    with FrameStream(video, seq.first_frame, seq.last_frame, chunk_frames) as frames:
        _, info = run(
            filt,
            jax.random.PRNGKey(seed),
            default_params if params is None else params,
            seq.detections,
            chunk_frames=chunk_frames,
            fit_capacity=True,
            frame_output=frame_output,
            frames=frames,
        )
    return info
