"""Figures of learned scene context: intensity heat maps and the evolution of the mixtures.

* :func:`save_intensity_maps` (PHD-context Fig. 8): the birth and clutter intensities as
  heat maps over the image plane. The value at a pixel is the intensity's marginal over the
  box centre, ``lambda p(y1, y2)`` (expected events per frame per square pixel; velocities
  and sizes integrated out, :func:`jaxtrack.context.learn.marginal`), shown on a square-root
  colour scale so that both sharp modes and the weak uniform floor stay visible. A video
  frame, when given, is drawn underneath in grey. When the true intensities are known
  (synthetic scenes) they are drawn beside the learned ones on the same colour scale.
* :func:`save_mixture_evolution` (PHD-context Fig. 7 and 11): the density after more and
  more samples (top row) and its live Gaussian components as 2-sigma ellipses of the
  centre position over the samples learned so far (bottom row).
* :func:`save_context_plots` writes both for a :class:`~jaxtrack.context.learn.LearnedContext`.

Matplotlib's object-oriented API with the Agg canvas: no display, no pyplot global state.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import EllipseCollection
from matplotlib.colors import PowerNorm, to_rgba
from matplotlib.figure import Figure

from jaxtrack.context.intensity import Intensity
from jaxtrack.context.learn import (
    BIRTH_POSITION_DIMS,
    CLUTTER_POSITION_DIMS,
    LearnedContext,
    Snapshot,
    marginal,
)
from jaxtrack.context.map_em import to_intensity

if TYPE_CHECKING:
    from matplotlib.axes import Axes

#: Grid step of the heat maps, pixels.
MAP_STEP = 4.0
#: Colour map of the heat maps.
COLOUR_MAP = "inferno"


def position_map(
    intensity: Intensity,
    dims: tuple[int, int],
    width: float,
    height: float,
    step: float = MAP_STEP,
) -> np.ndarray:
    """The intensity's marginal over the box centre on a pixel grid.

    The marginal (:func:`~jaxtrack.context.learn.marginal`) is 2-D, so it is evaluated here
    in closed form with NumPy over the live components only (the batched triangular solves
    of :func:`~jaxtrack.context.intensity.log_density` are slow on CPU for whole images).

    Args:
        intensity: a birth or clutter intensity.
        dims: its ``(column, row)`` centre axes (``(0, 2)`` for births, ``(0, 1)`` for clutter).
        width: image width, pixels.
        height: image height, pixels.
        step: grid step, pixels; cell ``(i, j)`` is centred on ``((j + 1/2) step, (i + 1/2)
            step)``.

    Returns:
        ``[rows, columns]`` expected events per frame per square pixel.
    """
    centre = marginal(intensity, dims)
    columns = (np.arange(int(np.ceil(width / step))) + 0.5) * step
    rows = (np.arange(int(np.ceil(height / step))) + 0.5) * step
    uniform_weight = float(centre.uniform_weight)
    area = float(np.prod(np.asarray(centre.upper, np.float64) - np.asarray(centre.lower)))
    density = np.full((rows.size, columns.size), uniform_weight / area)
    weights = np.asarray(centre.weights, np.float64)
    alive = weights > 0
    if uniform_weight < 1 and np.any(alive):
        means = np.asarray(centre.means, np.float64)[alive]
        covs = np.asarray(centre.covs, np.float64)[alive]
        det = covs[:, 0, 0] * covs[:, 1, 1] - covs[:, 0, 1] ** 2
        dx = columns[None, None, :] - means[:, 0, None, None]
        dy = rows[None, :, None] - means[:, 1, None, None]
        var_x, cov_xy, var_y = (
            value[:, None, None] for value in (covs[:, 0, 0], covs[:, 0, 1], covs[:, 1, 1])
        )
        quadratic = (var_y * dx**2 - 2 * cov_xy * dx * dy + var_x * dy**2) / det[:, None, None]
        log_terms = np.log(weights[alive] / (2 * np.pi * np.sqrt(det)))[:, None, None]
        log_terms = log_terms - 0.5 * quadratic
        top = log_terms.max(axis=0)
        mixture = np.exp(top) * np.exp(log_terms - top).sum(axis=0)
        density = density + (1 - uniform_weight) * mixture
    return float(centre.magnitude) * density


def draw_intensity(
    ax: Axes,
    values: np.ndarray,
    width: float,
    height: float,
    vmax: float,
    background: np.ndarray | None = None,
):
    """Draws a heat map from :func:`position_map` on ``ax`` (over a grey video frame if given).

    Args:
        ax: matplotlib axes.
        values: ``[rows, columns]`` map.
        width: image width, pixels.
        height: image height, pixels.
        vmax: top of the colour scale.
        background: ``[H, W]`` or ``[H, W, 3]`` image drawn underneath, or None.

    Returns:
        The ``AxesImage`` of the heat map (for a colour bar).
    """
    norm = PowerNorm(gamma=0.5, vmin=0.0, vmax=vmax)
    extent = (0, width, height, 0)
    alpha = None
    if background is not None:
        grey = background.mean(axis=-1) if background.ndim == 3 else background
        ax.imshow(grey, cmap="gray", extent=extent, interpolation="bilinear")
        alpha = np.clip(0.15 + 0.85 * norm(values).filled(0.0), 0.0, 1.0)
    image = ax.imshow(
        values, cmap=COLOUR_MAP, norm=norm, extent=extent, alpha=alpha, interpolation="bilinear"
    )
    ax.set_xlim(0, width)
    ax.set_ylim(height, 0)
    ax.set_aspect("equal")
    return image


def save_intensity_maps(
    path: str | Path,
    birth: Intensity,
    clutter: Intensity,
    width: float,
    height: float,
    truth: tuple[Intensity, Intensity] | None = None,
    background: np.ndarray | None = None,
    title: str = "",
) -> None:
    """Writes the birth and clutter heat maps (learned, and true when given) as a PNG.

    Args:
        path: the PNG file.
        birth: learned birth intensity (6-D).
        clutter: learned clutter intensity (4-D).
        width: image width, pixels.
        height: image height, pixels.
        truth: the true ``(birth, clutter)`` intensities, drawn in a second column.
        background: a video frame drawn under every map.
        title: figure title.
    """
    rows = (
        ("birth", BIRTH_POSITION_DIMS, birth, truth[0] if truth else None),
        ("clutter", CLUTTER_POSITION_DIMS, clutter, truth[1] if truth else None),
    )
    columns = 2 if truth else 1
    panel = 4.2
    figure = Figure(figsize=(panel * width / height * columns + 1.2 * columns, 2 * panel + 0.8))
    FigureCanvasAgg(figure)
    axes = figure.subplots(2, columns, squeeze=False)
    for row, (name, dims, learned, true) in enumerate(rows):
        maps = [("learned", position_map(learned, dims, width, height), learned)]
        if true is not None:
            maps.append(("true", position_map(true, dims, width, height), true))
        vmax = max(float(values.max()) for _, values, _ in maps)
        for column, (kind, values, intensity) in enumerate(maps):
            ax = axes[row, column]
            image = draw_intensity(ax, values, width, height, vmax, background)
            alive = int(np.sum(np.asarray(intensity.weights) > 0))
            ax.set_title(
                f"{kind} {name}: {float(intensity.magnitude):.3g}/frame, "
                f"pi_u {float(intensity.uniform_weight):.3g}, {alive} Gaussians",
                fontsize=9,
            )
            colour_bar = figure.colorbar(image, ax=ax, fraction=0.035, pad=0.02)
            colour_bar.set_label("events / frame / px² (centre)", fontsize=7)
            colour_bar.ax.tick_params(labelsize=6)
    if title:
        figure.suptitle(title, fontsize=10)
    figure.tight_layout()
    figure.savefig(Path(path), dpi=100)


def draw_components(
    ax: Axes,
    snapshot: Snapshot,
    dims: tuple[int, int],
    width: float,
    height: float,
) -> None:
    """Draws a snapshot's live components (2-sigma centre ellipses) over its samples.

    Args:
        ax: matplotlib axes.
        snapshot: the mixture and the samples learned so far.
        dims: the ``(column, row)`` centre axes.
        width: image width, pixels.
        height: image height, pixels.
    """
    state = snapshot.state
    weights = np.asarray(state.weights, np.float64)
    alive = np.asarray(state.alive)
    means = np.asarray(state.means, np.float64)[:, dims]
    covs = np.asarray(state.covs, np.float64)[:, dims][:, :, dims]
    seen = snapshot.samples
    if seen.shape[0]:
        ax.plot(seen[:, dims[0]], seen[:, dims[1]], ".", color="tab:red", ms=2, zorder=1)
    if np.any(alive):
        values, vectors = np.linalg.eigh(covs[alive])
        angles = np.degrees(np.arctan2(vectors[:, 1, 1], vectors[:, 0, 1]))
        share = weights[alive] / weights[alive].max()
        colours = np.zeros((share.size, 4))
        colours[:] = to_rgba("tab:blue")
        colours[:, 3] = 0.3 + 0.7 * share
        ax.add_collection(
            EllipseCollection(
                4 * np.sqrt(values[:, 1]),
                4 * np.sqrt(values[:, 0]),
                angles,
                units="xy",
                offsets=means[alive],
                offset_transform=ax.transData,
                facecolors="none",
                edgecolors=colours,
                linewidths=0.5 + 1.5 * share,
                zorder=2,
            )
        )
    ax.set_xlim(0, width)
    ax.set_ylim(height, 0)
    ax.set_aspect("equal")
    ax.set_facecolor("0.95")


def save_mixture_evolution(
    path: str | Path,
    snapshots: Sequence[Snapshot],
    dims: tuple[int, int],
    width: float,
    height: float,
    title: str = "",
) -> None:
    """Writes the evolution of a mixture with the number of samples as a PNG.

    Top row: the density's centre marginal (magnitude 1) after each snapshot; bottom row:
    the live components and the samples learned so far.

    Args:
        path: the PNG file.
        snapshots: e.g. ``LearnedContext.birth_snapshots``.
        dims: the ``(column, row)`` centre axes of the state.
        width: image width, pixels.
        height: image height, pixels.
        title: figure title.
    """
    count = len(snapshots)
    panel = 2.6
    figure = Figure(figsize=(panel * width / height * count + 0.4, 2 * panel + 0.9))
    FigureCanvasAgg(figure)
    axes = figure.subplots(2, count, squeeze=False)
    for column, snapshot in enumerate(snapshots):
        values = position_map(to_intensity(snapshot.state, 1.0), dims, width, height)
        draw_intensity(axes[0, column], values, width, height, float(values.max()))
        draw_components(axes[1, column], snapshot, dims, width, height)
        alive = int(np.sum(np.asarray(snapshot.state.alive)))
        label = f"n = {snapshot.num_samples}"
        if snapshot.epochs:
            label += f", {snapshot.epochs} passes"
        axes[0, column].set_title(label, fontsize=9)
        axes[1, column].set_title(
            f"{alive} Gaussians, pi_u {float(snapshot.state.uniform_weight):.3g}", fontsize=8
        )
        for ax in axes[:, column]:
            ax.tick_params(labelsize=6)
    if title:
        figure.suptitle(title, fontsize=10)
    figure.tight_layout()
    figure.savefig(Path(path), dpi=100)


def save_context_plots(
    out_dir: str | Path,
    learned: LearnedContext,
    width: float,
    height: float,
    truth: tuple[Intensity, Intensity] | None = None,
    background: np.ndarray | None = None,
) -> list[Path]:
    """Writes ``intensities.png``, ``birth_evolution.png`` and ``clutter_evolution.png``.

    Args:
        out_dir: the folder (created if needed).
        learned: the result of :func:`~jaxtrack.context.learn.learn_context`.
        width: image width, pixels.
        height: image height, pixels.
        truth: the true ``(birth, clutter)`` intensities (synthetic scenes), or None.
        background: a video frame for the heat maps, or None.

    Returns:
        The files written.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    meta = learned.metadata
    name = meta.get("sequence_name", "")
    first, last = meta.get("frames", ("?", "?"))
    paths = [out / "intensities.png", out / "birth_evolution.png", out / "clutter_evolution.png"]
    save_intensity_maps(
        paths[0],
        learned.birth,
        learned.clutter,
        width,
        height,
        truth,
        background,
        title=f"{name} frames {first}:{last}: birth from {learned.birth_samples.source}, "
        f"clutter from {learned.clutter_samples.source}",
    )
    for path, snapshots, dims, kind in (
        (paths[1], learned.birth_snapshots, BIRTH_POSITION_DIMS, "birth"),
        (paths[2], learned.clutter_snapshots, CLUTTER_POSITION_DIMS, "clutter"),
    ):
        save_mixture_evolution(
            path, snapshots, dims, width, height, title=f"{name}: {kind} density (centre marginal)"
        )
    return paths
