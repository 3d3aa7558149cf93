"""Gradient tuning versus a grid sweep of the clutter and birth magnitudes.

Protocol, on one sequence cut into a training and a disjoint test span:

1. **Grid** (the previous issue's sweep, :func:`jaxtrack.sweep.sweep`): the tracker runs on
   the training span for every ``(lambda_r, lambda_s)`` of a log-spaced grid
   (:func:`~jaxtrack.sweep.magnitude_grid`) and is scored against the ground truth; the
   configuration of the best training MOTA is kept. Cost: one tracker run per grid point.
2. **Gradient tuning** (:func:`~jaxtrack.pipelines.tuning.tune_sequence`): from mis-specified
   magnitudes (:attr:`TuningSettings.start_clutter_rate`, ``start_birth_rate``), adam on the
   unsupervised PHD log-likelihood of the training span (no ground truth), one key per step,
   at most a quarter of the grid's number of runs. Cost: one forward and backward filter pass
   per step and key (:attr:`~jaxtrack.pipelines.tuner.TuneResult.filter_runs`).
3. **Scores** on the test span for the default configuration, the mis-specified start, the
   grid's choice and the tuned magnitudes (the tracker with the configuration's particle
   count in all four), and the test MOTA of the iterates along the optimisation (for the
   figure; these runs are not part of the tuning).

The goal: the tuned magnitudes reach at least 95% of the grid choice's test MOTA with at
most a quarter of the grid's tracker runs.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any

import jax
import numpy as np

from jaxtrack.experiments.common import (
    QUICK_TRACKER_CONFIG,
    Split,
    evaluate_rows,
    markdown_table,
    output_folder,
    score_summary,
    split_halves,
    synthetic_sequence,
    write_csv,
)
from jaxtrack.filters.phd_tracker import PHDConfig, phd_filter_of, phd_params
from jaxtrack.io import load_sequence
from jaxtrack.pipelines.sweep import magnitude_grid, sweep
from jaxtrack.pipelines.tracking import track_sequences
from jaxtrack.pipelines.tuning import CONFIG_TRAINABLE, tune_sequence
from jaxtrack.plot.experiments import save_tuning_figure


@dataclasses.dataclass(frozen=True)
class TuningSettings:
    """Settings of :func:`run_tuning_experiment`.

    Attributes:
        clutter_rates: grid values of ``lambda_r``.
        birth_rates: grid values of ``lambda_s``.
        start_clutter_rate: mis-specified start of ``lambda_r``.
        start_birth_rate: mis-specified start of ``lambda_s``.
        num_steps: adam steps (one key each); at most a quarter of the grid's size.
        learning_rate: adam's learning rate (log units).
        average_steps: the result averages the last iterates.
        tuning_particles: particles of the tuning filter.
        tracker_config: the tracker configuration (grid, scores).
        eval_every: test MOTA of every ``eval_every``-th iterate for the figure.
    """

    clutter_rates: tuple[float, ...] = tuple(np.round(np.logspace(-2, 1, 8), 4))
    birth_rates: tuple[float, ...] = tuple(np.round(np.logspace(-3, 0, 8), 4))
    start_clutter_rate: float = 10.0
    start_birth_rate: float = 1.0
    num_steps: int = 16
    learning_rate: float = 0.4
    average_steps: int = 3
    tuning_particles: int = 512
    tracker_config: PHDConfig = dataclasses.field(default_factory=PHDConfig)
    eval_every: int = 2

    @property
    def grid_size(self) -> int:
        return len(self.clutter_rates) * len(self.birth_rates)


#: Seconds-long settings (``--quick``, the notebook and the tests).
QUICK_SETTINGS = TuningSettings(
    clutter_rates=(0.1, 1.0, 10.0),
    birth_rates=(0.01, 0.1, 1.0),
    num_steps=2,
    tuning_particles=64,
    tracker_config=QUICK_TRACKER_CONFIG,
    average_steps=1,
    eval_every=1,
)

#: Columns of the summary table and of the step table.
SUMMARY_COLUMNS = (
    "dataset",
    "method",
    "clutter_rate",
    "birth_rate",
    "runs",
    "seconds",
    "train_MOTA",
    "MOTA",
    "IDF1",
    "HOTA",
)
STEP_COLUMNS = ("dataset", "step", "loss", "clutter_rate", "birth_rate", "MOTA")
GOAL_COLUMNS = (
    "dataset",
    "grid_MOTA",
    "tuned_MOTA",
    "tuned_vs_grid_percent",
    "grid_runs",
    "tuning_runs",
    "grid_train_MOTA_min",
    "grid_train_MOTA_max",
    "met",
)


def run_tuning_experiment(
    split: Split,
    name: str,
    settings: TuningSettings = TuningSettings(),
    seed: int = 0,
    progress: bool = False,
) -> dict[str, Any]:
    """Grid sweep and gradient tuning on the training span, scores on the test span.

    Args:
        split: training and test spans (ground truth in both).
        name: the dataset's name in the tables.
        settings: the experiment's settings.
        seed: PRNG seed (tracker runs and tuning).
        progress: show progress bars.

    Returns:
        ``{"summary": rows of SUMMARY_COLUMNS, "steps": rows of STEP_COLUMNS,
        "goal": row of GOAL_COLUMNS, "loss": [...]}``; the goal row holds the test MOTA of
        the grid's choice and of the tuned magnitudes, their ratio, the run counts and the
        range of the training MOTA over the grid (how much the magnitudes matter).
    """
    config = settings.tracker_config
    key = jax.random.key(seed)
    train, test = split.train, split.test

    began = time.perf_counter()
    grid = sweep(
        phd_filter_of(config),
        phd_params(config, train.info),
        key,
        train.detections,
        magnitude_grid(settings.clutter_rates, settings.birth_rates),
        ground_truth=train.gt_table,
        first_frame=train.first_frame,
        output=config.output,
        max_gap=config.max_gap,
        retrodiction=config.retrodiction,
        smoothing=config.smoothing,
        progress=progress,
    )
    grid_seconds = time.perf_counter() - began
    best = int(np.nanargmax(grid.scores["MOTA"]))
    grid_rates = (
        float(grid.updates["clutter_rate"][best]),
        float(grid.updates["birth_rate"][best]),
    )

    start_config = config.replace(
        clutter_rate=settings.start_clutter_rate, birth_rate=settings.start_birth_rate
    )
    tuning = tune_sequence(
        train,
        "likelihood",
        start_config,
        CONFIG_TRAINABLE,
        seed=seed,
        num_steps=settings.num_steps,
        num_keys=1,
        learning_rate=settings.learning_rate,
        patience=0,
        average_steps=settings.average_steps,
        num_particles=settings.tuning_particles,
        births_per_detection=min(16, config.births_per_detection),
        progress=progress,
    )
    tuned_rates = (tuning.config.clutter_rate, tuning.config.birth_rate)

    def test_scores(rates_list):
        params = [
            phd_params(config.replace(clutter_rate=c, birth_rate=b), test.info)
            for c, b in rates_list
        ]
        rows = track_sequences([test] * len(params), config, seed, params)
        return [score_summary(evaluate_rows(test, r)) for r in rows]

    history = tuning.result.history
    evaluated = list(range(0, len(history["loss"]), settings.eval_every))
    step_rates = [
        (float(history["values"]["clutter_rate"][s]), float(history["values"]["birth_rate"][s]))
        for s in evaluated
    ]
    default_rates = (PHDConfig().clutter_rate, PHDConfig().birth_rate)
    start_rates = (settings.start_clutter_rate, settings.start_birth_rate)
    scores = test_scores([default_rates, start_rates, grid_rates, tuned_rates, *step_rates])
    default_s, start_s, grid_s, tuned_s, step_s = (
        scores[0],
        scores[1],
        scores[2],
        scores[3],
        scores[4:],
    )

    def row(method, rates, score, runs, seconds, train_mota):
        return {
            "dataset": name,
            "method": method,
            "clutter_rate": f"{rates[0]:.3g}",
            "birth_rate": f"{rates[1]:.3g}",
            "runs": runs,
            "seconds": round(seconds, 1),
            "train_MOTA": train_mota,
            **score,
        }

    summary = [
        row("default", default_rates, default_s, 0, 0.0, float("nan")),
        row("mis-specified start", start_rates, start_s, 0, 0.0, float("nan")),
        row(
            f"grid {len(settings.clutter_rates)}x{len(settings.birth_rates)}",
            grid_rates,
            grid_s,
            settings.grid_size,
            grid_seconds,
            round(100 * float(grid.scores["MOTA"][best]), 2),
        ),
        row(
            "gradient (likelihood)",
            tuned_rates,
            tuned_s,
            tuning.result.filter_runs,
            tuning.report["seconds"],
            float("nan"),
        ),
    ]
    steps = [
        {
            "dataset": name,
            "step": s,
            "loss": round(float(history["loss"][s]), 4),
            "clutter_rate": round(rates[0], 4),
            "birth_rate": round(rates[1], 4),
            "MOTA": score["MOTA"],
        }
        for s, rates, score in zip(evaluated, step_rates, step_s, strict=True)
    ]
    ratio = tuned_s["MOTA"] / grid_s["MOTA"] if grid_s["MOTA"] > 0 else float("nan")
    goal = {
        "dataset": name,
        "grid_MOTA": grid_s["MOTA"],
        "tuned_MOTA": tuned_s["MOTA"],
        "tuned_vs_grid_percent": round(100 * ratio, 1),
        "grid_runs": settings.grid_size,
        "tuning_runs": tuning.result.filter_runs,
        "grid_train_MOTA_min": round(100 * float(np.nanmin(grid.scores["MOTA"])), 2),
        "grid_train_MOTA_max": round(100 * float(np.nanmax(grid.scores["MOTA"])), 2),
        "met": bool(ratio >= 0.95 and 4 * tuning.result.filter_runs <= settings.grid_size),
    }
    return {"summary": summary, "steps": steps, "goal": goal, "loss": history["loss"].tolist()}


def gradient_tuning_experiment(
    out_dir: str | Path,
    seed: int = 0,
    quick: bool = False,
    pets_dir: str | Path | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    """The whole experiment: the synthetic scene and (unless None) PETS09-S2L1; writes files.

    The synthetic scene of ``seed`` is split in halves (:func:`split_halves`); PETS09-S2L1 is
    split as in the acceptance commands, frames 1-400 for training and 401-795 for testing.

    Args:
        out_dir: output folder: ``summary.csv``, ``steps.csv``, ``goals.csv``, ``summary.md``,
            ``gradient_tuning.png`` and the synthetic sequence folder.
        seed: seed of the synthetic scene and of the runs.
        quick: seconds-long settings (:data:`QUICK_SETTINGS`) and the short synthetic scene.
        pets_dir: the PETS09-S2L1 folder, or None to skip it.
        progress: show progress bars.

    Returns:
        ``{"summary": [...], "steps": [...], "goals": [...]}`` (also written as
        ``summary.csv``, ``steps.csv``, ``goals.csv``).
    """
    out = output_folder(out_dir)
    settings = QUICK_SETTINGS if quick else TuningSettings()
    datasets = [("synthetic", split_halves(synthetic_sequence(out / "synthetic", seed, quick)))]
    if pets_dir is not None:
        pets = Path(pets_dir)
        last = 795 if not quick else 120
        half = 400 if not quick else 60
        datasets.append(
            (
                "PETS09-S2L1",
                Split(load_sequence(pets, (1, half)), load_sequence(pets, (half + 1, last))),
            )
        )
    summary, steps, goals, losses = [], [], [], {}
    for name, split in datasets:
        result = run_tuning_experiment(split, name, settings, seed, progress)
        summary += result["summary"]
        steps += result["steps"]
        goals.append(result["goal"])
        losses[name] = result["loss"]
    write_csv(out / "summary.csv", summary, SUMMARY_COLUMNS)
    write_csv(out / "steps.csv", steps, STEP_COLUMNS)
    text = markdown_table(summary, SUMMARY_COLUMNS) + "\n" + markdown_table(goals, GOAL_COLUMNS)
    write_csv(out / "goals.csv", goals, GOAL_COLUMNS)
    (out / "summary.md").write_text(text)

    save_tuning_figure(steps, losses, summary, out / "gradient_tuning.png")
    return {"summary": summary, "steps": steps, "goals": goals}
