"""Context ablation (PHD-context Fig. 14): UM, GM and A1-A6 on the same test span.

Protocol: context is learned on the training span of a :class:`~jaxtrack.experiments.common.Split`
twice with :func:`~jaxtrack.context.learn.learn_context`: birth events from the trajectories
of a UM tracker run (the paper's source) and, for A6, from the ground truth (the paper's
manually labelled births); clutter events from the ground truth in both (the toolkit's
stand-in for the paper's interactive labels). Every variant of
:data:`~jaxtrack.filters.phd_tracker.VARIANTS` then tracks the test span with the same seed
(:func:`~jaxtrack.filters.phd_tracker.phd_params`; A6 = GM with the second context) and
is scored; each score's difference with respect to UM is given in percent,
``100 (s - s_UM) / |s_UM|`` (:func:`~jaxtrack.experiments.common.percent_difference`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

from jaxtrack.experiments.common import (
    COUNT_KEYS,
    QUICK_TRACKER_CONFIG,
    SCORE_KEYS,
    Split,
    evaluate_rows,
    learn_split,
    markdown_table,
    output_folder,
    percent_difference,
    score_summary,
    split_halves,
    synthetic_sequence,
    write_csv,
)
from jaxtrack.filters.phd import PHDParams
from jaxtrack.filters.phd_tracker import VARIANTS, Context, PHDConfig, phd_params
from jaxtrack.pipelines.sweep import common_shapes
from jaxtrack.pipelines.tracking import track_sequences
from jaxtrack.plot.experiments import save_ablation_figure
from jaxtrack.types import SequenceInfo

#: What each variant uses (PHD-context Sec. V), for tables and summaries.
VARIANT_DESCRIPTIONS = {
    "UM": "uniform birth and clutter, configured magnitudes",
    "GM": "learned birth and clutter",
    "A1": "learned birth, uniform clutter",
    "A2": "uniform birth, learned clutter",
    "A3": "uniform both, magnitudes measured on the training span",
    "A4": "learned birth, uniform clutter with measured magnitude",
    "A5": "uniform birth with measured magnitude, learned clutter",
    "A6": "GM, births learned from the ground truth",
}
#: Scores whose % difference w.r.t. UM is reported (the paper's Fig. 14 scores).
DIFFERENCE_KEYS = ("MOTA", "MOTP", "MODA", "MODP")
#: The columns of :func:`ablation_table`'s rows, in order.
ABLATION_COLUMNS = (
    "variant",
    *SCORE_KEYS,
    *COUNT_KEYS,
    *(f"{key}_diff_pct" for key in DIFFERENCE_KEYS),
)


class AblationResult(NamedTuple):
    """The ablation table and what it was learned from.

    Attributes:
        rows: one dict per variant (UM first) with the :data:`ABLATION_COLUMNS`.
        contexts: the metadata of the two learned contexts, ``{"tracks": ..., "gt": ...}``
            (keyed by the birth events' source).
    """

    rows: list[dict[str, Any]]
    contexts: dict[str, dict]


def ablation_table(
    split: Split,
    config: PHDConfig | None = None,
    seed: int = 0,
    progress: Callable[[str], None] | None = None,
) -> AblationResult:
    """Learns context on ``split.train``, tracks ``split.test`` with every variant, scores.

    Args:
        split: the training and test spans of a sequence with ground truth.
        config: the tracker configuration (default ``PHDConfig()``) (its
            ``num_particles`` also sets the particles of the UM run that yields birth events).
        seed: seeds the learning (tracker run, sample order) and the tracking.
        progress: called with a short description before each long step.

    Returns:
        The :class:`AblationResult`.

    Raises:
        InputError: no birth or clutter events on the training span, or a bad configuration.
    """
    notify = progress or (lambda _: None)
    config = config or PHDConfig()
    contexts = ablation_contexts(split, config, seed, progress)
    params = common_shapes(variant_params(config, split.test.info, contexts))
    notify(f"tracking frames {split.test.first_frame}:{split.test.last_frame}")
    results = track_sequences(
        [split.test] * len(params), config, seed, params, progress=progress is not None
    )
    rows = [
        {"variant": name, **score_summary(evaluate_rows(split.test, result))}
        for name, result in zip(VARIANTS, results, strict=True)
    ]
    add_differences(rows, "UM")
    return AblationResult(rows, {key: context.metadata for key, context in contexts.items()})


def ablation_contexts(
    split: Split,
    config: PHDConfig,
    seed: int = 0,
    progress: Callable[[str], None] | None = None,
    first_frame: bool = False,
) -> dict[str, Context]:
    """The two contexts of the ablation, learned on ``split.train``, keyed by birth source.

    Args:
        split: the training and test spans.
        config: the tracker configuration (also that of the UM run that yields births).
        seed: seeds the learning (tracker run, sample order).
        progress: called with a short description before each long step.
        first_frame: also learn each context's first-frame intensity
            (:func:`~jaxtrack.pipelines.context.learn_context`).

    Returns:
        ``{"tracks": ..., "gt": ...}``: births from a UM tracker run (UM, GM, A1-A5) and from
        the ground truth (A6); clutter from the ground truth in both.

    Raises:
        InputError: no birth or clutter events on the training span.
    """
    notify = progress or (lambda _: None)
    contexts = {}
    for source in ("tracks", "gt"):
        notify(f"learning context (births from {source})")
        contexts[source] = Context.from_learned(
            learn_split(split, config, seed, source, first_frame=first_frame)
        )
    return contexts


def variant_params(
    config: PHDConfig, info: SequenceInfo, contexts: dict[str, Context]
) -> list[PHDParams]:
    """The parameters of every variant of :data:`VARIANTS`, in order.

    UM has uniform intensities; A6 is GM with ``contexts["gt"]``, every other variant, UM
    included, uses ``contexts["tracks"]`` (:func:`ablation_contexts`; for UM only its detector
    score calibration, which the ``"evidence"`` confirmation reads). The parameters are not
    padded to common shapes (:func:`~jaxtrack.pipelines.sweep.common_shapes` does that).
    """
    return [
        phd_params(config, info, contexts["gt" if name == "A6" else "tracks"], name)
        for name in VARIANTS
    ]


def add_differences(rows: list[dict[str, Any]], reference: str) -> None:
    """Adds ``<score>_diff_pct`` for the :data:`DIFFERENCE_KEYS` w.r.t. the reference row.

    Args:
        rows: table rows with a ``"variant"`` key and the scores; updated in place.
        reference: the variant the differences are taken against (its own are 0).

    Raises:
        KeyError: no row of the reference variant.
    """
    base = next((row for row in rows if row["variant"] == reference), None)
    if base is None:
        raise KeyError(f"no row of the reference variant {reference!r}")
    for row in rows:
        for key in DIFFERENCE_KEYS:
            row[f"{key}_diff_pct"] = round(percent_difference(row[key], base[key]), 2)


def run_ablation(
    out_dir: str | Path,
    seed: int = 0,
    quick: bool = False,
    sequence_dir: str | Path | None = None,
    progress: Callable[[str], None] | None = None,
) -> tuple[AblationResult, list[Path]]:
    """The whole Fig. 14 experiment: data, split, ablation, ``ablation.csv|png``, ``summary.md``.

    Args:
        out_dir: the output folder (created if needed).
        seed: seeds the synthetic scene, the learning and the tracking.
        quick: a seconds-long smoke run (short synthetic scene, few particles).
        sequence_dir: a MOTChallenge sequence folder with ground truth; default: the
            synthetic scene of ``seed``, written to ``out_dir/scene``.
        progress: called with a short description before each long step.

    Returns:
        The :class:`AblationResult` and the files written.

    Raises:
        InputError: bad data (see :func:`~jaxtrack.experiments.common.split_halves` and
            :func:`ablation_table`) or output folder.
    """

    start = time.perf_counter()
    out = output_folder(out_dir)
    if sequence_dir is None:
        sequence_dir = synthetic_sequence(out / "scene", seed, quick)
    split = split_halves(sequence_dir)
    config = QUICK_TRACKER_CONFIG if quick else PHDConfig()
    result = ablation_table(split, config, seed, progress)
    name = split.test.info.name
    csv_path = write_csv(out / "ablation.csv", result.rows, ABLATION_COLUMNS)
    png_path = save_ablation_figure(
        result.rows, out / "ablation.png", DIFFERENCE_KEYS, title=f"{name}: % difference vs UM"
    )
    summary = [
        f"# Context ablation (PHD-context Fig. 14): {name}\n",
        f"Sequence `{split.test.path}`: context learned on frames "
        f"{split.train.first_frame}:{split.train.last_frame}, every variant tracks frames "
        f"{split.test.first_frame}:{split.test.last_frame} (seed {seed}"
        f"{', quick run' if quick else ''}; {config.num_particles} particles). "
        "Scores in %, CLEAR MOT MOTA/MOTP, VACE MODA/MODP (pooled), IDF1, HOTA; "
        "`*_diff_pct` = 100 (score - UM) / |UM|.\n",
        markdown_table(result.rows, ABLATION_COLUMNS),
        "Variants:\n",
        *(f"- {key}: {text}" for key, text in VARIANT_DESCRIPTIONS.items()),
        "\nLearned contexts (clutter from the ground truth in both):\n",
        *(
            f"- births from {source}: {meta['birth']['num_events']} births "
            f"(lambda_s {meta['birth']['magnitude']:.3f}/frame, "
            f"{meta['birth']['components_alive']} components), "
            f"{meta['clutter']['num_events']} clutter detections "
            f"(lambda_r {meta['clutter']['magnitude']:.3f}/frame, "
            f"{meta['clutter']['components_alive']} components)"
            for source, meta in result.contexts.items()
        ),
        f"\nRun time {time.perf_counter() - start:.0f} s (compiles included). Files: "
        f"`{csv_path.name}`, `{png_path.name}`.\n",
    ]
    md_path = out / "summary.md"
    md_path.write_text("\n".join(summary))
    return result, [csv_path, png_path, md_path]
