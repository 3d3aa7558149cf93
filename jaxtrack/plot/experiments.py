"""Figures of the experiments: magnitude sweep (PHD-context Fig. 15), context ablation (Fig. 14),
tracker comparison (Fig. 16).

Each ``save_<name>`` writes the PNG of the Figure built by ``<name>`` (kept apart so that
tests assert on the drawn data).

* :func:`save_ablation_figure`: for each variant but the reference (UM), one group of bars,
  the % difference of each score with respect to UM (the ``<score>_diff_pct`` columns of
  :func:`jaxtrack.experiments.ablation.ablation_table`).
* :func:`save_comparison_figure`: one panel per score; per sequence a group of bars, one per
  tracker (the rows of :func:`jaxtrack.experiments.comparison.comparison_table`).
* :func:`save_sweep_figure` / :func:`save_sweep_heatmaps`: scores against the clutter and
  birth magnitudes, and MOTA over the whole grid, of a
  :class:`~jaxtrack.experiments.magnitudes.MagnitudeSweep`.
* :func:`save_demo_figure`: the overview figure of ``jaxtrack demo``.
* :func:`save_tuning_figure`: loss and test MOTA against the steps of gradient tuning.

Matplotlib's object-oriented API with the Agg canvas: no display, no pyplot global state.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import NullFormatter

from jaxtrack.plot.context import (
    BIRTH_POSITION_DIMS,
    CLUTTER_POSITION_DIMS,
    draw_intensity,
    position_map,
)


def _save(figure: Figure, path: str | Path, dpi: int = 100) -> Path:
    """Writes ``figure`` as a PNG; returns ``path`` as a :class:`~pathlib.Path`."""
    path = Path(path)
    figure.savefig(path, dpi=dpi)
    return path


def _grouped_bars(axes, groups: Sequence[str], series: dict[str, Sequence[float]]) -> None:
    """Draws one group of bars per entry of ``groups``, one bar per ``series`` in each."""
    width = 0.8 / max(1, len(series))
    positions = np.arange(len(groups))
    for index, (label, values) in enumerate(series.items()):
        offset = (index - (len(series) - 1) / 2) * width
        heights = [0.0 if math.isnan(value) else value for value in values]
        axes.bar(positions + offset, heights, width, label=label)
    axes.set_xticks(positions, groups)
    axes.axhline(0.0, color="black", linewidth=0.8)
    axes.grid(axis="y", alpha=0.3)


def save_ablation_figure(rows: Sequence[dict], path: str | Path, *args, **kwargs) -> Path:
    """Writes :func:`ablation_figure` (and its other arguments) to ``path``."""
    return _save(ablation_figure(rows, *args, **kwargs), path)


def ablation_figure(
    rows: Sequence[dict],
    scores: Sequence[str] = ("MOTA", "MOTP", "MODA", "MODP"),
    reference: str = "UM",
    title: str = "",
) -> Figure:
    """Bars of each variant's score % difference w.r.t. the reference (PHD-context Fig. 14).

    Args:
        rows: table rows with ``variant`` and ``<score>_diff_pct`` for each score.
        scores: the scores drawn (one bar each per variant).
        reference: the variant the differences are taken against (not drawn).
        title: the figure's title.

    Returns:
        The figure (one axes; the bars of each score are one container, NaN drawn as 0).
    """
    shown = [row for row in rows if row["variant"] != reference]
    figure = Figure(figsize=(8, 4.5), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    _grouped_bars(
        axes,
        [row["variant"] for row in shown],
        {score: [row[f"{score}_diff_pct"] for row in shown] for score in scores},
    )
    axes.set_ylabel(f"% difference w.r.t. {reference}")
    axes.legend()
    axes.set_title(title or f"Score difference of the context variants w.r.t. {reference}")
    return figure


def save_comparison_figure(rows: Sequence[dict], path: str | Path, *args, **kwargs) -> Path:
    """Writes :func:`comparison_figure` (and its other arguments) to ``path``."""
    return _save(comparison_figure(rows, *args, **kwargs), path)


def comparison_figure(
    rows: Sequence[dict],
    scores: Sequence[str] = ("MOTA", "MOTP", "MODA", "MODP"),
    title: str = "",
) -> Figure:
    """One panel per score, bars per sequence and tracker (PHD-context Fig. 16).

    Args:
        rows: table rows with ``sequence``, ``tracker`` and the scores (in percent).
        scores: the scores drawn, one panel each.
        title: the figure's title.

    Returns:
        The figure, one axes per score in order; a missing (sequence, tracker) is drawn as 0.
    """
    sequences = list(dict.fromkeys(row["sequence"] for row in rows))
    trackers = list(dict.fromkeys(row["tracker"] for row in rows))
    value = {(row["sequence"], row["tracker"]): row for row in rows}
    columns = 2 if len(scores) > 1 else 1
    panels = math.ceil(len(scores) / columns)
    figure = Figure(
        figsize=(max(8, 0.6 * len(sequences) * columns + 2), 3.2 * panels), layout="constrained"
    )
    FigureCanvasAgg(figure)
    for index, score in enumerate(scores):
        axes = figure.add_subplot(panels, columns, index + 1)
        _grouped_bars(
            axes,
            sequences,
            {
                tracker: [
                    value[(sequence, tracker)][score] if (sequence, tracker) in value else math.nan
                    for sequence in sequences
                ]
                for tracker in trackers
            },
        )
        axes.set_ylabel(f"{score} (%)")
        axes.tick_params(axis="x", labelrotation=45 if len(sequences) > 3 else 0)
        if index == 0:
            axes.legend(fontsize="small")
    figure.suptitle(title or "Trackers on the same detections")
    return figure


def tick_labels(values: Sequence[float], most: int = 5) -> list[str]:
    """Labels for ticks at ``values``: every k-th value (``%.2g``), at most ``most`` shown."""
    every = max(1, -(-len(values) // most))
    return [f"{v:.2g}" if k % every == 0 else "" for k, v in enumerate(values)]


def save_sweep_figure(result, path: str | Path, *args, **kwargs) -> Path:
    """Writes :func:`sweep_figure` (and its other arguments) to ``path``."""
    return _save(sweep_figure(result, *args, **kwargs), path)


def sweep_figure(
    result,
    scores: Sequence[str] = ("MOTA", "MOTP", "MODA", "MODP"),
    title: str = "",
) -> Figure:
    """Scores against ``lambda_r`` and against ``lambda_s``, one line per variant (Fig. 15).

    Top row: each score against the clutter magnitude ``lambda_r`` with ``lambda_s`` at the
    grid value nearest the measured birth magnitude; bottom row: against ``lambda_s`` with
    ``lambda_r`` at the grid value nearest the measured clutter magnitude. Log-scaled x axes.

    Args:
        result: a :class:`~jaxtrack.experiments.magnitudes.MagnitudeSweep`.
        scores: the scores drawn, one column each.
        title: the figure's title (e.g. the sequence name).

    Returns:
        The figure: ``2 x len(scores)`` axes, row by row, one line per variant in each.
    """
    i_r, i_s = result.slice_index()
    figure = Figure(figsize=(3.2 * len(scores), 6), layout="constrained")
    FigureCanvasAgg(figure)
    slices = (
        ("lambda_r (false detections / frame)", result.clutter_rates, np.s_[:, i_s]),
        ("lambda_s (births / frame)", result.birth_rates, np.s_[i_r, :]),
    )
    fixed = (
        f"lambda_s = {result.birth_rates[i_s]:.3g}",
        f"lambda_r = {result.clutter_rates[i_r]:.3g}",
    )
    for row, (label, rates, index) in enumerate(slices):
        for column, score in enumerate(scores):
            axes = figure.add_subplot(2, len(scores), row * len(scores) + column + 1)
            for variant, grids in result.scores.items():
                axes.plot(rates, grids[score][index], marker="o", label=variant)
            axes.set_xscale("log")
            axes.set_xticks(rates, tick_labels(rates))
            axes.xaxis.set_minor_formatter(NullFormatter())
            axes.set_xlabel(label)
            axes.set_ylabel(f"{score} (%)")
            axes.grid(alpha=0.3)
            axes.set_title(fixed[row], fontsize="small")
            if row == 0 and column == 0:
                axes.legend()
    figure.suptitle(f"{title}: scores against the clutter and birth magnitudes".lstrip(": "))
    return figure


def save_sweep_heatmaps(result, path: str | Path, *args, **kwargs) -> Path:
    """Writes :func:`sweep_heatmaps` (and its other arguments) to ``path``."""
    return _save(sweep_heatmaps(result, *args, **kwargs), path)


def sweep_heatmaps(result, score: str = "MOTA", title: str = "") -> Figure:
    """One heat map of a score over the ``lambda_r x lambda_s`` grid per variant.

    Args:
        result: a :class:`~jaxtrack.experiments.magnitudes.MagnitudeSweep`.
        score: the score drawn (one shared colour scale).
        title: the figure's title.

    Returns:
        The figure: one axes per variant (its grid as the image, the best point starred),
        then the colour bar.
    """
    grids = {variant: values[score] for variant, values in result.scores.items()}
    low = min(float(np.min(g)) for g in grids.values())
    high = max(float(np.max(g)) for g in grids.values())
    figure = Figure(figsize=(5 * len(grids) + 1, 4.5), layout="constrained")
    FigureCanvasAgg(figure)
    for index, (variant, grid) in enumerate(grids.items()):
        axes = figure.add_subplot(1, len(grids), index + 1)
        image = axes.imshow(grid, origin="lower", vmin=low, vmax=high, cmap="viridis")
        axes.set_xticks(range(len(result.birth_rates)), [f"{v:.2g}" for v in result.birth_rates])
        axes.set_yticks(
            range(len(result.clutter_rates)), [f"{v:.2g}" for v in result.clutter_rates]
        )
        axes.tick_params(axis="x", labelrotation=45)
        axes.set_xlabel("lambda_s (births / frame)")
        axes.set_ylabel("lambda_r (false detections / frame)")
        best = np.unravel_index(int(np.argmax(grid)), grid.shape)
        axes.plot(best[1], best[0], marker="*", color="red", markersize=14)
        axes.set_title(f"{variant}: best {score} {grid[best]:.1f}")
        for (i, j), value in np.ndenumerate(grid):
            axes.text(j, i, f"{value:.0f}", ha="center", va="center", fontsize=7, color="white")
    figure.colorbar(image, ax=figure.axes, label=f"{score} (%)")
    figure.suptitle(f"{title}: {score} over the magnitude grid".lstrip(": "))
    return figure


def save_demo_figure(path: str | Path, context, sweep, rows, info) -> Path:
    """Writes :func:`demo_figure` to the PNG ``path``."""
    return _save(demo_figure(context, sweep, rows, info), path, dpi=90)


def demo_figure(context, sweep, rows, info) -> Figure:
    """The demo's overview: learned birth and clutter maps, MOTA against both magnitudes.

    Args:
        context: the learned :class:`~jaxtrack.filters.phd_tracker.Context`.
        sweep: the :class:`~jaxtrack.experiments.magnitudes.MagnitudeSweep` of UM and GM.
        rows: the UM and GM score rows (``variant``, ``MOTA``) on the test span.
        info: the sequence's :class:`~jaxtrack.io.SequenceInfo` (image size, name).

    Returns:
        The figure: birth map, clutter map, MOTA against ``lambda_r``, against ``lambda_s``
        (then the two colour bars).
    """

    width, height = info.im_width, info.im_height
    figure = Figure(figsize=(12, 7.5), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(2, 2)
    for ax, name, intensity, dims in (
        (axes[0, 0], "birth", context.birth, BIRTH_POSITION_DIMS),
        (axes[0, 1], "clutter", context.clutter, CLUTTER_POSITION_DIMS),
    ):
        values = position_map(intensity, dims, width, height)
        image = draw_intensity(ax, values, width, height, float(values.max()))
        figure.colorbar(image, ax=ax, fraction=0.035, label="events / frame / px²")
        ax.set_title(f"learned {name} intensity ({float(intensity.magnitude):.3g} / frame)")
    i_r, i_s = sweep.slice_index()
    scores = {row["variant"]: row["MOTA"] for row in rows}
    for ax, rates, index, label in (
        (axes[1, 0], sweep.clutter_rates, np.s_[:, i_s], "lambda_r (false detections / frame)"),
        (axes[1, 1], sweep.birth_rates, np.s_[i_r, :], "lambda_s (births / frame)"),
    ):
        for variant, grids in sweep.scores.items():
            ax.plot(rates, grids["MOTA"][index], marker="o", label=f"{variant}")
        ax.set_xscale("log")
        ax.set_xticks(rates, tick_labels(rates))
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel(label)
        ax.set_ylabel("MOTA (%)")
        ax.grid(alpha=0.3)
    axes[1, 0].set_title(f"MOTA vs clutter magnitude (lambda_s = {sweep.birth_rates[i_s]:.2g})")
    axes[1, 1].set_title(f"MOTA vs birth magnitude (lambda_r = {sweep.clutter_rates[i_r]:.2g})")
    axes[1, 0].legend()
    figure.suptitle(
        f"{info.name}: context learned on the first half; test half MOTA UM {scores['UM']:.1f}, "
        f"GM {scores['GM']:.1f}"
    )
    return figure


def save_tuning_figure(steps, losses, summary, path: str | Path) -> Path:
    """Writes :func:`tuning_figure` to the PNG ``path``."""
    return _save(tuning_figure(steps, losses, summary), path)


def tuning_figure(steps, losses, summary) -> Figure:
    """Loss and test MOTA against the optimisation step, one column per dataset.

    The grid choice's test MOTA is drawn as a horizontal line, 95% of it dashed.

    Args:
        steps: rows with ``dataset``, ``step`` and ``MOTA`` (test MOTA after that step).
        losses: ``{dataset: [loss per step]}``.
        summary: rows with ``dataset``, ``method`` and ``MOTA``; the ``grid...`` row is drawn.

    Returns:
        The figure: loss axes of each dataset, then their MOTA axes.
    """
    names = list(losses)
    figure = Figure(figsize=(5 * len(names), 6), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(2, len(names), squeeze=False)
    for column, name in enumerate(names):
        loss_axes, mota_axes = axes[0, column], axes[1, column]
        loss_axes.plot(np.arange(len(losses[name])), losses[name], color="C0")
        loss_axes.set_title(name)
        loss_axes.set_ylabel("loss (-log-likelihood / frame)")
        rows = [r for r in steps if r["dataset"] == name]
        mota_axes.plot([r["step"] for r in rows], [r["MOTA"] for r in rows], "o-", color="C1")
        grid = next(r for r in summary if r["dataset"] == name and r["method"].startswith("grid"))
        mota_axes.axhline(grid["MOTA"], color="k", label=f"grid choice ({grid['MOTA']:.1f})")
        mota_axes.axhline(0.95 * grid["MOTA"], color="k", linestyle="--", label="95% of it")
        mota_axes.set_xlabel("adam step")
        mota_axes.set_ylabel("test MOTA (%)")
        mota_axes.legend(loc="lower right")
    return figure
