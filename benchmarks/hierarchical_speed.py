"""The Hierarchical tracker end to end on PETS09-S2L1 (768x576, ``vtest.avi``).

What ``jaxtrack track-video vtest.avi --tracker hierarchical`` does, timed in its parts:

* ``detect_s``: decoding and background subtraction of every frame
  (:func:`jaxtrack.detect.pipeline.detect_video`, default settings);
* ``background_s``: the background model's image (the median of 25 frames,
  :func:`jaxtrack.pipelines.background.median_background`);
* ``track_s``: both levels over every frame, the frames decoded again and streamed
  (:func:`jaxtrack.pipelines.stream.track_streamed_events`, the default
  :class:`~jaxtrack.filters.hierarchical_tracker.HierarchicalConfig`, ``full``), events and
  offline output rows included; the best of ``--repeats`` runs after a first one that
  compiles (``track_first_s``).

``frames_per_s`` = frames / (detect_s + background_s + track_s): the end-to-end rate after
compilation; ``frames_per_s_with_compile`` counts the compiling run instead. Also
``track_only_frames_per_s`` (tracking with its decoding, no detection) and
``managed_frames_per_s`` (the low level alone, for the cost of the high level).

Prints one JSON object on its last line. The goal is ``frames_per_s >= 25`` on 2 CPU cores
(``taskset -c 0,1``); timings on a shared machine vary with its other load
(``load_average``).
"""

from __future__ import annotations

import json
import os

from timing import timed, video_run_parser

from jaxtrack.detect.pipeline import DetectorConfig, detect_video
from jaxtrack.detect.sequence import video_info, video_sequence
from jaxtrack.filters.hierarchical_tracker import HierarchicalConfig
from jaxtrack.io.video import VideoReader
from jaxtrack.pipelines.frame_context import streamed_params
from jaxtrack.pipelines.stream import track_streamed_events


def main() -> None:
    parser = video_run_parser(__doc__.split("\n")[0], sequence=False)
    args = parser.parse_args()

    with VideoReader(str(args.video)) as reader:
        info = video_info(reader)
        span = (1, args.frames or reader.num_frames)
        detect_s, found = timed(lambda: detect_video(reader, span, DetectorConfig()))
        sequence = video_sequence(str(args.video), found.table, span, info)
        rates = {}
        for variant in ("full", "managed"):
            config = HierarchicalConfig(variant=variant)
            background_s, (params, _) = timed(
                lambda config=config: streamed_params(config, sequence, reader)
            )

            def track(config=config, params=params):
                return track_streamed_events(sequence, reader, config, 0, params)

            first_s, (rows, _) = timed(track)
            track_s = min(timed(track)[0] for _ in range(args.repeats))
            rates[variant] = (background_s, first_s, track_s, len(rows.frames))
    frames = span[1] - span[0] + 1
    background_s, first_s, track_s, boxes = rates["full"]
    result = {
        "video": str(args.video),
        "frames": frames,
        "boxes": boxes,
        "detect_s": round(detect_s, 2),
        "background_s": round(background_s, 2),
        "track_first_s": round(first_s, 2),
        "track_s": round(track_s, 2),
        "track_only_frames_per_s": round(frames / track_s, 1),
        "managed_frames_per_s": round(frames / rates["managed"][2], 1),
        "frames_per_s_with_compile": round(frames / (detect_s + background_s + first_s), 1),
        "load_average": os.getloadavg()[0],
        "frames_per_s": round(frames / (detect_s + background_s + track_s), 1),
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
