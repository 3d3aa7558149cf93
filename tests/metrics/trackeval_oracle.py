"""TrackEval 1.3.0 as a test oracle: runs its MOTChallenge evaluation on tables in a temp dir."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np
import trackeval
from trackeval.datasets import MotChallenge2DBox

from jaxtrack.io import write_mot_file

#: jaxtrack score -> (TrackEval metric, field); HOTA fields are averaged over alphas.
FIELD_MAP = {
    "MOTA": ("CLEAR", "MOTA"),
    "MOTP": ("CLEAR", "MOTP"),
    "FP": ("CLEAR", "CLR_FP"),
    "FN": ("CLEAR", "CLR_FN"),
    "TP": ("CLEAR", "CLR_TP"),
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
    "IDTP": ("Identity", "IDTP"),
    "IDFN": ("Identity", "IDFN"),
    "IDFP": ("Identity", "IDFP"),
    "HOTA": ("HOTA", "HOTA"),
    "DetA": ("HOTA", "DetA"),
    "AssA": ("HOTA", "AssA"),
    "LocA": ("HOTA", "LocA"),
    "DetRe": ("HOTA", "DetRe"),
    "DetPr": ("HOTA", "DetPr"),
    "AssRe": ("HOTA", "AssRe"),
    "AssPr": ("HOTA", "AssPr"),
}
COUNT_KEYS = ("FP", "FN", "TP", "IDSW", "Frag", "MT", "PT", "ML", "GT_IDs", "IDTP", "IDFN", "IDFP")


class CentreDistanceMot(MotChallenge2DBox):
    """TrackEval's MOT dataset with its Euclidean similarity on box centres."""

    zero_distance = 2.0

    def _calculate_similarities(self, gt_dets_t, tracker_dets_t):
        gt_centres = gt_dets_t[:, :2] + gt_dets_t[:, 2:4] / 2
        tracker_centres = tracker_dets_t[:, :2] + tracker_dets_t[:, 2:4] / 2
        return self._calculate_euclidean_similarity(
            gt_centres, tracker_centres, zero_distance=self.zero_distance
        )


def run_trackeval(
    gt_root,
    results: dict,
    workdir,
    benchmark: str = "MOT15",
    threshold: float = 0.5,
    seq_lengths: dict | None = None,
    centre_threshold: float | None = None,
) -> dict:
    """TrackEval's per-sequence and combined scores, mapped to jaxtrack's names.

    Args:
        gt_root: folder with ``<SEQ>/gt/gt.txt`` and ``<SEQ>/seqinfo.ini``.
        results: ``{sequence: MotTable}`` tracker outputs.
        workdir: an empty temporary folder.
        benchmark: ``"MOT15"`` (no preprocessing) or ``"MOT17"`` (distractor rules).
        threshold: CLEAR and Identity ``THRESHOLD``.
        seq_lengths: ``{sequence: length}``; default read from seqinfo.ini.
        centre_threshold: match by centre distance (TrackEval's Euclidean similarity with
            zero distance ``2 * centre_threshold``).

    Returns:
        ``{sequence or "COMBINED_SEQ": {score: value}}`` plus ``"HOTA_arrays"`` per entry.
    """
    data_dir = Path(workdir) / "trackers" / "oracle" / "data"
    for sequence, table in results.items():
        write_mot_file(data_dir / f"{sequence}.txt", table)
    if seq_lengths is None:
        seq_lengths = {sequence: None for sequence in results}
    dataset_class = MotChallenge2DBox
    if centre_threshold is not None:
        dataset_class = type(
            "Centre", (CentreDistanceMot,), {"zero_distance": 2 * centre_threshold}
        )
    dataset = dataset_class(
        {
            "GT_FOLDER": str(gt_root),
            "TRACKERS_FOLDER": str(Path(workdir) / "trackers"),
            "BENCHMARK": benchmark,
            "SKIP_SPLIT_FOL": True,
            "SEQ_INFO": dict(seq_lengths),
            "TRACKERS_TO_EVAL": ["oracle"],
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
        trackeval.metrics.CLEAR({"THRESHOLD": threshold, "PRINT_CONFIG": False}),
        trackeval.metrics.Identity({"THRESHOLD": threshold, "PRINT_CONFIG": False}),
        trackeval.metrics.HOTA(),
    ]
    with contextlib.redirect_stdout(io.StringIO()):
        output, _ = evaluator.evaluate([dataset], metrics)
    raw = output[dataset.get_name()]["oracle"]
    scores = {}
    for sequence, by_class in raw.items():
        fields = by_class["pedestrian"]
        entry = {}
        for key, (metric, field) in FIELD_MAP.items():
            value = fields[metric][field]
            entry[key] = float(np.mean(value)) if metric == "HOTA" else value
        entry["HOTA_arrays"] = {k: np.asarray(v) for k, v in fields["HOTA"].items()}
        scores[sequence] = entry
    return scores
