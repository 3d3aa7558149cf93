"""Figures of CMT's analyses (Cui et al., Fig. 8 and Fig. 9; numbers from
:mod:`jaxtrack.experiments.cmt_analysis`).

* :func:`prediction_figure`: the summed particle-to-ground-truth distance per frame of each
  proposal (the contextual proposal against the Gaussian prior), one panel per comparison.
* :func:`discrimination_figure`: the likelihood difference per frame between two nearby
  similar targets under COM and EWOM, with the zero line (below it: A's model prefers B).

Each ``save_<name>`` writes the PNG of the Figure built by ``<name>``. Matplotlib's
object-oriented API with the Agg canvas: no display, no pyplot global state.
"""

from __future__ import annotations

from collections.abc import Mapping
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
