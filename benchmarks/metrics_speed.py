"""Speed of ``jaxtrack.metrics`` against TrackEval 1.3.0 on the 11 MOT15 sequences.

Generates one seeded tracker output per sequence (a corrupted copy of its ground truth),
writes them in MOT format to a temporary folder, then times, on the same files:

* jaxtrack: read gt + results, every metric (CLEAR, VACE, identity, HOTA, OSPA/GOSPA) per
  sequence, combined row;
* TrackEval: ``Evaluator`` with ``USE_PARALLEL=False`` and CLEAR + Identity + HOTA (+ Count),
  console and file output disabled.

Prints one JSON object: ``{"jaxtrack_s", "trackeval_s", "speedup", "max_abs_diff", ...}``,
times being the best of ``--repeats`` runs and ``max_abs_diff`` the largest difference over
every shared score, sequence and the combined row.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import tempfile
import time
from pathlib import Path

import numpy as np
import trackeval

from jaxtrack.io import read_mot_file, read_seqinfo, write_mot_file
from jaxtrack.metrics import combine_sequences, evaluate_sequence
from jaxtrack.metrics.synthetic import SCENARIOS, corrupt

DEFAULT_DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "mot15"
#: jaxtrack score -> (TrackEval metric, field); HOTA arrays are averaged over thresholds.
SHARED_SCORES = {
    "MOTA": ("CLEAR", "MOTA"),
    "MOTP": ("CLEAR", "MOTP"),
    "FP": ("CLEAR", "CLR_FP"),
    "FN": ("CLEAR", "CLR_FN"),
    "IDSW": ("CLEAR", "IDSW"),
    "Frag": ("CLEAR", "Frag"),
    "MT": ("CLEAR", "MT"),
    "PT": ("CLEAR", "PT"),
    "ML": ("CLEAR", "ML"),
    "Recall": ("CLEAR", "CLR_Re"),
    "Precision": ("CLEAR", "CLR_Pr"),
    "GT_IDs": ("Count", "GT_IDs"),
    "IDF1": ("Identity", "IDF1"),
    "IDP": ("Identity", "IDP"),
    "IDR": ("Identity", "IDR"),
    "HOTA": ("HOTA", "HOTA"),
    "DetA": ("HOTA", "DetA"),
    "AssA": ("HOTA", "AssA"),
    "LocA": ("HOTA", "LocA"),
    "DetRe": ("HOTA", "DetRe"),
    "DetPr": ("HOTA", "DetPr"),
    "AssRe": ("HOTA", "AssRe"),
    "AssPr": ("HOTA", "AssPr"),
}


def run_jaxtrack(data: Path, results: Path, sequences: list[str]) -> dict:
    evaluations = {}
    for name in sequences:
        seq_length = read_seqinfo(data / name / "seqinfo.ini").seq_length
        gt = read_mot_file(data / name / "gt" / "gt.txt", "gt", seq_length)
        result = read_mot_file(results / f"{name}.txt", "res", seq_length)
        evaluations[name] = evaluate_sequence(gt, result, (1, seq_length))
    scores = {name: evaluation.scores() for name, evaluation in evaluations.items()}
    scores["COMBINED_SEQ"] = combine_sequences(evaluations.values()).scores()
    return scores


def run_trackeval(data: Path, trackers: Path, sequences: list[str]) -> dict:
    dataset = trackeval.datasets.MotChallenge2DBox(
        {
            "GT_FOLDER": str(data),
            "TRACKERS_FOLDER": str(trackers),
            "BENCHMARK": "MOT15",
            "SKIP_SPLIT_FOL": True,
            "SEQ_INFO": {name: None for name in sequences},
            "TRACKERS_TO_EVAL": ["bench"],
            "PRINT_CONFIG": False,
        }
    )
    evaluator = trackeval.Evaluator(
        {
            "USE_PARALLEL": False,
            "PRINT_RESULTS": False,
            "PRINT_CONFIG": False,
            "TIME_PROGRESS": False,
            "OUTPUT_SUMMARY": False,
            "OUTPUT_DETAILED": False,
            "PLOT_CURVES": False,
        }
    )
    metrics = [
        trackeval.metrics.CLEAR({"PRINT_CONFIG": False}),
        trackeval.metrics.Identity({"PRINT_CONFIG": False}),
        trackeval.metrics.HOTA(),
    ]
    with contextlib.redirect_stdout(io.StringIO()):
        output, _ = evaluator.evaluate([dataset], metrics)
    return {
        name: by_class["pedestrian"]
        for name, by_class in output[dataset.get_name()]["bench"].items()
    }


def max_abs_diff(ours: dict, theirs: dict) -> float:
    worst = 0.0
    for name, scores in ours.items():
        for key, (metric, field) in SHARED_SCORES.items():
            reference = float(np.mean(theirs[name][metric][field]))
            worst = max(worst, abs(float(scores[key]) - reference))
    return worst


def best_time(function, repeats: int):
    times, value = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        value = function()
        times.append(time.perf_counter() - start)
    return min(times), value


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--data", type=Path, default=DEFAULT_DATA, help="MOT15 root (default ../shared/data/mot15)"
    )
    parser.add_argument(
        "--scenario",
        choices=sorted(SCENARIOS),
        default="noisy",
        help="corruption of the gt (noisy)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the generated results (0)")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs of each, best kept (3)")
    args = parser.parse_args(argv)
    data = args.data.resolve()
    sequences = sorted(p.name for p in data.iterdir() if (p / "seqinfo.ini").is_file())
    with tempfile.TemporaryDirectory() as workdir:
        trackers = Path(workdir) / "trackers"
        results = trackers / "bench" / "data"
        rows = 0
        for index, name in enumerate(sequences):
            gt = read_mot_file(data / name / "gt" / "gt.txt", "gt")
            table = corrupt(gt, SCENARIOS[args.scenario], seed=args.seed + index)
            write_mot_file(results / f"{name}.txt", table)
            rows += len(table)
        jaxtrack_s, ours = best_time(lambda: run_jaxtrack(data, results, sequences), args.repeats)
        trackeval_s, theirs = best_time(
            lambda: run_trackeval(data, trackers, sequences), args.repeats
        )
    report = {
        "jaxtrack_s": round(jaxtrack_s, 4),
        "trackeval_s": round(trackeval_s, 4),
        "speedup": round(trackeval_s / jaxtrack_s, 2),
        "max_abs_diff": max_abs_diff(ours, theirs),
        "sequences": len(sequences),
        "result_rows": rows,
        "scenario": args.scenario,
    }
    print(json.dumps(report))


if __name__ == "__main__":
    main()
