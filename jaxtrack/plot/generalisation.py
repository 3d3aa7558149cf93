"""Figure of the context-generalisation experiment: relative MOTA gain over UM per scene group.

:func:`gain_figure` draws, for each scene group (a family of the scene bank or a real
sequence), one bar per variant: the mean over the group's seeds of the relative MOTA gain
``100 (MOTA - MOTA_UM) / |MOTA_UM|``, with error marks from the smallest to the largest
gain over the seeds, a line at 0 and a dashed line at the goal (+9 %, PHD-context's lower
bound); under each group's name, the gain a perfect tracker would make over UM (the ceiling:
a group whose UM already scores MOTA 93 cannot gain 9 %). Its input is the long summary of
:func:`jaxtrack.experiments.context_generalisation.summarise` (one row per group and
variant).

Matplotlib's object-oriented API with the Agg canvas: no display, no pyplot global state.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


def save_gain_figure(rows: Sequence[dict], path: str | Path, *args, **kwargs) -> Path:
    """Writes :func:`gain_figure` (and its other arguments) to ``path`` as a PNG."""
    path = Path(path)
    gain_figure(rows, *args, **kwargs).savefig(path, dpi=100)
    return path


def gain_figure(
    rows: Sequence[dict],
    variants: Sequence[str] = ("GM",),
    goal: float = 9.0,
    title: str = "",
) -> Figure:
    """Bars of the relative MOTA gain over UM per group and variant, min/max marks over seeds.

    Args:
        rows: summary rows with ``group``, ``variant``, ``gain_pct_mean``, ``gain_pct_min``
            and ``gain_pct_max`` (percent); groups are drawn in their first-seen order.
        variants: the variants drawn (one bar container each); one with no row is left out.
        goal: the height of the dashed goal line (percent).
        title: the figure's title.

    Returns:
        The figure: one axes; one bar container per drawn variant (a missing or NaN gain is
        drawn as 0 without error mark), the horizontal lines at 0 and at ``goal``.
    """
    groups = list(dict.fromkeys(row["group"] for row in rows))
    by_key = {(row["group"], row["variant"]): row for row in rows}
    drawn = [name for name in variants if any((g, name) in by_key for g in groups)]
    figure = Figure(figsize=(min(14.0, max(7.0, 0.45 * len(groups) * max(1, len(drawn)) + 3)), 4.5))
    figure.set_layout_engine("constrained")
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    width = 0.8 / max(1, len(drawn))
    positions = np.arange(len(groups))
    for index, name in enumerate(drawn):
        offset = (index - (len(drawn) - 1) / 2) * width
        values = [by_key.get((group, name)) for group in groups]
        means = [_finite(row, "gain_pct_mean") for row in values]
        low = [m - _finite(row, "gain_pct_min", m) for m, row in zip(means, values, strict=True)]
        high = [_finite(row, "gain_pct_max", m) - m for m, row in zip(means, values, strict=True)]
        axes.bar(
            positions + offset,
            means,
            width,
            yerr=np.array([low, high]),
            capsize=3,
            label=name,
        )
    axes.axhline(0.0, color="black", linewidth=0.8)
    axes.axhline(goal, color="tab:red", linestyle="--", linewidth=1.0, label=f"goal +{goal:g} %")
    axes.set_xticks(positions, [_tick_label(group, by_key) for group in groups])
    axes.tick_params(axis="x", labelrotation=30 if len(groups) > 4 else 0)
    axes.set_ylabel("MOTA gain over UM (%)")
    axes.grid(axis="y", alpha=0.3)
    axes.legend()
    axes.set_title(title or "Relative MOTA gain over UM (bars: mean over seeds; marks: min-max)")
    return figure


def _tick_label(group: str, by_key: dict) -> str:
    """The group's name, and below it the gain a perfect tracker would make (``ceiling``,
    from UM's row's ``gain_ceiling_pct``) when the summary has it."""
    ceiling = float(by_key.get((group, "UM"), {}).get("gain_ceiling_pct", math.nan))
    return group if math.isnan(ceiling) else f"{group}\n(ceiling {ceiling:+.1f} %)"


def _finite(row: dict | None, key: str, default: float = 0.0) -> float:
    """``row[key]``, or ``default`` when there is no row or the value is NaN."""
    if row is None:
        return default
    value = float(row[key])
    return default if math.isnan(value) else value
