"""Frames of a video decoded ahead of use in a background thread (DESIGN.md, "Frames under
jit"): the frame source of a chunked run (``frames=`` of :func:`~jaxtrack.filters.base.run`).

One thread reads the span's frames in order with a :class:`~jaxtrack.io.video.VideoReader`
(a video file then decodes forward, never seeks) into ``lookahead`` frame slots; the runner
takes them out chunk by chunk. While the filter runs chunk ``k`` on the device, the thread
decodes chunk ``k + 1``: OpenCV and XLA release the GIL, so the two overlap, and the run
takes about the longer of decoding and filtering instead of their sum. Frame by frame
rather than a future per chunk, so that chunks of any length (a ``fit_capacity`` run's
crowded frames) are served from the same read-ahead.

Memory: every array is allocated once, when the stream opens or at its first chunks: the
``lookahead`` frame slots and :data:`RING` chunk arrays, aligned so that the runner reads
them in place (:func:`~jaxtrack.filters.base.aligned_frames`; a copy of each chunk into
fresh memory, whose pages the kernel maps and zeroes again, more than doubled the time per
frame of a cheap filter). A streamed run thus holds :func:`stream_bytes` of images whatever
the video's length (no whole video, no frame as float) and allocates nothing per frame.
"""

from __future__ import annotations

import queue
import threading

import numpy as np

from jaxtrack.errors import InputError
from jaxtrack.filters.base import aligned_frames
from jaxtrack.io.video import VideoReader

#: How often (seconds) a thread waiting for a free slot checks whether the stream was closed.
_POLL_SECONDS = 0.05
#: Chunk arrays the stream fills in turn. The runner is done with a chunk's images when it
#: asks for the chunk after next (:data:`~jaxtrack.filters.base.FrameSource`), so two
#: arrays suffice: one the device may be reading, one being filled.
RING = 2


def stream_bytes(height: int, width: int, chunk_frames: int) -> int:
    """Bytes of images a streamed run holds at most: ``(RING + 2) chunk_frames`` RGB
    ``uint8`` frames (``chunk_frames`` slots decoded ahead, :data:`RING` chunk arrays and the
    runner's copy of the last chunk, padded to ``chunk_frames``).

    Args:
        height: frame height in pixels.
        width: frame width in pixels.
        chunk_frames: frames per chunk, also the read-ahead.
    """
    return (RING + 2) * int(chunk_frames) * int(height) * int(width) * 3


class FrameStream:
    """The frames ``first..last`` of a reader, decoded ahead; a run's frame source.

    ``stream(start, stop)`` returns the frames ``first + start .. first + stop - 1`` (offsets
    from 0, as the run's detections) as RGB ``uint8`` ``[stop - start, height, width, 3]``.
    Frames are handed out once, in order, in one of :data:`RING` arrays filled in turn (a
    returned array is overwritten two calls later). Use as a context manager (or call
    :meth:`close`), which stops the thread; the reader stays open (its owner closes it) and
    must not be read by anyone else while the stream is open.

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
        self._chunks = 0
        self._ring: list[np.ndarray | None] = [None] * RING
        self._slots = np.empty((lookahead, self.height, self.width, 3), np.uint8)
        self._free: queue.Queue = queue.Queue()
        for slot in range(lookahead):
            self._free.put(slot)
        self._decoded: queue.Queue = queue.Queue()
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._decode, name="frame-stream", daemon=True)
        self._thread.start()

    def _decode(self) -> None:
        """The thread: every frame of the span in order into a free slot, or the error that
        stopped it, onto the decoded queue."""
        try:
            for frame in range(self._first, self._first + self.num_frames):
                slot = self._free_slot()
                if slot is None:
                    return
                self._reader.read(frame, out=self._slots[slot])
                self._decoded.put(slot)
        except Exception as err:  # raised again by __call__, in the runner's thread
            self._decoded.put(err)

    def _free_slot(self) -> int | None:
        """A slot once one is free; None when the stream was closed meanwhile."""
        while not self._closed.is_set():
            try:
                return self._free.get(timeout=_POLL_SECONDS)
            except queue.Empty:
                continue
        return None

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
        images = self._chunk_array(stop - start)
        for k in range(stop - start):
            slot = self._decoded.get()
            if isinstance(slot, Exception):
                self.close()
                raise slot
            images[k] = self._slots[slot]
            self._free.put(slot)
        self._next = stop
        return images

    def _chunk_array(self, count: int) -> np.ndarray:
        """The next of the :data:`RING` chunk arrays, grown to ``count`` frames if needed."""
        index = self._chunks % RING
        self._chunks += 1
        if self._ring[index] is None or self._ring[index].shape[0] < count:
            self._ring[index] = aligned_frames(count, self.height, self.width)
        return self._ring[index][:count]

    def close(self) -> None:
        """Stops the thread (it finishes the frame it is decoding)."""
        self._closed.set()
        self._thread.join()

    def __enter__(self) -> FrameStream:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()
