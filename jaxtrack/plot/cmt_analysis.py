"""Figures of CMT's analyses (Cui et al., Fig. 8 and Fig. 9; numbers from
:mod:`jaxtrack.experiments.cmt_analysis`).

* :func:`prediction_figure`: the summed particle-to-ground-truth distance per frame of each
  proposal (the contextual proposal against the Gaussian prior), one panel per comparison.
* :func:`discrimination_figure`: the likelihood difference per frame between two nearby
  similar targets under COM and EWOM, with the zero line (below it: A's model prefers B).
* :func:`crossing_families_figure`: per family of crossing scenes (how alike the pair dress),
  the variants' SE on the crossings and the pair's switched identities, and Fig. 9's mean
  likelihood gap under COM and EWOM
  (:mod:`jaxtrack.experiments.cmt_crossings`).

Each ``save_<name>`` writes the PNG of the Figure built by ``<name>``. Matplotlib's
object-oriented API with the Agg canvas: no display, no pyplot global state.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


def prediction_figure(
    frames: np.ndarray, panels: Mapping[str, Mapping[str, np.ndarray]], title: str
) -> Figure:
    """One panel per comparison (its title -> the proposals' values), one line per proposal:
    the summed distance of a target's proposed particles to its ground-truth centre (mean
    over the tracked targets), per frame."""
    figure = Figure(figsize=(8, 3 * len(panels)), layout="constrained")
    FigureCanvasAgg(figure)
    figure.suptitle(title)
    for axes, (name, distances) in zip(
        figure.subplots(len(panels), 1, squeeze=False)[:, 0], panels.items(), strict=True
    ):
        for label, values in distances.items():
            axes.plot(frames, values, label=f"{label} (mean {np.nanmean(values):.0f} px)")
        axes.set_xlabel("frame")
        axes.set_ylabel("summed distance (px)")
        axes.set_title(name)
        axes.grid(alpha=0.3)
        axes.legend()
    return figure


def save_prediction_figure(path: str | Path, *args) -> Path:
    """Writes :func:`prediction_figure` as a PNG."""
    path = Path(path)
    prediction_figure(*args).savefig(path, dpi=100)
    return path


def discrimination_figure(frames: np.ndarray, gaps: Mapping[str, np.ndarray], title: str) -> Figure:
    """One line per observation model: ``log p(z_A | m_A) - log p(z_B | m_A)`` per frame."""
    figure = Figure(figsize=(8, 3.5), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    for label, values in gaps.items():
        axes.plot(frames, values, marker=".", label=label)
    axes.axhline(0.0, color="black", linewidth=0.8)
    axes.set_xlabel("frame")
    axes.set_ylabel("likelihood difference A - B")
    axes.set_title(title)
    axes.grid(alpha=0.3)
    axes.legend()
    return figure


def save_discrimination_figure(path: str | Path, *args) -> Path:
    """Writes :func:`discrimination_figure` as a PNG."""
    path = Path(path)
    discrimination_figure(*args).savefig(path, dpi=100)
    return path


def crossing_families_figure(
    rows: Sequence[Mapping], gaps: Mapping[str, Mapping[str, float]]
) -> Figure:
    """Three panels over the families (``rows``: one per family and tracker with
    ``SE_crossings``, ``crossing_swap_frames``, ``switched``, ``kept``, ``lost``; ``gaps``:
    family -> ``{"COM", "EWOM"}`` mean likelihood gaps): grouped bars per tracker."""
    families = list(dict.fromkeys(row["family"] for row in rows))
    trackers = list(dict.fromkeys(row["tracker"] for row in rows))
    by = {(row["family"], row["tracker"]): row for row in rows}
    figure = Figure(figsize=(12, 3.8), layout="constrained")
    FigureCanvasAgg(figure)
    figure.suptitle("Crossings of similarly dressed people: EWOM (MTb+CPD) vs COM (CMT)")
    left, middle, right = figure.subplots(1, 3)
    x = np.arange(len(families))
    width = 0.8 / len(trackers)

    def bars(axes, values, labels, offset, name):
        drawn = axes.bar(x + offset, values, width, label=name)
        axes.bar_label(drawn, labels=labels, fontsize=8)

    for i, name in enumerate(trackers):
        offset = (i - (len(trackers) - 1) / 2) * width
        chosen = [by[family, name] for family in families]
        bars(
            left,
            [row["SE_crossings"] for row in chosen],
            [str(row["crossing_swap_frames"]) for row in chosen],
            offset,
            name,
        )
        scored = [row["kept"] + row["switched"] + row["lost"] for row in chosen]
        bars(
            middle,
            [100 * row["switched"] / max(1, n) for row, n in zip(chosen, scored, strict=True)],
            [f"{row['switched']}/{n}" for row, n in zip(chosen, scored, strict=True)],
            offset,
            name,
        )
    for i, model in enumerate(("EWOM", "COM")):
        right.bar(x + (i - 0.5) * 0.4, [gaps[f][model] for f in families], 0.4, label=model)
    titles = (
        ("SE on the crossings (%; labels: swap frames)", left),
        ("pair's identity switched across the crossing (%)", middle),
        ("Fig. 9 mean likelihood gap A - B", right),
    )
    for title, axes in titles:
        axes.set_xticks(x, [f"alike: {family}" for family in families])
        axes.set_title(title, fontsize=10)
        axes.grid(alpha=0.3, axis="y")
        axes.legend(fontsize=8)
    return figure


def save_crossing_families_figure(path: str | Path, *args) -> Path:
    """Writes :func:`crossing_families_figure` as a PNG."""
    path = Path(path)
    crossing_families_figure(*args).savefig(path, dpi=100)
    return path
