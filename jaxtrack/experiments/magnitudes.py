"""Magnitude sweep, PHD-context Fig. 15: scores against ``lambda_r`` and ``lambda_s``, UM and GM.

Protocol: context is learned on the training span of a
:class:`~jaxtrack.experiments.common.Split` (birth events from a UM tracker run, clutter
events from the ground truth, as the ablation's GM). The test span is then tracked for every
point of a log-spaced ``lambda_r x lambda_s`` grid (clutter and birth magnitudes, PHD-context
eq. 19-20) with uniform intensities (UM) and with the learned ones (GM: the learned densities
scaled to the grid's magnitudes). All ``2 x n_r x n_s`` tracker runs are one vmapped,
device-sharded sweep (:func:`~jaxtrack.sweep.sweep`), scored with MOTA, MOTP, MODA, MODP,
IDF1 and HOTA. Both variants see the same key (common random numbers).

The figure draws each score against ``lambda_r`` with ``lambda_s`` at the grid value
nearest the birth magnitude measured on the training span, and against ``lambda_s`` with
``lambda_r`` at the grid value nearest the measured clutter magnitude.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import jax
import numpy as np

from jaxtrack.experiments.common import (
    COUNT_KEYS,
    QUICK_TRACKER_CONFIG,
    SCORE_KEYS,
    Split,
    learn_split,
    markdown_table,
    output_folder,
    split_halves,
    synthetic_sequence,
    write_csv,
)
from jaxtrack.filters.phd_tracker import Context, PHDConfig, phd_filter_of, phd_params
from jaxtrack.pipelines.sweep import batch_params, common_shapes, log_grid, magnitude_grid, sweep
from jaxtrack.plot.experiments import save_sweep_figure, save_sweep_heatmaps

#: Clutter magnitudes ``lambda_r`` of the default grid (false detections per frame).
CLUTTER_RATES = log_grid(0.1, 10.0, 9)
#: Birth magnitudes ``lambda_s`` of the default grid (births per frame).
BIRTH_RATES = log_grid(0.02, 2.0, 9)
#: The 3 x 3 grid of ``--quick`` runs.
QUICK_CLUTTER_RATES = log_grid(0.1, 10.0, 3)
QUICK_BIRTH_RATES = log_grid(0.02, 2.0, 3)
#: The variants swept: uniform (UM) and learned (GM) intensities.
SWEEP_VARIANTS = ("UM", "GM")
#: The columns of :attr:`MagnitudeSweep.rows`, in order.
SWEEP_COLUMNS = ("variant", "lambda_r", "lambda_s", *SCORE_KEYS, *COUNT_KEYS)


class MagnitudeSweep(NamedTuple):
    """Scores of UM and GM over a ``lambda_r x lambda_s`` grid.

    Attributes:
        clutter_rates: the grid's ``lambda_r`` values ``[n_r]``.
        birth_rates: the grid's ``lambda_s`` values ``[n_s]``.
        scores: ``{variant: {score: [n_r, n_s]}}`` in percent for the :data:`SCORE_KEYS`,
            counts for the :data:`COUNT_KEYS`.
        rows: one dict per configuration with the :data:`SWEEP_COLUMNS` (UM's grid first,
            ``lambda_r`` slowest).
        measured: the magnitudes measured on the training span,
            ``{"lambda_r": ..., "lambda_s": ...}``.
        context: the learned context's metadata.
    """

    clutter_rates: np.ndarray
    birth_rates: np.ndarray
    scores: dict[str, dict[str, np.ndarray]]
    rows: list[dict[str, Any]]
    measured: dict[str, float]
    context: dict

    def slice_index(self) -> tuple[int, int]:
        """Grid indices ``(i_r, i_s)`` nearest (in log) the measured magnitudes."""
        return (
            int(np.argmin(np.abs(np.log(self.clutter_rates / self.measured["lambda_r"])))),
            int(np.argmin(np.abs(np.log(self.birth_rates / self.measured["lambda_s"])))),
        )

    def best(self, variant: str, score: str = "MOTA") -> dict[str, float]:
        """The grid point of a variant's highest score: ``{score, lambda_r, lambda_s}``."""
        grid = self.scores[variant][score]
        i, j = np.unravel_index(int(np.argmax(grid)), grid.shape)
        return {
            score: float(grid[i, j]),
            "lambda_r": float(self.clutter_rates[i]),
            "lambda_s": float(self.birth_rates[j]),
        }


def variant_params(info, config: PHDConfig, context: Context) -> list[Any]:
    """UM's and GM's tracker parameters for a sequence, padded to one PyTree shape.

    Args:
        info: the sequence's ``SequenceInfo``.
        config: a full tracker configuration.
        context: the learned context (GM).

    Returns:
        ``[UM, GM]`` :class:`~jaxtrack.filters.phd.PHDParams`, stackable into one batch
        (:func:`~jaxtrack.sweep.common_shapes`).
    """
    # UM reads the context's detector score calibration too (the "evidence" confirmation).
    return common_shapes([phd_params(config, info, context, v) for v in ("UM", "GM")])


def magnitude_batch(params: list[Any], clutter_rates: np.ndarray, birth_rates: np.ndarray):
    """One batch of every parameter set of ``params`` at every grid point, set after set.

    Args:
        params: parameter PyTrees of one shape (e.g. :func:`variant_params`).
        clutter_rates: ``lambda_r`` values, 1-D, positive.
        birth_rates: ``lambda_s`` values, 1-D, positive.

    Returns:
        The batched PyTree, ``len(params) * len(clutter_rates) * len(birth_rates)``
        configurations (``lambda_r`` slowest within a set).
    """
    grid = magnitude_grid(clutter_rates, birth_rates)
    return jax.tree.map(
        lambda *leaves: np.concatenate(leaves), *(batch_params(p, grid) for p in params)
    )


def magnitude_sweep(
    split: Split,
    context: Context,
    config: PHDConfig | None = None,
    seed: int = 0,
    clutter_rates: np.ndarray = CLUTTER_RATES,
    birth_rates: np.ndarray = BIRTH_RATES,
    chunk_size: int = 18,
    progress: bool = False,
) -> MagnitudeSweep:
    """Tracks ``split.test`` with UM and GM over the magnitude grid in one sweep and scores it.

    Args:
        split: the training and test spans (the test span needs ground truth).
        context: the context learned on ``split.train``
            (:func:`~jaxtrack.experiments.common.learn_split`).
        config: the tracker configuration (default ``PHDConfig()``).
        seed: the tracking key, shared by every configuration.
        clutter_rates: ``lambda_r`` values, 1-D, positive.
        birth_rates: ``lambda_s`` values, 1-D, positive.
        chunk_size: configurations per device per compiled call (bounds memory; see
            :func:`~jaxtrack.pipelines.sweep.sweep`).
        progress: a progress bar over the chunks.

    Returns:
        The :class:`MagnitudeSweep`.

    Raises:
        InputError: bad rates or configuration, or a test span without ground truth.
    """
    config = config or PHDConfig()
    params = variant_params(split.test.info, config, context)
    result = sweep(
        phd_filter_of(config),
        magnitude_batch(params, clutter_rates, birth_rates),
        jax.random.key(seed),
        split.test.detections,
        ground_truth=split.test.gt_table,
        first_frame=split.test.first_frame,
        output=config.output,
        max_gap=config.max_gap,
        retrodiction=config.retrodiction,
        smoothing=config.smoothing,
        chunk_size=chunk_size,
        progress=progress,
    )
    shape = (len(SWEEP_VARIANTS), len(clutter_rates), len(birth_rates))
    scores = {
        variant: {
            key: (100 * result.scores[key] if key in SCORE_KEYS else result.scores[key]).reshape(
                shape
            )[v]
            for key in (*SCORE_KEYS, *COUNT_KEYS)
        }
        for v, variant in enumerate(SWEEP_VARIANTS)
    }
    rows = [
        {
            "variant": variant,
            "lambda_r": float(clutter_rates[i]),
            "lambda_s": float(birth_rates[j]),
            **{key: round(float(scores[variant][key][i, j]), 2) for key in SCORE_KEYS},
            **{key: int(scores[variant][key][i, j]) for key in COUNT_KEYS},
        }
        for variant in SWEEP_VARIANTS
        for i in range(len(clutter_rates))
        for j in range(len(birth_rates))
    ]
    meta = context.metadata
    measured = {
        "lambda_r": float(meta["clutter"]["magnitude"]),
        "lambda_s": float(meta["birth"]["magnitude"]),
    }
    return MagnitudeSweep(
        np.asarray(clutter_rates, np.float64),
        np.asarray(birth_rates, np.float64),
        scores,
        rows,
        measured,
        meta,
    )


def sweep_summary(result: MagnitudeSweep) -> dict[str, Any]:
    """Headline numbers: each variant's best MOTA, and GM against UM over the grid.

    Returns:
        ``{"best": {variant: {...}}, "gm_minus_um_best_mota": ..., "gm_better_fraction": ...,
        "mean_mota": {variant: ...}}`` (MOTA in percent; ``gm_better_fraction`` is the share
        of grid points where GM's MOTA is higher than UM's).
    """
    um, gm = result.scores["UM"]["MOTA"], result.scores["GM"]["MOTA"]
    best = {variant: result.best(variant) for variant in SWEEP_VARIANTS}
    return {
        "best": best,
        "gm_minus_um_best_mota": best["GM"]["MOTA"] - best["UM"]["MOTA"],
        "gm_better_fraction": float(np.mean(gm > um)),
        "mean_mota": {"UM": float(np.mean(um)), "GM": float(np.mean(gm))},
    }


def run_magnitude_sweep(
    out_dir: str | Path,
    seed: int = 0,
    quick: bool = False,
    sequence_dir: str | Path | None = None,
    progress: Callable[[str], None] | None = None,
) -> tuple[MagnitudeSweep, list[Path]]:
    """The whole Fig. 15 experiment: data, split, learning, sweep, CSV, PNGs, ``summary.md``.

    Args:
        out_dir: the output folder (created if needed).
        seed: seeds the synthetic scene, the learning and the tracking.
        quick: a seconds-long smoke run (short scene, few particles, 3 x 3 grid).
        sequence_dir: a MOTChallenge sequence folder with ground truth; default: the
            synthetic scene of ``seed``, written to ``out_dir/scene``.
        progress: called with a short description before each long step (also turns on
            the sweep's progress bar).

    Returns:
        The :class:`MagnitudeSweep` and the files written (``sweep.csv``, ``sweep.png``,
        ``sweep_mota.png``, ``summary.md``).

    Raises:
        InputError: bad data or output folder, or no events to learn from.
    """
    start = time.perf_counter()
    notify = progress or (lambda _: None)
    out = output_folder(out_dir)
    if sequence_dir is None:
        sequence_dir = synthetic_sequence(out / "scene", seed, quick)
    split = split_halves(sequence_dir)
    config = QUICK_TRACKER_CONFIG if quick else PHDConfig()
    context = Context.from_learned(learn_split(split, config, seed, progress=progress))
    rates = (QUICK_CLUTTER_RATES, QUICK_BIRTH_RATES) if quick else (CLUTTER_RATES, BIRTH_RATES)
    notify(
        f"sweeping {len(SWEEP_VARIANTS)} x {len(rates[0])} x {len(rates[1])} configurations "
        f"on frames {split.test.first_frame}:{split.test.last_frame}"
    )
    result = magnitude_sweep(split, context, config, seed, *rates, progress=progress is not None)
    files = write_sweep_files(result, out, split.test.info.name)
    md_path = out / "summary.md"
    md_path.write_text(
        summary_markdown(result, split, seed, quick, config, time.perf_counter() - start)
    )
    return result, [*files, md_path]


def write_sweep_files(result: MagnitudeSweep, out: Path, name: str) -> list[Path]:
    """Writes ``sweep.csv`` (every configuration), ``sweep.png`` and ``sweep_mota.png``.

    Args:
        result: the sweep.
        out: the output folder.
        name: the sequence's name (figure titles).

    Returns:
        The three files.
    """

    return [
        write_csv(out / "sweep.csv", result.rows, SWEEP_COLUMNS),
        save_sweep_figure(result, out / "sweep.png", title=name),
        save_sweep_heatmaps(result, out / "sweep_mota.png", title=name),
    ]


def summary_markdown(
    result: MagnitudeSweep,
    split: Split,
    seed: int,
    quick: bool,
    config: PHDConfig,
    seconds: float,
) -> str:
    """The experiment's ``summary.md``: protocol, best points, GM vs UM, the figure's slices."""
    head = sweep_summary(result)
    i_r, i_s = result.slice_index()
    slice_rows = [
        row
        for row in result.rows
        if row["lambda_s"] == result.birth_rates[i_s]
        or row["lambda_r"] == result.clutter_rates[i_r]
    ]
    columns = ("variant", "lambda_r", "lambda_s", *SCORE_KEYS)
    lines = [
        f"# Magnitude sweep (PHD-context Fig. 15): {split.test.info.name}\n",
        f"Sequence `{split.test.path}`: context learned on frames "
        f"{split.train.first_frame}:{split.train.last_frame} (births from a UM tracker run, "
        f"clutter from the ground truth; measured lambda_r {result.measured['lambda_r']:.3f}, "
        f"lambda_s {result.measured['lambda_s']:.3f} per frame); frames "
        f"{split.test.first_frame}:{split.test.last_frame} tracked for "
        f"{len(result.clutter_rates)} x {len(result.birth_rates)} magnitudes with UM and GM "
        f"in one vmapped sweep (seed {seed}{', quick run' if quick else ''}; "
        f"{config.num_particles} particles). Scores in %.\n",
        "| variant | best MOTA | at lambda_r | at lambda_s | mean MOTA over the grid |",
        "|---|---|---|---|---|",
        *(
            f"| {v} | {head['best'][v]['MOTA']:.1f} | {head['best'][v]['lambda_r']:.3g} | "
            f"{head['best'][v]['lambda_s']:.3g} | {head['mean_mota'][v]:.1f} |"
            for v in SWEEP_VARIANTS
        ),
        "",
        f"GM - UM at the best points: {head['gm_minus_um_best_mota']:+.1f} MOTA points; GM "
        f"is better than UM at {100 * head['gm_better_fraction']:.0f}% of the grid points.\n",
        f"The figure's slices (lambda_s = {result.birth_rates[i_s]:.3g}, lambda_r = "
        f"{result.clutter_rates[i_r]:.3g}: the grid values nearest the measured magnitudes):\n",
        markdown_table(
            [
                {**row, "lambda_r": f"{row['lambda_r']:.3g}", "lambda_s": f"{row['lambda_s']:.3g}"}
                for row in slice_rows
            ],
            columns,
        ),
        f"Run time {seconds:.0f} s (compiles included). Files: `sweep.csv` (every "
        "configuration), `sweep.png` (scores against lambda_r and lambda_s), `sweep_mota.png` "
        "(MOTA over the grid).\n",
    ]
    return "\n".join(lines)
