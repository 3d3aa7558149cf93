"""The two speed goals of the appearance ground (issue 16), in one JSON line.

Runs, each in a fresh process on the same machine one after the other:

* ``benchmarks/appearance_features.py``: features of 16 targets x 64 particles (top/bottom
  joint RGB histograms, 8 bins per channel) per 768x576 PETS09-S2L1 frame inside a jitted
  ``lax.scan`` -> ``features_ms_per_frame`` (goal <= 2 ms on 2 CPU cores);
* ``benchmarks/stream_speed.py``: every frame of ``vtest.avi`` streamed through the chunked
  runner with a no-op frame filter, decoding included -> ``stream_frames_per_s`` (goal >= 200).

Each script's own JSON object (variants, accuracy, peak memory per chunk length, load) is
kept under ``features`` and ``stream``. Options: ``--quick`` (fewer frames and repeats in
both). Prints one JSON object on its last line.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def last_json(script: str, *args: str) -> dict:
    """The JSON object on the last line of ``python benchmarks/<script> <args>``."""
    done = subprocess.run(
        [sys.executable, str(HERE / script), *args], capture_output=True, text=True, check=True
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer frames and repeats")
    args = parser.parse_args()
    features = last_json("appearance_features.py", *(["--quick"] if args.quick else []))
    stream = last_json(
        "stream_speed.py", *(["--repeats", "1", "--chunks", "32"] if args.quick else [])
    )
    result = {
        "features_ms_per_frame": features["features_ms_per_frame"],
        "stream_frames_per_s": stream["stream_frames_per_s"],
        "goals": {"features_ms_per_frame": 2.0, "stream_frames_per_s": 200},
        "features": features,
        "stream": stream,
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
