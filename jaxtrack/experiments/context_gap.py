"""UM against GM on the scene bank: what learned context gains or loses on held-out families.

For each scene family of :mod:`jaxtrack.datasets.scene_bank` and seed, the scene is written
(:func:`~jaxtrack.datasets.scene_bank.write_family_scene`) and run through the context
ablation's protocol (:mod:`jaxtrack.experiments.ablation`): context is learned on the first
half (:func:`~jaxtrack.experiments.common.learn_split`: births from a UM tracker run,
clutter from the ground truth), then the PHD tracker tracks the second half with uniform
intensities (UM) and with the learned ones (GM, :data:`~jaxtrack.filters.phd_tracker.VARIANTS`)
and both are scored (:func:`~jaxtrack.experiments.common.score_summary`). The table is the
baseline for learners meant to generalise beyond the default scene's model family (issue 15).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from jaxtrack.datasets.scene_bank import FAMILIES, SEEDS, write_family_scene
from jaxtrack.experiments.common import (
    COUNT_KEYS,
    QUICK_TRACKER_CONFIG,
    SCORE_KEYS,
    evaluate_rows,
    learn_split,
    markdown_table,
    output_folder,
    percent_difference,
    score_summary,
    split_halves,
    write_csv,
)
from jaxtrack.filters.phd_tracker import Context, PHDConfig, phd_params
from jaxtrack.pipelines.sweep import common_shapes
from jaxtrack.pipelines.tracking import track_sequences

#: The tracker variants compared.
GAP_VARIANTS = ("UM", "GM")
#: The columns of :func:`context_gap`'s rows, in order.
GAP_COLUMNS = ("family", "seed", "variant", *SCORE_KEYS, *COUNT_KEYS)
#: The columns of the summary table (one row per family and seed).
GAP_SUMMARY_COLUMNS = ("family", "seed", "UM_MOTA", "GM_MOTA", "GM_minus_UM", "MOTA_diff_pct")


def context_gap(
    sequence_dir: str | Path,
    config: PHDConfig,
    seed: int = 0,
    progress: Callable[[str], None] | None = None,
) -> list[dict[str, Any]]:
    """Learns context on a sequence's first half; tracks the second with UM and GM; scores.

    Args:
        sequence_dir: a MOTChallenge sequence folder with ground truth.
        config: the tracker configuration (also that of the UM run that yields the births).
        seed: seeds the learning and the tracking.
        progress: called with a short description before each long step.

    Returns:
        One row per variant (UM, GM) with the :data:`SCORE_KEYS` and :data:`COUNT_KEYS`.

    Raises:
        InputError: bad data, or no birth or clutter events on the training half.
    """
    notify = progress or (lambda _: None)
    split = split_halves(sequence_dir)
    notify(f"{split.train.info.name}: learning context on frames 1:{split.train.last_frame}")
    context = Context.from_learned(learn_split(split, config, seed, "tracks"))
    info = split.test.info
    # UM reads the context's detector score calibration too (the "evidence" confirmation).
    params = common_shapes([phd_params(config, info, context, v) for v in GAP_VARIANTS])
    notify(f"{info.name}: tracking frames {split.test.first_frame}:{split.test.last_frame}")
    results = track_sequences([split.test] * len(params), config, seed, params, progress=False)
    return [
        {"variant": name, **score_summary(evaluate_rows(split.test, rows))}
        for name, rows in zip(GAP_VARIANTS, results, strict=True)
    ]


def gap_summary(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per family and seed: UM and GM MOTA, their difference and % difference."""
    by_scene: dict[tuple[str, int], dict[str, float]] = {}
    for row in rows:
        by_scene.setdefault((row["family"], row["seed"]), {})[row["variant"]] = row["MOTA"]
    return [
        {
            "family": family,
            "seed": seed,
            "UM_MOTA": scores["UM"],
            "GM_MOTA": scores["GM"],
            "GM_minus_UM": round(scores["GM"] - scores["UM"], 2),
            "MOTA_diff_pct": round(percent_difference(scores["GM"], scores["UM"]), 2),
        }
        for (family, seed), scores in by_scene.items()
    ]


def run_context_gap(
    out_dir: str | Path,
    families: Sequence[str] | None = None,
    seeds: Sequence[int] = SEEDS,
    quick: bool = False,
    progress: Callable[[str], None] | None = None,
) -> tuple[list[dict[str, Any]], list[Path]]:
    """UM and GM on every family and seed: ``context_gap.csv`` and ``summary.md``.

    Each scene is written to ``out_dir/scenes/<family>-<seed>``; the scene's seed also seeds
    its learning and tracking.

    Args:
        out_dir: the output folder (created if needed).
        families: keys of :data:`~jaxtrack.datasets.scene_bank.FAMILIES`; default all.
        seeds: the scenes' seeds.
        quick: few particles (:data:`~jaxtrack.experiments.common.QUICK_TRACKER_CONFIG`)
            instead of the default :class:`PHDConfig`; the scenes are the same.
        progress: called with a short description before each long step.

    Returns:
        The rows (:data:`GAP_COLUMNS`) and the files written.

    Raises:
        InputError: an unknown family, a bad seed or output folder.
    """
    start = time.perf_counter()
    out = output_folder(out_dir)
    families = list(FAMILIES) if families is None else list(families)
    config = QUICK_TRACKER_CONFIG if quick else PHDConfig()
    rows = []
    for family in families:
        for seed in seeds:
            folder = write_family_scene(family, seed, out / "scenes" / f"{family}-{seed}")
            for row in context_gap(folder, config, seed, progress):
                rows.append({"family": family, "seed": seed, **row})
    csv_path = write_csv(out / "context_gap.csv", rows, GAP_COLUMNS)
    summary = gap_summary(rows)
    text = [
        "# UM vs GM on the scene bank\n",
        f"Context learned on frames 1-300 of each scene (births from a UM run, clutter from "
        f"the ground truth), UM and GM scored on frames 301-600 ({config.num_particles} "
        f"particles, {config.births_per_detection} births per detection"
        f"{', quick run' if quick else ''}). MOTA in %; `MOTA_diff_pct` = "
        "100 (GM - UM) / |UM|.\n",
        markdown_table(summary, GAP_SUMMARY_COLUMNS),
        "All scores:\n",
        markdown_table(rows, GAP_COLUMNS),
        f"Run time {time.perf_counter() - start:.0f} s (compiles included).\n",
    ]
    md_path = out / "summary.md"
    md_path.write_text("\n".join(text))
    return rows, [csv_path, md_path]
