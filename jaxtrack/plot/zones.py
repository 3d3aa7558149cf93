"""Figure of a scene's structure: entry/exit zones and activity mask over a video frame.

:func:`save_zones_figure` draws, over the frame in grey: the activity mask (light blue), the
start (green triangles up) and end points (red triangles down) of the training
trajectories, the points of dropped clusters (grey crosses: too few points, or interior,
their cluster circled by a dashed line), and each zone's box (yellow) with its number and
counts. Matplotlib's object-oriented API with the Agg canvas: no display, no pyplot state.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Rectangle

from jaxtrack.context.zones import LearnedZones, SceneZones

if TYPE_CHECKING:
    from matplotlib.axes import Axes

#: Colour of the zone boxes and their labels.
ZONE_COLOUR = "gold"
#: Colour map of the activity mask (transparent, then light blue).
ACTIVITY_COLOURS = ListedColormap([(0, 0, 0, 0), (0.4, 0.8, 1.0, 0.35)])


def draw_zones(
    ax: Axes,
    zones: SceneZones,
    image_size: tuple[int, int],
    labels: list[str] | None = None,
    learned: LearnedZones | None = None,
    background: np.ndarray | None = None,
) -> None:
    """Draws zones (and how they were learned) on ``ax``.

    Args:
        ax: matplotlib axes.
        zones: the zones and activity mask.
        image_size: ``(width, height)``, pixels.
        labels: one label per zone (default: its number).
        learned: the endpoints and clusters behind the zones, drawn when given.
        background: ``[H, W, 3]`` or ``[H, W]`` frame drawn underneath in grey.
    """
    width, height = image_size
    if background is not None:
        grey = background.mean(axis=-1) if background.ndim == 3 else background
        ax.imshow(grey, cmap="gray", extent=(0, width, height, 0), interpolation="bilinear")
    if zones.activity is not None:
        rows, columns = zones.activity.shape
        extent = (0, columns * zones.cell_size, rows * zones.cell_size, 0)
        mask = np.asarray(zones.activity, np.float64)
        ax.imshow(mask, cmap=ACTIVITY_COLOURS, vmin=0, vmax=1, extent=extent)
    if learned is not None:
        _draw_endpoints(ax, learned)
    labels = labels or [str(k + 1) for k in range(len(zones.boxes))]
    for box, label in zip(np.asarray(zones.boxes), labels, strict=True):
        ax.add_patch(
            Rectangle(box[:2], box[2], box[3], fill=False, edgecolor=ZONE_COLOUR, linewidth=2)
        )
        right_half = box[0] + box[2] / 2 > width / 2  # labels grow towards the image centre
        ax.text(
            box[0] + box[2] if right_half else box[0],
            box[1] + box[3] / 2,
            label,
            color="black",
            fontsize=8,
            ha="right" if right_half else "left",
            va="center",
            bbox={"facecolor": ZONE_COLOUR, "alpha": 0.8, "pad": 1.5, "linewidth": 0},
        )
    ax.set_xlim(0, width)
    ax.set_ylim(height, 0)
    ax.set_aspect("equal")


def _draw_endpoints(ax: Axes, learned: LearnedZones) -> None:
    """Start/end points of the zones' clusters, and the dropped clusters' points circled."""
    points, entry = learned.endpoints.points, learned.endpoints.is_entry
    kept = np.isin(learned.labels, learned.zone_clusters)
    for mask, marker, colour in ((entry, "^", "limegreen"), (~entry, "v", "red")):
        ax.scatter(
            *points[kept & mask].T,
            marker=marker,
            s=18,
            c=colour,
            edgecolors="black",
            linewidths=0.4,
            zorder=3,
        )
    ax.scatter(*points[~kept].T, marker="x", s=16, c="0.6", linewidths=1, zorder=3)
    for cluster in np.flatnonzero(learned.interior):
        members = points[learned.labels == cluster]
        radius = np.max(np.linalg.norm(members - learned.cluster_centres[cluster], axis=1))
        ax.add_patch(
            Circle(
                learned.cluster_centres[cluster],
                radius + 10,
                fill=False,
                edgecolor="0.6",
                linestyle="--",
                linewidth=1.2,
            )
        )


def save_zones_figure(
    path: str | Path,
    zones: SceneZones,
    image_size: tuple[int, int],
    labels: list[str] | None = None,
    learned: LearnedZones | None = None,
    background: np.ndarray | None = None,
    title: str = "",
) -> None:
    """Writes the zones figure (:func:`draw_zones`) as an image file.

    Args:
        path: the file (PNG, or any format matplotlib writes).
        zones: the zones and activity mask.
        image_size: ``(width, height)``, pixels.
        labels: one label per zone (default: its number).
        learned: the endpoints and clusters behind the zones.
        background: a video frame drawn underneath.
        title: figure title.
    """
    width, height = image_size
    figure = Figure(figsize=(8.0, 8.0 * height / width + 0.5))
    FigureCanvasAgg(figure)
    ax = figure.subplots()
    draw_zones(ax, zones, image_size, labels, learned, background)
    if title:
        ax.set_title(title, fontsize=9)
    ax.tick_params(labelsize=7)
    figure.tight_layout()
    figure.savefig(Path(path), dpi=100)
