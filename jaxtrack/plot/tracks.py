"""The particle PHD tracker on one frame (PHD-context Fig. 3): particles, estimates, tracks.

Drawn over the video frame when one is given, else over a blank canvas of the image size:

* the particle cloud as the box centres ``(y1, y2)``, each point's opacity and area
  proportional to its weight (relative to the heaviest particle; after resampling the
  weights are equal and the density shows as the concentration of points);
* the extracted states (:class:`~jaxtrack.association.estimates.Estimates`) as dashed white
  boxes labelled with their PHD mass;
* the labelled tracks of the frame as solid boxes coloured by identity, each with the trail
  of its box centres over the previous frames (``trail`` frames, 30 by default).

:func:`draw_phd_frame` draws on given axes; :func:`phd_frame_figure` writes the PNG of a
frame of a run (:func:`jaxtrack.pipelines.tracking.phd_frame_snapshot` runs the tracker up to
it). Matplotlib's object-oriented API with the Agg canvas: no display,
no pyplot global state.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from jaxtrack.association.estimates import Estimates
from jaxtrack.types import Tracks

if TYPE_CHECKING:
    from matplotlib.axes import Axes

#: Default number of previous frames in a track's trail.
DEFAULT_TRAIL = 30
#: Qualitative colour map of the track identities (colour = id modulo its size).
TRACK_COLOURS = "tab20"
#: Colour of the particles and of the estimate boxes.
PARTICLE_COLOUR = "tab:cyan"
ESTIMATE_COLOUR = "white"
#: Largest particle marker area (points squared) and opacity, for the heaviest particle.
PARTICLE_MAX_AREA = 6.0
PARTICLE_MAX_ALPHA = 0.6


def track_colour(track_id: int) -> tuple[float, float, float, float]:
    """The RGBA colour of a track identity (:data:`TRACK_COLOURS`, cycling)."""
    palette = colormaps[TRACK_COLOURS]
    return palette(int(track_id) % palette.N)


def draw_phd_frame(
    ax: Axes,
    particles: Any,
    log_weights: Any,
    estimates: Estimates,
    tracks: Tracks,
    image: np.ndarray | None = None,
    image_size: tuple[float, float] | None = None,
    title: str | None = None,
) -> None:
    """Draws one frame of the PHD tracker on ``ax``.

    Args:
        ax: matplotlib axes.
        particles: ``[num_particles, 6]`` states ``(y1, vy1, y2, vy2, w, h)``.
        log_weights: ``[num_particles]`` log-weights.
        estimates: the frame's extracted states (one frame, ``states [max_estimates, 6]``).
        tracks: labelled boxes of the frames that make the trails (top-left ``x, y, w, h``,
            ``[num_frames, max_objects]``); the last frame is the drawn one, whose tracks get
            boxes. ``num_frames`` may be 1 (no trails).
        image: the video frame, ``[height, width, 3]`` uint8, drawn underneath.
        image_size: ``(width, height)`` of the blank canvas when there is no image.
        title: axes title.

    Raises:
        ValueError: an image that is not ``[height, width, 3]`` uint8, neither an image nor
            an image size, or arrays of inconsistent shapes.
    """
    particles = np.asarray(particles, np.float64)
    log_weights = np.asarray(log_weights, np.float64)
    if particles.ndim != 2 or particles.shape[1] != 6:
        raise ValueError(f"particles must be [num_particles, 6], got {particles.shape}")
    if log_weights.shape != particles.shape[:1]:
        raise ValueError(
            f"log_weights {log_weights.shape} do not match particles {particles.shape}"
        )
    boxes, ids, mask = (np.asarray(x) for x in (tracks.boxes, tracks.ids, tracks.mask))
    if boxes.ndim != 3:
        raise ValueError(f"tracks must hold [num_frames, max_objects] boxes, got {boxes.shape}")
    width, height = _canvas_size(image, image_size)

    if image is None:
        ax.set_facecolor("0.93")
    else:
        ax.imshow(image, extent=(0, width, height, 0), interpolation="nearest")
    ax.set_xlim(0, width)
    ax.set_ylim(height, 0)
    ax.set_aspect("equal")

    relative = np.exp(log_weights - np.max(log_weights)) if len(log_weights) else log_weights
    colours = np.zeros((len(relative), 4))
    colours[:, :3] = to_rgb(PARTICLE_COLOUR)
    colours[:, 3] = PARTICLE_MAX_ALPHA * relative
    ax.scatter(
        particles[:, 0],
        particles[:, 2],
        s=PARTICLE_MAX_AREA * relative,
        c=colours,
        linewidths=0,
        label="particles",
    )

    estimate_mask = np.asarray(estimates.mask)
    for state, mass in zip(
        np.asarray(estimates.states)[estimate_mask],
        np.asarray(estimates.masses)[estimate_mask],
        strict=True,
    ):
        y1, _, y2, _, w, h = state
        ax.add_patch(
            Rectangle(
                (y1 - w / 2, y2 - h / 2), w, h, fill=False, color=ESTIMATE_COLOUR, lw=1, ls="--"
            )
        )
        ax.text(
            y1 - w / 2, y2 + h / 2 + 2, f"{mass:.2f}", color=ESTIMATE_COLOUR, fontsize=6, va="top"
        )

    current = mask[-1]
    for box, track_id in zip(boxes[-1][current], ids[-1][current], strict=True):
        colour = track_colour(track_id)
        in_trail = mask & (ids == track_id)
        centres = boxes[in_trail][:, :2] + boxes[in_trail][:, 2:] / 2
        ax.plot(centres[:, 0], centres[:, 1], color=colour, lw=1.5, alpha=0.8)
        ax.add_patch(Rectangle(box[:2], box[2], box[3], fill=False, color=colour, lw=1.5, ls="-"))
        ax.text(box[0], box[1] - 2, str(int(track_id)), color=colour, fontsize=8, fontweight="bold")

    if title is not None:
        ax.set_title(title, fontsize=9)


def phd_frame_figure(
    snapshot: Any,
    out_path: str | Path,
    image: np.ndarray | None = None,
    first_frame: int = 1,
    image_size: tuple[float, float] | None = None,
    dpi: int = 100,
) -> Path:
    """Saves the figure of one frame of a PHD tracker run as a PNG.

    Args:
        snapshot: the tracker on that frame
            (:func:`jaxtrack.pipelines.tracking.phd_frame_snapshot`): ``particles``,
            ``log_weights``, ``mass`` after the frame's update and resampling, the frame's
            ``estimates``, the ``tracks`` of the frame and of its trail (the last row is the
            frame), and its 0-based ``frame_index``.
        out_path: the PNG to write (parent folders are created).
        image: the video frame, ``[height, width, 3]`` uint8 (RGB).
        first_frame: MOT frame number of frame index 0 (for the title).
        image_size: ``(width, height)`` of the blank canvas when there is no image.
        dpi: resolution; the figure is sized so that one image pixel is about one PNG pixel
            at 100 dpi.

    Returns:
        The path of the PNG.

    Raises:
        ValueError: a bad image, or neither an image nor an image size.
    """
    width, height = _canvas_size(image, image_size)
    num_tracks = int(np.sum(np.asarray(snapshot.tracks.mask)[-1]))
    num_estimates = int(np.sum(np.asarray(snapshot.estimates.mask)))
    figure = Figure(figsize=(width / 100 + 0.4, height / 100 + 0.6))
    FigureCanvasAgg(figure)
    ax = figure.add_subplot()
    draw_phd_frame(
        ax,
        snapshot.particles,
        snapshot.log_weights,
        snapshot.estimates,
        snapshot.tracks,
        image=image,
        image_size=(width, height),
        title=(
            f"frame {first_frame + snapshot.frame_index}: {snapshot.particles.shape[0]} "
            f"particles, PHD mass {float(snapshot.mass):.2f}, {num_estimates} estimates, "
            f"{num_tracks} tracks"
        ),
    )
    figure.tight_layout()
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(out_path, dpi=dpi)
    return out_path


def _canvas_size(
    image: np.ndarray | None, image_size: tuple[float, float] | None
) -> tuple[float, float]:
    """``(width, height)`` of the drawing: the image's, else ``image_size``."""
    if image is not None:
        image = np.asarray(image)
        if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
            raise ValueError(
                f"image must be [height, width, 3] uint8, got {image.shape} {image.dtype}"
            )
        return float(image.shape[1]), float(image.shape[0])
    if image_size is None:
        raise ValueError("give either an image or the image size (width, height)")
    width, height = image_size
    if not (width > 0 and height > 0):
        raise ValueError(f"image size must be positive, got {image_size}")
    return float(width), float(height)
