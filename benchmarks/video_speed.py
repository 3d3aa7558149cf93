"""Speed of the video front end on PETS09-S2L1 (vtest.avi, 768x576, 795 frames).

Times, on this machine (wall clock, best of ``--repeats``):

* ``decode_fps``: decoding every frame (OpenCV) to RGB, nothing else;
* ``detect_fps[method]``: :func:`jaxtrack.detect.pipeline.detect_video` over all frames,
  decoding, background training, masks, blobs and perspective splitting included;
* ``detect_track_fps``: detection (``--method``) plus PHD tracking (the default
  configuration) of frames ``--frames``; ``detect_track_fps_with_compile`` counts the
  tracker's one-off JIT compilation too (a fresh process pays it once).

Prints one JSON object. The goals are ``detect_fps >= 60`` and ``detect_track_fps >= 25`` on 2
CPU cores; timings on a shared machine vary with the other load on it.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import cv2
from timing import best_time

from jaxtrack.detect.pipeline import METHODS, DetectorConfig, detect_video
from jaxtrack.detect.sequence import video_info, video_sequence
from jaxtrack.filters.phd_tracker import PHDConfig, phd_params
from jaxtrack.io import parse_frame_span
from jaxtrack.io.video import VideoReader
from jaxtrack.pipelines.tracking import track_sequences

DEFAULT_VIDEO = (
    Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "video" / "vtest.avi"
)


def decode_all(path: Path) -> int:
    """Decodes every frame to RGB; returns the count."""
    capture = cv2.VideoCapture(str(path))
    count = 0
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)
        count += 1
    capture.release()
    return count


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--video", type=Path, default=DEFAULT_VIDEO)
    parser.add_argument("--repeats", type=int, default=2, help="timed runs (best kept)")
    parser.add_argument("--method", choices=METHODS, default="mog2", help="detector tracked")
    parser.add_argument("--frames", default="401:795", help="span detected and tracked")
    args = parser.parse_args()

    with VideoReader(args.video, fps=7.0) as reader:
        num_frames = reader.num_frames
        info = video_info(reader)
    decode_seconds = best_time(lambda: decode_all(args.video), args.repeats)
    detect_fps = {}
    for method in METHODS:
        seconds = best_time(
            lambda method=method: detect_video(args.video, None, DetectorConfig(method=method)),
            args.repeats,
        )
        detect_fps[method] = round(num_frames / seconds, 1)

    span = parse_frame_span(args.frames, num_frames)
    span_frames = span[1] - span[0] + 1
    start = time.perf_counter()
    found = detect_video(args.video, span, DetectorConfig(method=args.method))
    detect_seconds = time.perf_counter() - start
    sequence = video_sequence(args.video, found.table, span, info)
    params = phd_params(PHDConfig(), info)
    track_times = []
    for _ in range(1 + args.repeats):  # the first run compiles
        start = time.perf_counter()
        track_sequences([sequence], PHDConfig(), 0, [params])
        track_times.append(time.perf_counter() - start)
    result = {
        "video": str(args.video),
        "frames": num_frames,
        "size": [info.im_width, info.im_height],
        "cpu_count": os.cpu_count(),
        "decode_fps": round(num_frames / decode_seconds, 1),
        "detect_fps": detect_fps,
        "tracked_span": list(span),
        "tracked_method": args.method,
        "detect_span_fps": round(span_frames / detect_seconds, 1),
        "track_fps": round(span_frames / min(track_times[1:]), 1),
        "detect_track_fps": round(span_frames / (detect_seconds + min(track_times[1:])), 1),
        "detect_track_fps_with_compile": round(span_frames / (detect_seconds + track_times[0]), 1),
        "note": "wall clock on a shared machine; other load slows it",
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
