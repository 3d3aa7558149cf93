"""Preview of a synthetic scene: one frame's boxes over the scene's context.

Drawn on a plain image-sized canvas (synthetic scenes have no pixels): entry zones (2-sigma
ellipses, widened by a zone's extent, with the mean entry velocity as an arrow, exits
dashed), clutter sources (likewise), the centres of every clutter detection and every birth
of the sequence (faint dots and crosses, showing where context concentrates), and the chosen
frame's ground truth (green, with ids), true detections (blue) and clutter detections (red).
Uses matplotlib's object-oriented API with the Agg canvas: no display and no pyplot global
state.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse, Rectangle

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from jaxtrack.datasets.synthetic import SyntheticScene

#: Arrow length of a zone's mean velocity, in frames of motion.
ARROW_FRAMES = 10.0


def default_preview_frame(scene: SyntheticScene) -> int:
    """The frame a preview shows by default.

    Args:
        scene: the scene.

    Returns:
        The first frame (1-based) with the most live targets.
    """
    return int(np.argmax(scene.num_targets)) + 1


def draw_scene_frame(ax: Axes, scene: SyntheticScene, frame: int) -> None:
    """Draws one frame of a synthetic scene with its context on ``ax``.

    Args:
        ax: matplotlib axes.
        scene: the scene.
        frame: 1-based frame number.

    Raises:
        ValueError: ``frame`` outside ``1..seq_length``.
    """
    info, config = scene.info, scene.config
    if not 1 <= frame <= info.seq_length:
        raise ValueError(f"frame {frame} outside 1..{info.seq_length}")
    ax.set_xlim(0, info.im_width)
    ax.set_ylim(info.im_height, 0)
    ax.set_aspect("equal")
    ax.set_facecolor("0.93")

    det_boxes = scene.det_table.boxes
    centres = det_boxes[:, :2] + det_boxes[:, 2:] / 2
    clutter = scene.is_clutter
    ax.scatter(*centres[clutter].T, s=2, c="tab:red", alpha=0.15, linewidths=0)
    births = scene.birth_states
    ax.scatter(births[:, 0], births[:, 2], s=14, c="tab:green", marker="x", alpha=0.5)

    for zone in config.zones:
        (c1, c2), (s1, s2) = zone.centre, _spread(zone)
        ax.add_patch(
            Ellipse(
                (c1, c2),
                4 * s1,
                4 * s2,
                fill=False,
                color="tab:green",
                linestyle="--" if zone.exit else "-",
                linewidth=1.5,
            )
        )
        v1, v2 = zone.velocity
        ax.annotate(
            "",
            xy=(c1 + ARROW_FRAMES * v1, c2 + ARROW_FRAMES * v2),
            xytext=(c1, c2),
            arrowprops={"arrowstyle": "->", "color": "tab:green"},
        )
        ax.text(c1, c2 - 2 * s2 - 4, zone.name, color="darkgreen", ha="center", fontsize=8)
    for source in config.clutter_sources:
        (c1, c2), (s1, s2) = source.centre, _spread(source)
        ax.add_patch(Ellipse((c1, c2), 4 * s1, 4 * s2, fill=False, color="tab:red", lw=1.5))
        ax.text(
            c1,
            c2 - 2 * s2 - 4,
            f"{source.name} ({source.rate:g}/frame)",
            color="darkred",
            ha="center",
            fontsize=8,
        )

    in_frame = scene.gt_table.frames == frame
    for box, target_id in zip(
        scene.gt_table.boxes[in_frame], scene.gt_table.ids[in_frame], strict=True
    ):
        ax.add_patch(Rectangle(box[:2], box[2], box[3], fill=False, color="tab:green", lw=1.5))
        ax.text(box[0], box[1] - 2, str(target_id), color="darkgreen", fontsize=7)
    in_frame = scene.det_table.frames == frame
    for box, is_clutter in zip(det_boxes[in_frame], clutter[in_frame], strict=True):
        color = "tab:red" if is_clutter else "tab:blue"
        ax.add_patch(Rectangle(box[:2], box[2], box[3], fill=False, color=color, lw=1, ls=":"))

    num_clutter = int(np.sum(clutter[in_frame]))
    ax.set_title(
        f"{info.name}, frame {frame}: {int(scene.num_targets[frame - 1])} targets (green), "
        f"{int(np.sum(in_frame)) - num_clutter} detections (blue), {num_clutter} clutter (red)",
        fontsize=9,
    )


def save_scene_preview(
    scene: SyntheticScene, path: str | Path, frame: int | None = None, dpi: int = 100
) -> None:
    """Saves a PNG of one frame drawn by :func:`draw_scene_frame`.

    Args:
        scene: the scene.
        path: the PNG file to write.
        frame: 1-based frame; default :func:`default_preview_frame`.
        dpi: resolution; the figure is sized so that one pixel of the image is about one
            pixel of the PNG at 100 dpi.
    """
    frame = default_preview_frame(scene) if frame is None else frame
    info = scene.info
    figure = Figure(figsize=(info.im_width / 100 + 0.6, info.im_height / 100 + 0.6))
    FigureCanvasAgg(figure)
    ax = figure.add_subplot()
    draw_scene_frame(ax, scene, frame)
    figure.tight_layout()
    figure.savefig(Path(path), dpi=dpi)


def _spread(part) -> tuple[float, float]:
    """Per axis, std + extent / 2: the drawn ellipse spans 2 stds plus the extent each side."""
    return tuple(
        std + extent / 2 for std, extent in zip(part.position_std, part.extent, strict=True)
    )
