"""Figures of the experiments: context ablation (PHD-context Fig. 14), tracker comparison (Fig. 16).

* :func:`save_ablation_figure`: for each variant but the reference (UM), one group of bars,
  the % difference of each score with respect to UM (the ``<score>_diff_pct`` columns of
  :func:`jaxtrack.experiments.ablation.ablation_table`).
* :func:`save_comparison_figure`: one panel per score; per sequence a group of bars, one per
  tracker (the rows of :func:`jaxtrack.experiments.comparison.comparison_table`).

Matplotlib's object-oriented API with the Agg canvas: no display, no pyplot global state.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


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


def save_ablation_figure(
    rows: Sequence[dict],
    path: str | Path,
    scores: Sequence[str] = ("MOTA", "MOTP", "MODA", "MODP"),
    reference: str = "UM",
    title: str = "",
) -> Path:
    """Bars of each variant's score % difference w.r.t. the reference (PHD-context Fig. 14).

    Args:
        rows: table rows with ``variant`` and ``<score>_diff_pct`` for each score.
        path: the PNG to write.
        scores: the scores drawn (one bar each per variant).
        reference: the variant the differences are taken against (not drawn).
        title: the figure's title.

    Returns:
        ``path`` as a :class:`~pathlib.Path`.
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
    path = Path(path)
    figure.savefig(path, dpi=100)
    return path


def save_comparison_figure(
    rows: Sequence[dict],
    path: str | Path,
    scores: Sequence[str] = ("MOTA", "MOTP", "MODA", "MODP"),
    title: str = "",
) -> Path:
    """One panel per score, bars per sequence and tracker (PHD-context Fig. 16).

    Args:
        rows: table rows with ``sequence``, ``tracker`` and the scores (in percent).
        path: the PNG to write.
        scores: the scores drawn, one panel each.
        title: the figure's title.

    Returns:
        ``path`` as a :class:`~pathlib.Path`.
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
    path = Path(path)
    figure.savefig(path, dpi=100)
    return path
