"""One crowded frame must not slow a whole run (issue 14): ``jaxtrack track`` on a sequence
with and without one frame of many extra detections.

Copies a sequence's ``seqinfo.ini`` and ``det/det.txt`` into a temporary folder twice, adds
``--count`` detections (spread over the image, 40x80 px, score 0.5) to frame ``--frame`` of
the second copy, and times ``jaxtrack track`` on each in a fresh process (import, load,
compile and run: what a user waits for), alternating the two ``--repeats`` times and keeping
the best of each. Prints one JSON object on the last line with both times and their ratio
(goal: ``ratio <= 1.5``). Before per-chunk capacities every frame was padded to the crowded
frame's 501 slots (4.2x on TUD-Campus with 500 extra detections).
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

DEFAULT_SEQUENCE = (
    Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "mot15" / "TUD-Campus"
)


def make_copies(sequence: Path, root: Path, frame: int, count: int) -> tuple[Path, Path]:
    """The plain copy and the crowded copy of ``sequence`` under ``root``."""
    folders = []
    for name in ("plain", "crowded"):
        folder = root / name
        (folder / "det").mkdir(parents=True)
        shutil.copy(sequence / "seqinfo.ini", folder / "seqinfo.ini")
        shutil.copy(sequence / "det" / "det.txt", folder / "det" / "det.txt")
        folders.append(folder)
    rng = np.random.default_rng(0)
    rows = [
        f"{frame},-1,{x:.1f},{y:.1f},40,80,0.5,-1,-1,-1\n"
        for x, y in zip(rng.uniform(0, 560, count), rng.uniform(0, 380, count), strict=True)
    ]
    with (folders[1] / "det" / "det.txt").open("a") as file:
        file.writelines(rows)
    return folders[0], folders[1]


def track_seconds(folder: Path, out: Path) -> float:
    """Wall-clock seconds of ``jaxtrack track folder`` in a fresh process."""
    start = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "jaxtrack", "track", str(folder), "--out", str(out), "--quiet"],
        check=True,
        capture_output=True,
    )
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sequence", type=Path, default=DEFAULT_SEQUENCE)
    parser.add_argument("--frame", type=int, default=30, help="frame that gets the crowd")
    parser.add_argument("--count", type=int, default=500, help="extra detections on it")
    parser.add_argument("--repeats", type=int, default=2, help="timed runs of each (best kept)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        plain, crowded = make_copies(args.sequence, root, args.frame, args.count)
        times = {"plain": [], "crowded": []}
        for _ in range(args.repeats):
            for name, folder in (("plain", plain), ("crowded", crowded)):
                times[name].append(track_seconds(folder, root / f"{name}.txt"))
        rows = {
            name: sum(1 for _ in (root / f"{name}.txt").open()) for name in ("plain", "crowded")
        }
    best = {name: min(values) for name, values in times.items()}
    print(
        json.dumps(
            {
                "sequence": args.sequence.name,
                "crowded_frame": args.frame,
                "extra_detections": args.count,
                "plain_seconds": round(best["plain"], 2),
                "crowded_seconds": round(best["crowded"], 2),
                "ratio": round(best["crowded"] / best["plain"], 3),
                "rows": rows,
            }
        )
    )


if __name__ == "__main__":
    main()
