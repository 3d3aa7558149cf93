"""Detections of a video as a :class:`~jaxtrack.io.MotSequence`, for the tracker and learner.

A video has no ``seqinfo.ini``: the sequence information comes from the video itself (name
= file stem, size, frame count, frame rate from the reader, with its override).
"""

from __future__ import annotations

from pathlib import Path

from jaxtrack.errors import InputError
from jaxtrack.io.motchallenge import (
    MotSequence,
    MotTable,
    SequenceInfo,
    pad_detections,
    pad_ground_truth,
    read_mot_file,
)


def video_sequence(
    video: str | Path,
    detections: MotTable,
    frames: tuple[int, int],
    info: SequenceInfo,
    gt: MotTable | str | Path | None = None,
) -> MotSequence:
    """A frame span of a video with its detections (and ground truth) as a sequence.

    Args:
        video: the video file or image folder (kept as the sequence's path).
        detections: the detections; rows outside ``frames`` are dropped.
        frames: ``(first, last)`` 1-based inclusive span.
        info: the video's :class:`SequenceInfo` (see :func:`video_info`).
        gt: ground truth (a table or a MOTChallenge gt file), or None.

    Returns:
        The sequence, padded detections included.

    Raises:
        FileFormatError: a malformed gt file.
        InputError: a span outside the video.
    """
    first, last = frames
    if not 1 <= first <= last <= info.seq_length:
        raise InputError(f"frame span {first}:{last} outside the video's 1..{info.seq_length}")
    num_frames = last - first + 1
    det_table = detections.frame_span(first, last)
    gt_table = None
    ground_truth = None
    if gt is not None:
        if not isinstance(gt, MotTable):
            gt = read_mot_file(gt, "gt", info=info)
        gt_table = gt.frame_span(first, last)
        ground_truth = pad_ground_truth(gt_table, first, num_frames)
    return MotSequence(
        path=Path(video),
        info=info,
        first_frame=first,
        last_frame=last,
        det_table=det_table,
        gt_table=gt_table,
        detections=pad_detections(det_table, first, num_frames),
        ground_truth=ground_truth,
    )


def video_info(reader) -> SequenceInfo:
    """The :class:`SequenceInfo` of an open :class:`~jaxtrack.io.video.VideoReader`."""
    return SequenceInfo(
        name=Path(reader.path).stem,
        seq_length=reader.num_frames,
        im_width=reader.width,
        im_height=reader.height,
        frame_rate=reader.fps,
    )
