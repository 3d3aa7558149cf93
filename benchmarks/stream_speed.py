"""Frames streamed through the chunked runner: speed and peak memory on PETS09-S2L1.

A no-op frame filter (it adds up each frame's pixel values, so every frame is really read
on the device, and does nothing else) runs over every frame of ``vtest.avi`` (795 frames of
768x576) with :func:`jaxtrack.filters.base.run`'s ``frames`` read from a
:class:`jaxtrack.io.frame_stream.FrameStream` (decoded a chunk ahead in a background
thread), decoding included. Reports, on this machine:

* ``stream_frames_per_s``: frames per second of the streamed run at the chunk length
  ``jaxtrack track`` uses (:data:`jaxtrack.pipelines.stream.STREAM_CHUNK_FRAMES`), best of
  ``--repeats`` after a run that compiles; ``by_chunk`` the same per chunk length, with the
  first run (compile included);
* ``decode_frames_per_s``: decoding alone (:class:`~jaxtrack.io.video.VideoReader`, RGB),
  which bounds the streamed run;
* ``peak_rss_mb``: the peak resident memory (``VmHWM``) of a fresh process that streams the
  whole video at each chunk length, of one that only runs the first chunk (the JAX and
  OpenCV runtime, compile included), and of one that decodes the whole video into one
  ``uint8`` array; beside them the video's size as ``uint8`` and as float32.

Prints one JSON object on its last line. The goal is ``stream_frames_per_s >= 200`` on 2 CPU
cores; timings on a shared machine vary with the other load on it (``load_average``).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.filters.base import Filter, run
from jaxtrack.io.frame_stream import FrameStream, stream_bytes
from jaxtrack.io.video import VideoReader
from jaxtrack.pipelines.stream import STREAM_CHUNK_FRAMES
from jaxtrack.types import Detections

DEFAULT_VIDEO = (
    Path(__file__).resolve().parents[1].parent / "shared" / "data" / "video" / "vtest.avi"
)
MB = 1 << 20


def checksum_filter() -> Filter:
    """The no-op frame filter: state = running (wrapping ``uint32``) sum of every pixel."""

    def init(key, params):
        del key, params
        return jnp.zeros((), jnp.uint32)

    def step(key, state, params, inputs):
        del key, params
        total = jnp.sum(inputs.frame, dtype=jnp.uint32)
        return state + total, total

    return Filter(init, step)


NO_OP = checksum_filter()


def stream_run(video: Path, chunk_frames: int, num_frames: int | None = None) -> int:
    """Streams the video's first ``num_frames`` (default all) through the runner; the sum."""
    with VideoReader(video) as reader:
        count = num_frames or reader.num_frames
        no_detections = Detections(
            np.zeros((count, 16, 4), np.float32),
            np.zeros((count, 16), np.float32),
            np.zeros((count, 16), bool),
        )
        with FrameStream(reader, 1, count, chunk_frames) as frames:
            state, _ = run(
                NO_OP,
                jax.random.key(0),
                None,
                no_detections,
                chunk_frames=chunk_frames,
                frames=frames,
            )
    return int(state)


def decode_all(video: Path, keep: bool = False) -> np.ndarray | None:
    """Decodes every frame (RGB, in order); with ``keep``, all of them in one ``uint8``
    array."""
    with VideoReader(video) as reader:
        shape = (reader.num_frames, reader.height, reader.width, 3)
        frames = np.empty(shape, np.uint8) if keep else None
        for k in range(reader.num_frames):
            image = reader.read(k + 1)
            if keep:
                frames[k] = image
    return frames


def checksum_of(video: Path) -> int:
    """The wrapping ``uint32`` sum of every pixel value of the video, decoded directly."""
    with VideoReader(video) as reader:
        total = sum(int(reader.read(k + 1).sum(dtype=np.uint64)) for k in range(reader.num_frames))
    return total % 2**32


def timed(function) -> float:
    start = time.perf_counter()
    function()
    return time.perf_counter() - start


def peak_rss(video: Path, mode: str, chunk_frames: int = STREAM_CHUNK_FRAMES) -> float:
    """Peak resident memory (MB) of a fresh process running ``mode`` (see ``--peak``)."""
    done = subprocess.run(
        [
            sys.executable,
            __file__,
            "--video",
            str(video),
            "--peak",
            mode,
            "--chunk",
            str(chunk_frames),
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    return float(done.stdout.strip().splitlines()[-1])


def measure_peak(video: Path, mode: str, chunk_frames: int) -> float:
    """Runs ``mode`` in this (fresh) process; its ``VmHWM`` in MB."""
    if mode == "stream":
        stream_run(video, chunk_frames)
    elif mode == "first-chunk":
        stream_run(video, chunk_frames, chunk_frames)
    else:
        decode_all(video, keep=True)
    status = Path("/proc/self/status").read_text().splitlines()
    return next(int(line.split()[1]) * 1024 for line in status if line.startswith("VmHWM:")) / MB


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--video", type=Path, default=DEFAULT_VIDEO)
    parser.add_argument("--chunks", default="16,32,128", help="chunk lengths, comma-separated")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs (best kept)")
    parser.add_argument(
        "--peak", choices=("stream", "first-chunk", "decode-all"), help=argparse.SUPPRESS
    )
    parser.add_argument("--chunk", type=int, default=STREAM_CHUNK_FRAMES, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.peak:
        print(measure_peak(args.video, args.peak, args.chunk))
        return

    load = os.getloadavg()
    with VideoReader(args.video) as reader:
        num_frames, size = reader.num_frames, (reader.width, reader.height)
    checksum = checksum_of(args.video)
    decode = min(timed(lambda: decode_all(args.video)) for _ in range(args.repeats))
    chunks = sorted({int(c) for c in args.chunks.split(",")} | {STREAM_CHUNK_FRAMES})
    by_chunk = {}
    for chunk in chunks:
        first = timed(lambda chunk=chunk: stream_run(args.video, chunk))
        assert stream_run(args.video, chunk) == checksum, "a frame was lost or changed"
        best = min(
            timed(lambda chunk=chunk: stream_run(args.video, chunk)) for _ in range(args.repeats)
        )
        by_chunk[chunk] = {
            "frames_per_s": round(num_frames / best, 1),
            "frames_per_s_first_run": round(num_frames / first, 1),
            "peak_rss_mb": round(peak_rss(args.video, "stream", chunk)),
            "stream_images_mb": round(stream_bytes(size[1], size[0], chunk) / MB),
        }
    uint8_bytes = num_frames * size[0] * size[1] * 3
    result = {
        "video": str(args.video),
        "frames": num_frames,
        "size": list(size),
        "cpu_count": os.cpu_count(),
        "load_average": [round(x, 2) for x in load],
        "chunk_frames": STREAM_CHUNK_FRAMES,
        "stream_frames_per_s": by_chunk[STREAM_CHUNK_FRAMES]["frames_per_s"],
        "decode_frames_per_s": round(num_frames / decode, 1),
        "by_chunk": by_chunk,
        "peak_rss_mb": {
            **{f"stream_chunk_{c}": v["peak_rss_mb"] for c, v in by_chunk.items()},
            "first_chunk_only": round(peak_rss(args.video, "first-chunk", STREAM_CHUNK_FRAMES)),
            "decode_whole_video_uint8": round(peak_rss(args.video, "decode-all")),
        },
        "video_uint8_mb": round(uint8_bytes / MB),
        "video_float32_mb": round(4 * uint8_bytes / MB),
        "goal_frames_per_s": 200,
        "note": "wall clock on a shared machine; other load slows it",
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
