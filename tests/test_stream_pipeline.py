"""track_streamed and the tracking pipeline's rules for trackers that use frames: the right
runner for each kind of tracker, frames of the sequence's size, memory counted with the
stream's images."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from jaxtrack import resources
from jaxtrack.detect.sequence import video_sequence
from jaxtrack.errors import InputError, InputWarning
from jaxtrack.filters.hierarchical_tracker import HierarchicalConfig
from jaxtrack.filters.kalman_tracker import KalmanConfig
from jaxtrack.filters.registry import TRACKERS
from jaxtrack.io.frame_stream import stream_bytes
from jaxtrack.io.video import VideoReader
from jaxtrack.pipelines.stream import STREAM_CHUNK_FRAMES, track_streamed
from jaxtrack.pipelines.tracking import (
    check_tracking_memory,
    track_sequences,
    warn_if_overflow,
)
from jaxtrack.resources import ResourceError
from jaxtrack.types import MotTable, SequenceInfo
from tests.filters.frame_filters import MEAN_COLOUR_ENTRY, MeanColourConfig, numpy_mean_colours
from tests.synthetic_video import NUM_FRAMES, SIZE, person_box, write_synthetic_folder


@pytest.fixture(autouse=True)
def mean_colour_tracker(monkeypatch):
    monkeypatch.setitem(TRACKERS, "mean-colour", MEAN_COLOUR_ENTRY)


@pytest.fixture
def walk(tmp_path):
    """The synthetic walking rectangle (img1/) and its box as the detections, frames 5..30."""
    folder = write_synthetic_folder(tmp_path / "img1")
    boxes = [person_box(k) for k in range(1, NUM_FRAMES + 1)]
    table = MotTable.from_arrays(np.arange(1, NUM_FRAMES + 1), -np.ones(NUM_FRAMES), boxes)
    info = SequenceInfo("walk", NUM_FRAMES, *SIZE, 25.0)
    return folder, video_sequence(folder, table, (5, 30), info)


def test_track_streamed_scores_each_box_with_its_mean_red(walk):
    folder, seq = walk
    with VideoReader(folder) as reader:
        rows = track_streamed(seq, reader, MeanColourConfig(), chunk_frames=8)
        frames = {k: reader.read(k) for k in range(5, 31)}
    np.testing.assert_array_equal(rows.frames, np.arange(5, 31))
    for frame, box, score in zip(rows.frames, rows.boxes, rows.confs, strict=True):
        expected = numpy_mean_colours(frames[frame], box[None])[0, 0]
        assert score == pytest.approx(expected, rel=1e-5)


def test_each_kind_of_tracker_has_its_runner(walk):
    folder, seq = walk
    with pytest.raises(InputError, match="mean-colour tracker uses frames: run it with"):
        track_sequences([seq], MeanColourConfig())
    with VideoReader(folder) as reader:
        with pytest.raises(InputError, match="kalman tracker reads no frames"):
            track_streamed(seq, reader, KalmanConfig())
        small = video_sequence(folder, seq.det_table, (5, 30), SequenceInfo("s", 40, 200, 120))
        with pytest.raises(InputError, match="frames are 240x120 but s is 200x120"):
            track_streamed(small, reader, MeanColourConfig())


def test_memory_check_counts_the_streams_images(walk, monkeypatch):
    _, seq = walk
    config = MeanColourConfig()
    chunk = STREAM_CHUNK_FRAMES
    tracker = MEAN_COLOUR_ENTRY.memory(config, 16, chunk).run_bytes(seq.num_frames)
    images = stream_bytes(SIZE[1], SIZE[0], chunk)
    assert images == 4 * chunk * 240 * 120 * 3
    monkeypatch.setattr(resources, "available_memory_bytes", lambda: tracker + images)
    check_tracking_memory([seq], config, chunk)
    monkeypatch.setattr(resources, "available_memory_bytes", lambda: tracker + images - 1)
    with pytest.raises(ResourceError, match="tracking walk"):
        check_tracking_memory([seq], config, chunk)


def test_full_tables_warn_with_the_frames_and_the_slot_settings(walk):
    """Two detections per frame and one slot per level: the second never starts a track,
    and the run says so (first frame, the settings and what to raise them to)."""
    folder, seq = walk
    boxes = [person_box(k) for k in range(1, NUM_FRAMES + 1)]
    second = [(x + 60.0, y, w, h) for x, y, w, h in boxes]
    frames = np.arange(1, NUM_FRAMES + 1)
    table = MotTable.from_arrays(
        np.concatenate([frames, frames]), -np.ones(2 * NUM_FRAMES), boxes + second
    )
    crowded = video_sequence(folder, table, (5, 30), seq.info)
    for variant in ("managed", "full"):
        config = HierarchicalConfig(variant=variant, max_tracks=1, max_trackers=1)
        with VideoReader(folder) as reader:
            with pytest.warns(InputWarning, match=r"first: frame 5\) the hierarchical") as got:
                track_streamed(crowded, reader, config)
        message = str(got[0].message)
        assert "max_tracks=1, max_trackers=1" in message
        assert '{"max_tracks": 2, "max_trackers": 2}' in message


def test_no_overflow_warning_without_flags_or_full_frames():
    seq = type("Seq", (), {"info": SequenceInfo("s", 3, 10, 10), "first_frame": 1})()
    config = HierarchicalConfig()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_if_overflow(seq, None, config)
        warn_if_overflow(seq, np.zeros((2, 3), bool), config)
    with pytest.warns(InputWarning, match=r"on 2 frame\(s\) \(first: frame 2\)"):
        # batch axes: a frame counts once whichever member overflowed
        warn_if_overflow(seq, np.array([[False, True, False], [False, True, True]]), config)
