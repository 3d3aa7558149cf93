"""Frames of a video decoded ahead of use in a background thread (DESIGN.md, "Frames under
jit"): the frame source of a chunked run (``frames=`` of :func:`~jaxtrack.filters.base.run`).

One thread reads the span's frames in order with a :class:`~jaxtrack.io.video.VideoReader`
(a video file then decodes forward, never seeks) into a queue of at most ``lookahead``
frames; the runner takes them out chunk by chunk. While the filter runs chunk ``k`` on the
device, the thread decodes chunk ``k + 1``: OpenCV and XLA release the GIL, so the two
overlap, and the run takes about the longer of decoding and filtering instead of their sum.
A frame-by-frame queue rather than a future per chunk, so that chunks of any length (a
``fit_capacity`` run's crowded frames) are served from the same read-ahead.

Memory: the queue holds ``lookahead`` frames and the runner at most three chunks of
``chunk_frames`` (the one it is filling, the one queued on the device and the one running),
so a streamed run holds about :func:`stream_bytes` of images, whatever the video's length;
no whole video, and no frame as float, is ever held.
"""

from __future__ import annotations

import queue
import threading

import numpy as np

from jaxtrack.errors import InputError
from jaxtrack.io.video import VideoReader

#: How often (seconds) a thread waiting on a full queue checks whether the stream was closed.
_POLL_SECONDS = 0.05


def stream_bytes(height: int, width: int, chunk_frames: int) -> int:
    """Bytes of images a streamed run holds at most: ``4 chunk_frames + 1`` RGB ``uint8``
    frames (``chunk_frames`` queued ahead, one being decoded, three chunks in the runner).

    Args:
        height: frame height in pixels.
        width: frame width in pixels.
        chunk_frames: frames per chunk, also the read-ahead.
    """
    return (4 * int(chunk_frames) + 1) * int(height) * int(width) * 3


class FrameStream:
    """The frames ``first..last`` of a reader, decoded ahead; a run's frame source.

    ``stream(start, stop)`` returns the frames ``first + start .. first + stop - 1`` (offsets
    from 0, as the run's detections) as RGB ``uint8`` ``[stop - start, height, width, 3]``.
    Frames are handed out once, in order. Use as a context manager (or call :meth:`close`),
    which stops the thread; the reader stays open (its owner closes it) and must not be read
    by anyone else while the stream is open.

    Args:
        reader: an open video file or image folder.
        first: 1-based number of the first frame.
        last: 1-based number of the last frame (inclusive).
        lookahead: frames decoded ahead of the runner at most (e.g. the chunk length).

    Attributes:
        num_frames: frames of the span, ``last - first + 1``.
        height: frame height in pixels.
        width: frame width in pixels.

    Raises:
        InputError: a span outside ``1..reader.num_frames`` or a lookahead below 1.
    """

    def __init__(self, reader: VideoReader, first: int, last: int, lookahead: int):
        if not 1 <= first <= last <= reader.num_frames:
            raise InputError(
                f"frame span {first}:{last} is outside {reader.path}'s 1..{reader.num_frames}"
            )
        if lookahead < 1:
            raise InputError(f"lookahead must be at least 1 frame, got {lookahead}")
        self.num_frames = last - first + 1
        self.height, self.width = reader.height, reader.width
        self._reader = reader
        self._first = first
        self._next = 0
        self._queue: queue.Queue = queue.Queue(maxsize=lookahead)
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._decode, name="frame-stream", daemon=True)
        self._thread.start()

    def _decode(self) -> None:
        """The thread: every frame of the span in order, or the error that stopped it."""
        try:
            for frame in range(self._first, self._first + self.num_frames):
                if not self._put(self._reader.read(frame)):
                    return
        except Exception as err:  # raised again by __call__, in the runner's thread
            self._put(err)

    def _put(self, item) -> bool:
        """Queues ``item`` once there is room; False when the stream was closed meanwhile."""
        while not self._closed.is_set():
            try:
                self._queue.put(item, timeout=_POLL_SECONDS)
                return True
            except queue.Full:
                continue
        return False

    def __call__(self, start: int, stop: int) -> np.ndarray:
        """The frames at offsets ``start..stop-1`` (the next ones not yet handed out).

        Raises:
            InputError: offsets out of order, or past the span.
            FileFormatError: a frame that does not decode (as the reader raised it).
        """
        if self._closed.is_set():
            raise InputError(f"the frame stream of {self._reader.path} is closed")
        if start != self._next or not start < stop <= self.num_frames:
            raise InputError(
                f"frames are streamed in order: expected offsets {self._next}..n with "
                f"n <= {self.num_frames}, got {start}..{stop}"
            )
        images = np.empty((stop - start, self.height, self.width, 3), np.uint8)
        for k in range(stop - start):
            item = self._queue.get()
            if isinstance(item, Exception):
                self.close()
                raise item
            images[k] = item
        self._next = stop
        return images

    def close(self) -> None:
        """Stops the thread (it finishes the frame it is decoding) and drops queued frames."""
        self._closed.set()
        self._thread.join()
        while not self._queue.empty():
            self._queue.get_nowait()

    def __enter__(self) -> FrameStream:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()
