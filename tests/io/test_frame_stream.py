"""FrameStream: the reader's frames in any chunks, bounded read-ahead, errors passed on, and
the memory of a streamed run over the whole PETS09 video (vtest.avi)."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import cv2
import jax
import numpy as np
import pytest

from jaxtrack.errors import FileFormatError, InputError
from jaxtrack.filters.base import FRAME_ALIGNMENT, run
from jaxtrack.io.frame_stream import FrameStream
from jaxtrack.io.video import VideoReader
from jaxtrack.types import FrameInputs
from tests.data import REPO_ROOT
from tests.filters.frame_filters import (
    MEAN_COLOUR,
    NUM_FRAMES,
    RED,
    random_detections,
    random_video,
)

VIDEO = random_video(0)


def write_frames(path: Path, frames: np.ndarray) -> Path:
    """RGB frames written losslessly: an FFV1 ``.avi``, or a folder of PNGs."""
    height, width = frames.shape[1:3]
    if path.suffix == ".avi":
        writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), 5.0, (width, height))
        assert writer.isOpened()
        for frame in frames:
            writer.write(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
        writer.release()
    else:
        path.mkdir()
        for k, frame in enumerate(frames, start=1):
            cv2.imwrite(str(path / f"{k:06d}.png"), cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
    return path


@pytest.fixture(params=["clip.avi", "img1"])
def clip(request, tmp_path) -> Path:
    return write_frames(tmp_path / request.param, VIDEO)


def test_stream_gives_the_readers_frames_in_chunks_of_any_length(clip):
    with VideoReader(clip) as reader, FrameStream(reader, 3, 10, lookahead=2) as stream:
        assert (stream.num_frames, stream.height, stream.width) == (8, 24, 32)
        chunks = [stream(0, 3), stream(3, 4), stream(4, 8)]
    assert [c.shape[0] for c in chunks] == [3, 1, 4]
    assert all(c.dtype == np.uint8 for c in chunks)
    np.testing.assert_array_equal(np.concatenate(chunks), VIDEO[2:10])


def test_read_into_an_array(clip):
    with VideoReader(clip) as reader:
        out = np.zeros((24, 32, 3), np.uint8)
        for frame in (1, 2, 5, 3):  # forward, skipping ahead, back (a seek in a video)
            assert reader.read(frame, out=out) is out
            np.testing.assert_array_equal(out, VIDEO[frame - 1])
            np.testing.assert_array_equal(reader.read(frame), VIDEO[frame - 1])
        for bad in (np.zeros((24, 31, 3), np.uint8), np.zeros((24, 32, 3)), out[:, ::-1]):
            with pytest.raises(InputError, match=r"out must be a C-contiguous uint8 array"):
                reader.read(1, out=bad)


def test_chunk_arrays_are_aligned_and_reused_two_calls_later(clip):
    with VideoReader(clip) as reader, FrameStream(reader, 1, NUM_FRAMES, lookahead=2) as stream:
        chunks = [stream(0, 3), stream(3, 6), stream(6, 8), stream(8, 11)]
    assert all(chunk.ctypes.data % FRAME_ALIGNMENT == 0 for chunk in chunks)
    assert np.shares_memory(chunks[0], chunks[2]) and np.shares_memory(chunks[1], chunks[3])
    assert not np.shares_memory(chunks[0], chunks[1])
    np.testing.assert_array_equal(chunks[3], VIDEO[8:11])


def test_streamed_run_equals_the_run_over_frames_in_memory(clip):
    detections = random_detections(1)
    key = jax.random.key(2)
    _, expected = run(MEAN_COLOUR, key, RED, FrameInputs(detections, VIDEO))
    with VideoReader(clip) as reader, FrameStream(reader, 1, NUM_FRAMES, 4) as stream:
        _, streamed = run(MEAN_COLOUR, key, RED, detections, chunk_frames=4, frames=stream)
    jax.tree.map(lambda a, b: np.testing.assert_allclose(a, b, rtol=1e-6), streamed, expected)


class CountingReader:
    """A stand-in reader that counts the frames read (and can fail on one)."""

    path, num_frames, height, width = "counting", NUM_FRAMES, 24, 32

    def __init__(self, fail_at: int | None = None):
        self.reads: list[int] = []
        self.fail_at = fail_at

    def read(self, frame: int, out: np.ndarray) -> np.ndarray:
        if frame == self.fail_at:
            raise FileFormatError(self.path, None, f"frame {frame} does not decode")
        self.reads.append(frame)
        out[...] = VIDEO[frame - 1]
        return out


def wait_for(condition, seconds: float = 5.0) -> None:
    deadline = time.monotonic() + seconds
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.01)


def test_read_ahead_is_bounded_and_close_stops_the_thread():
    reader = CountingReader()
    stream = FrameStream(reader, 1, NUM_FRAMES, lookahead=3)
    wait_for(lambda: len(reader.reads) >= 3)
    time.sleep(0.2)
    assert reader.reads == [1, 2, 3]  # three slots filled, the thread waits for one
    np.testing.assert_array_equal(stream(0, 2), VIDEO[:2])
    wait_for(lambda: len(reader.reads) >= 5)
    time.sleep(0.2)
    assert reader.reads == [1, 2, 3, 4, 5]
    stream.close()
    assert not stream._thread.is_alive()
    with pytest.raises(InputError, match="is closed"):
        stream(2, 3)


def test_a_frame_that_does_not_decode_is_raised_in_the_runner():
    with FrameStream(CountingReader(fail_at=6), 1, NUM_FRAMES, lookahead=2) as stream:
        np.testing.assert_array_equal(stream(0, 4), VIDEO[:4])
        with pytest.raises(FileFormatError, match="counting: frame 6 does not decode"):
            stream(4, 8)


def test_frames_out_of_order_or_outside_the_span_are_errors():
    with pytest.raises(InputError, match=r"frame span 0:3 is outside counting's 1..11"):
        FrameStream(CountingReader(), 0, 3, lookahead=2)
    with pytest.raises(InputError, match=r"frame span 5:12"):
        FrameStream(CountingReader(), 5, 12, lookahead=2)
    with pytest.raises(InputError, match="lookahead must be at least 1"):
        FrameStream(CountingReader(), 1, 3, lookahead=0)
    with FrameStream(CountingReader(), 2, 6, lookahead=2) as stream:
        with pytest.raises(InputError, match=r"expected offsets 0..n with n <= 5, got 1..2"):
            stream(1, 2)
        stream(0, 3)
        with pytest.raises(InputError, match=r"got 3..6"):
            stream(3, 6)
        np.testing.assert_array_equal(stream(3, 5), VIDEO[4:6])


#: Streams vtest.avi (795 frames of 768x576) through the chunked runner with the checksum
#: filter in chunks of the streamed tracker's length; prints the checksum and the process's
#: peak resident memory.
STREAMED_RUN = """
import json, jax
from pathlib import Path
from jaxtrack.filters.base import run
from jaxtrack.io.frame_stream import FrameStream
from jaxtrack.io.video import VideoReader
from jaxtrack.pipelines.stream import STREAM_CHUNK_FRAMES as CHUNK
from tests.filters.frame_filters import CHECKSUM, random_detections
with VideoReader({video!r}) as reader, FrameStream(reader, 1, 795, CHUNK) as stream:
    state, _ = run(CHECKSUM, jax.random.key(0), None, random_detections(0, 795),
                   chunk_frames=CHUNK, frames=stream)
status = Path("/proc/self/status").read_text().splitlines()
peak = next(int(line.split()[1]) * 1024 for line in status if line.startswith("VmHWM:"))
print(json.dumps({{"checksum": int(state), "peak_bytes": peak}}))
"""


def test_a_streamed_run_holds_a_few_chunks_never_the_video(data_root):
    video = data_root / "video" / "vtest.avi"
    script = STREAMED_RUN.format(video=str(video))
    done = subprocess.run(
        [sys.executable, "-c", script], cwd=REPO_ROOT, capture_output=True, text=True, check=True
    )
    result = json.loads(done.stdout.strip().splitlines()[-1])
    checksum = 0
    capture = cv2.VideoCapture(str(video))
    while (frame := capture.read()[1]) is not None:
        checksum += int(frame.sum(dtype=np.uint64))
    capture.release()
    assert result["checksum"] == checksum % 2**32  # every frame went through the filter
    # The process (JAX and OpenCV included, about 0.4 GB before any frame) stays far below
    # the video as float (4.2 GB), and below the video as uint8 (1.05 GB).
    whole_video_float = 795 * 576 * 768 * 3 * 4
    assert result["peak_bytes"] < whole_video_float / 4, result
