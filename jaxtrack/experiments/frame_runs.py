"""The run loop of the experiments on the video sequences: every (sequence, detection
source) pair, opened once, tracked by every compared tracker as ``jaxtrack track`` does.

:func:`frame_tracker_runs` opens a sequence's frames once per detection source (:data:`SOURCES`),
loads the detections (the folder's own, or background subtraction on the frames,
:func:`~jaxtrack.pipelines.frame_context.load_tracked_sequence`, written beside the results
as ``det.txt``), and runs each tracker with the experiment's seed: a tracker that reads the
frames with its learned context (:func:`~jaxtrack.pipelines.frame_context.streamed_params`)
and its frames streamed, the others on the detections alone. It yields one
:class:`FrameRun` per tracker; the experiment scores and writes it.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import NamedTuple

from tqdm import tqdm

from jaxtrack.configs import TrackerConfig
from jaxtrack.experiments.cmt_ablation import ExperimentSequence
from jaxtrack.filters.registry import build_tracker, tracker_entry
from jaxtrack.io import MotSequence, MotTable, load_sequence, write_mot_file
from jaxtrack.io.video import open_sequence_frames
from jaxtrack.metrics.events import EventRows
from jaxtrack.pipelines.frame_context import load_tracked_sequence, streamed_params
from jaxtrack.pipelines.stream import track_streamed_events
from jaxtrack.pipelines.tracking import track_sequences

#: Detection sources: the sequence's own detections, background subtraction on its frames.
SOURCES = ("det", "bs")


class FrameRun(NamedTuple):
    """One tracker's run on one sequence with one detection source.

    Attributes:
        sequence: the sequence.
        source: the detection source (:data:`SOURCES`).
        name: the tracker's name (a key of the experiment's trackers).
        loaded: the sequence (span) with its own detections and ground truth (scored on).
        folder: ``OUT/sequences/SEQUENCE/SOURCE``, where the run's files go.
        rows: the result rows.
        events: the event rows of a tracker that writes events, else None.
        used: what the tracker's context was (``streamed_params``'s description).
        seconds: the tracking time (compile included; context learning excluded).
        detections: the detections tracked (the source's: ``loaded``'s own, or the ``bs``
            detections written to ``folder/det.txt``).
    """

    sequence: ExperimentSequence
    source: str
    name: str
    loaded: MotSequence
    folder: Path
    rows: MotTable
    events: EventRows | None
    used: dict[str, str]
    seconds: float
    detections: MotTable


def frame_tracker_runs(
    sequences: Sequence[ExperimentSequence],
    trackers: Mapping[str, TrackerConfig],
    out: Path,
    seed: int = 0,
    progress: bool = False,
) -> Iterator[FrameRun]:
    """Runs every tracker on every sequence and source (module docstring).

    Args:
        sequences: the sequences (:func:`~jaxtrack.experiments.cmt_ablation.experiment_sequences`).
        trackers: name -> configuration, run in this order.
        out: the experiment's output folder (``sequences/SEQ/SOURCE/`` created in it; the
            ``bs`` detections written there as ``det.txt``).
        seed: the trackers' seed (and that of their context learning).
        progress: a progress bar over the (sequence, source) pairs.

    Yields:
        One :class:`FrameRun` per (sequence, source, tracker), in that nesting order.
    """
    pairs = [(sequence, source) for sequence in sequences for source in SOURCES]
    for sequence, source in tqdm(pairs, desc="sequences", unit="run", disable=not progress):
        loaded = load_sequence(sequence.folder, sequence.frames)
        with open_sequence_frames(sequence.folder, loaded.info, sequence.video) as reader:
            tracked = loaded
            folder = out / "sequences" / sequence.name / source
            folder.mkdir(parents=True, exist_ok=True)
            if source == "bs":
                tracked = load_tracked_sequence(sequence.folder, sequence.frames, "bs", reader)
                write_mot_file(folder / "det.txt", tracked.det_table)
            for name, config in trackers.items():
                used: dict[str, str] = {}
                if tracker_entry(config.tracker).uses_frames:
                    params, used = streamed_params(
                        config, tracked, reader, seed, blobs=source == "bs"
                    )
                    begin = time.perf_counter()
                    rows, events = track_streamed_events(tracked, reader, config, seed, params)
                else:
                    _, params = build_tracker(config, tracked.info)
                    begin = time.perf_counter()
                    (rows,), events = track_sequences([tracked], config, seed, [params]), None
                seconds = time.perf_counter() - begin
                yield FrameRun(
                    sequence,
                    source,
                    name,
                    loaded,
                    folder,
                    rows,
                    events,
                    used,
                    seconds,
                    tracked.det_table,
                )
