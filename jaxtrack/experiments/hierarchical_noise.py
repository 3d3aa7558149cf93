"""The Hierarchical low level's noise on the development split: a priori vs estimated.

The evidence for ``HierarchicalConfig.noise`` (:mod:`~jaxtrack.filters.hier_low_noise`),
reproducible: the managed low level (``variant="managed"``, which does not look at the
images) runs on the MOT15 training sequences that have no video (:func:`development_sequences`:
all but :data:`~jaxtrack.experiments.cmt_ablation.VIDEO_SEQUENCES`, which the Hierarchical
experiment holds out) on their own detections, with

* :data:`SETTINGS`: the a priori noise and the estimated one, each with every detection and
  with the detections scoring at least :data:`SCORE_THRESHOLD` (the Kalman baseline's
  threshold);
* the Kalman bank (``variant="kalman"``, the baseline's default preset) for reference.

Each step gets a 1 x 1 blank frame (the managed low level never reads it). The table has,
per setting, the scores pooled over the sequences (TrackEval's combination) and, per
sequence, the estimated noise's gate calibration factor.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from tqdm import tqdm

from jaxtrack.errors import InputError
from jaxtrack.experiments.cmt_ablation import VIDEO_SEQUENCES
from jaxtrack.experiments.common import (
    environment,
    environment_lines,
    evaluate_rows,
    markdown_table,
    score_summary,
)
from jaxtrack.filters.base import run
from jaxtrack.filters.hierarchical_tracker import (
    HierarchicalConfig,
    HierarchicalContext,
    build_hierarchical,
    low_noise,
)
from jaxtrack.io import MotSequence, load_sequence
from jaxtrack.metrics.evaluate import combine_sequences
from jaxtrack.pipelines.tracking import output_rows
from jaxtrack.types import FrameInputs

#: The Kalman baseline's score threshold, the second value of ``min_score`` compared.
SCORE_THRESHOLD = 0.9
#: Setting name -> configuration of the managed low level.
SETTINGS: dict[str, HierarchicalConfig] = {
    "a priori": HierarchicalConfig(variant="managed", noise="default"),
    "estimated": HierarchicalConfig(variant="managed", noise="estimated"),
    f"a priori, score >= {SCORE_THRESHOLD}": HierarchicalConfig(
        variant="managed", noise="default", min_score=SCORE_THRESHOLD
    ),
    f"estimated, score >= {SCORE_THRESHOLD}": HierarchicalConfig(
        variant="managed", noise="estimated", min_score=SCORE_THRESHOLD
    ),
}
#: The reference row.
KALMAN = "Kalman bank"
#: The table's columns.
COLUMNS = ("setting", "MOTA", "IDF1", "HOTA", "IDSW", "FP", "FN")
#: Frames of each sequence in a quick run.
QUICK_FRAMES = 60


def development_folders(data: str | Path) -> list[Path]:
    """The MOT15 training sequences of ``data/mot15`` other than the held-out video ones.

    Raises:
        InputError: none found.
    """
    root = Path(data) / "mot15"
    folders = sorted(
        p
        for p in root.glob("*")
        if (p / "gt" / "gt.txt").is_file() and p.name not in VIDEO_SEQUENCES
    )
    if not folders:
        held_out = ", ".join(VIDEO_SEQUENCES)
        raise InputError(f"{root}: no MOT15 training sequences besides {held_out}")
    return folders


def development_sequences(data: str | Path, quick: bool = False) -> list[MotSequence]:
    """:func:`development_folders` loaded (quick: the first two, their first
    :data:`QUICK_FRAMES` frames)."""
    folders = development_folders(data)
    if quick:
        return [load_sequence(p, frames=f"1:{QUICK_FRAMES}") for p in folders[:2]]
    return [load_sequence(p) for p in folders]


def detection_rows(config: HierarchicalConfig, seq: MotSequence, noise=None):
    """The result rows of a Hierarchical variant that does not read the images (``managed``,
    ``kalman``) on a sequence's detections (blank frames), with the low level's ``noise``
    (:func:`~jaxtrack.filters.hierarchical_tracker.low_noise`; None: the a priori noise)."""
    background = np.zeros((seq.info.im_height, seq.info.im_width, 3), np.uint8)
    context = HierarchicalContext(background, noise)
    filt, params = build_hierarchical(config, seq.info, context)
    frames = jnp.zeros((seq.num_frames, 1, 1, 3), jnp.uint8)
    inputs = FrameInputs(seq.detections, frames)
    _, info = jax.jit(lambda p, i: run(filt, jax.random.key(0), p, i))(params, inputs)
    return output_rows(jax.device_get(info), config, seq.first_frame)


def run_experiment(
    out_dir: str | Path, data: str | Path, quick: bool = False, progress: bool = True
) -> dict[str, Any]:
    """Runs every setting and the Kalman bank on the development sequences; writes
    ``table.md`` and ``results.json`` into ``out_dir`` and returns the record."""
    start = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    sequences = development_sequences(data, quick)
    configs = {**SETTINGS, KALMAN: HierarchicalConfig(variant="kalman")}
    evaluations: dict[str, list] = {name: [] for name in configs}
    noise: dict[str, str] = {}
    for seq in tqdm(sequences, desc="sequences", unit="seq", disable=not progress):
        for name, config in configs.items():
            low = None  # the Kalman bank has no low-level noise
            if name in SETTINGS:
                low, line = low_noise(config, seq.detections)
                if name == "estimated":
                    noise[seq.info.name] = line
            evaluations[name].append(evaluate_rows(seq, detection_rows(config, seq, low)))
    rows = []
    for name, evals in evaluations.items():
        rows.append({"setting": name, **score_summary(combine_sequences(evals))})
    record = {
        "quick": quick,
        "sequences": [s.info.name for s in sequences],
        "held_out": list(VIDEO_SEQUENCES),
        "rows": rows,
        "estimated_noise": noise,
        "seconds": round(time.perf_counter() - start, 1),
        "environment": environment(),
    }
    (out / "results.json").write_text(json.dumps(record, indent=1) + "\n")
    (out / "table.md").write_text(table_markdown(record))
    return record


def table_markdown(record: dict[str, Any]) -> str:
    """The record as markdown: the pooled table, then each sequence's estimated noise."""
    lines = [
        "# Hierarchical low level: a priori vs estimated noise (development split)",
        "",
        f"Managed low level on {', '.join(record['sequences'])} (pooled; "
        f"held out, not run: {', '.join(record['held_out'])}).",
        "",
        markdown_table(record["rows"], COLUMNS),
        "",
        "## Estimated noise per sequence",
        "",
    ]
    lines += [f"- {name}: {line}" for name, line in record["estimated_noise"].items()]
    lines += [f"\n{line}" for line in environment_lines(record)]  # after a blank line
    return "\n".join(lines) + "\n"
