"""Interactive clutter labelling: click the detections that are not objects of interest.

:class:`ClutterLabeller` shows chosen frames one at a time, each with its detections as
rectangles (green: object, red: clutter). A left click inside a detection toggles it
between object and clutter; where boxes overlap, the click goes to the smallest box that
contains it. Keys: ``right``/``n`` next frame, ``left``/``p`` previous frame, ``s`` save,
``q`` save and close (closing the window saves too). A frame counts as labelled once it has
been shown: its detections that were not clicked are objects. Labels are written with
:func:`jaxtrack.context.clutter_labels.save_clutter_labels`.

The event handlers are plain methods (:meth:`ClutterLabeller.on_click`,
:meth:`ClutterLabeller.on_key`) connected with ``mpl_connect``, so the tool runs on any
canvas, including a headless Agg canvas driven by synthetic events in tests.
:func:`label_interactively` opens it in a window with pyplot and an interactive backend.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib
import numpy as np
from matplotlib.backend_bases import MouseButton
from matplotlib.patches import Rectangle

from jaxtrack.context.clutter_labels import ClutterLabels, clutter_mask, save_clutter_labels
from jaxtrack.errors import InputError

if TYPE_CHECKING:
    from matplotlib.backend_bases import KeyEvent, MouseEvent
    from matplotlib.figure import Figure

    from jaxtrack.io.motchallenge import MotTable

#: Edge colour of a detection labelled clutter.
CLUTTER_COLOUR = "tab:red"
#: Edge colour of a detection labelled object (the default).
OBJECT_COLOUR = "tab:green"
#: Grey level of the canvas drawn when there is no frame source.
CANVAS_GREY = 128
#: Keys and what they do.
NEXT_KEYS = ("right", "n")
PREVIOUS_KEYS = ("left", "p")
SAVE_KEY = "s"
QUIT_KEY = "q"
HELP_TEXT = (
    "left click on a box: toggle clutter (red) / object (green)    "
    "n or \u2192: next frame    p or \u2190: previous    s: save    q: save and close"
)


class ClutterLabeller:
    """A clutter-labelling session on a matplotlib figure.

    Args:
        figure: the figure to draw on (its canvas receives the events).
        det_table: detections (at least those of ``frames``; other rows are ignored).
        frames: 1-based frames to show, in showing order, distinct.
        out_path: the labels file that :meth:`save` writes.
        sequence: sequence name stored in the labels.
        image_size: ``(width, height)`` of the frames in pixels.
        frame_source: ``frame -> RGB uint8 [height, width, 3]`` (e.g.
            :meth:`jaxtrack.io.video.VideoReader.read`); None draws a grey canvas.
        resume: labels of an earlier session: its clutter detections start red and its
            labelled frames count as labelled; the session starts at the first frame not
            labelled yet.

    Attributes:
        frames: the frames to show, int64 ``[num_frames]``.
        index: position in ``frames`` of the frame shown.
        rectangles: the shown frame's rectangles, one per detection row in ``rows``.
        rows: the ``det_table`` rows of the shown frame, in drawing order.
        closed: True after ``q`` or after the window was closed.

    Raises:
        ValueError: no frames, a repeated frame, ``resume`` for another sequence or image
            size, or with labelled frames that are not in ``frames``.
        InputError: a ``resume`` label that matches no detection of ``det_table``.
    """

    def __init__(
        self,
        figure: Figure,
        det_table: MotTable,
        frames: Sequence[int],
        out_path: str | Path,
        *,
        sequence: str,
        image_size: tuple[int, int],
        frame_source: Callable[[int], np.ndarray] | None = None,
        resume: ClutterLabels | None = None,
    ):
        self.frames = np.asarray(frames, dtype=np.int64).reshape(-1)
        if self.frames.size == 0:
            raise ValueError("no frames to label")
        if np.unique(self.frames).size != self.frames.size:
            raise ValueError("frames to label must be distinct")
        self.figure = figure
        self.out_path = Path(out_path)
        self.sequence = sequence
        self.image_size = (int(image_size[0]), int(image_size[1]))
        self.frame_source = frame_source

        shown = np.isin(det_table.frames, self.frames)
        self.frame_of_row = det_table.frames[shown]
        self.boxes = det_table.boxes[shown]
        self.is_clutter = np.zeros(self.frame_of_row.shape[0], dtype=bool)
        self.visited = np.zeros(self.frames.shape[0], dtype=bool)
        if resume is not None:
            self._apply_resume(resume)

        self.closed = False
        self.rows = np.zeros(0, dtype=np.int64)
        self.rectangles: list[Rectangle] = []
        self.ax = figure.add_axes((0.02, 0.07, 0.96, 0.86))
        self.ax.set_axis_off()
        width, height = self.image_size
        self.image = self.ax.imshow(
            self._grey(), extent=(0, width, height, 0), interpolation="nearest"
        )
        self.ax.set_xlim(0, width)
        self.ax.set_ylim(height, 0)
        figure.text(0.5, 0.02, HELP_TEXT, ha="center", fontsize=8)

        canvas = figure.canvas
        manager = canvas.manager
        if manager is not None and getattr(manager, "key_press_handler_id", None) is not None:
            canvas.mpl_disconnect(manager.key_press_handler_id)
        self._connections = [
            canvas.mpl_connect("button_press_event", self.on_click),
            canvas.mpl_connect("key_press_event", self.on_key),
            canvas.mpl_connect("close_event", self.on_close),
        ]
        start = np.flatnonzero(~self.visited)
        self.show(int(start[0]) if start.size else 0)

    def _apply_resume(self, resume: ClutterLabels) -> None:
        if resume.sequence != self.sequence or resume.image_size != self.image_size:
            raise ValueError(
                f"labels are for {resume.sequence} at {resume.image_size[0]}x"
                f"{resume.image_size[1]}, not {self.sequence} at "
                f"{self.image_size[0]}x{self.image_size[1]}"
            )
        outside = np.setdiff1d(resume.labelled_frames, self.frames)
        if outside.size:
            raise ValueError(f"labelled frame {int(outside[0])} is not among the frames to show")
        self.is_clutter = clutter_mask(resume, self.frame_of_row, self.boxes)
        self.visited = np.isin(self.frames, resume.labelled_frames)

    def _grey(self) -> np.ndarray:
        width, height = self.image_size
        return np.full((height, width, 3), CANVAS_GREY, dtype=np.uint8)

    @property
    def frame(self) -> int:
        """The 1-based frame shown."""
        return int(self.frames[self.index])

    def show(self, index: int) -> None:
        """Shows ``frames[index]`` with its detections and marks it labelled.

        Args:
            index: position in :attr:`frames`, ``0 <= index < len(frames)``.
        """
        if not 0 <= index < self.frames.shape[0]:
            raise IndexError(f"frame index {index} outside 0..{self.frames.shape[0] - 1}")
        self.index = index
        self.visited[index] = True
        pixels = self._grey() if self.frame_source is None else self.frame_source(self.frame)
        width, height = self.image_size
        if pixels.shape[:2] != (height, width):
            raise ValueError(
                f"frame {self.frame} is {pixels.shape[1]}x{pixels.shape[0]}, "
                f"expected {width}x{height}"
            )
        self.image.set_data(pixels)
        for rectangle in self.rectangles:
            rectangle.remove()
        self.rows = np.flatnonzero(self.frame_of_row == self.frame)
        self.rectangles = []
        for row in self.rows:
            x, y, w, h = self.boxes[row]
            rectangle = Rectangle(
                (x, y), w, h, fill=False, linewidth=2, edgecolor=self._colour(row)
            )
            self.ax.add_patch(rectangle)
            self.rectangles.append(rectangle)
        self._refresh()

    def _colour(self, row: int) -> str:
        return CLUTTER_COLOUR if self.is_clutter[row] else OBJECT_COLOUR

    def _refresh(self, note: str = "") -> None:
        in_frame = int(self.is_clutter[self.rows].sum())
        total = int(self.is_clutter[np.isin(self.frame_of_row, self.frames[self.visited])].sum())
        self.ax.set_title(
            f"{self.sequence}  frame {self.frame}  ({self.index + 1}/{self.frames.shape[0]})"
            f"    clutter {in_frame} of {self.rows.shape[0]} detections here"
            f"    {total} clutter in {int(self.visited.sum())} labelled frames{note}",
            fontsize=9,
        )
        self.figure.canvas.draw_idle()

    def detection_at(self, x: float, y: float) -> int | None:
        """The shown frame's detection under a point: the smallest box that contains it.

        Args:
            x: horizontal image coordinate (pixels).
            y: vertical image coordinate (pixels, downwards).

        Returns:
            The row (index into :attr:`boxes`), or None when no box contains the point.
        """
        boxes = self.boxes[self.rows]
        inside = (
            (boxes[:, 0] <= x)
            & (x <= boxes[:, 0] + boxes[:, 2])
            & (boxes[:, 1] <= y)
            & (y <= boxes[:, 1] + boxes[:, 3])
        )
        if not inside.any():
            return None
        area = np.where(inside, boxes[:, 2] * boxes[:, 3], np.inf)
        return int(self.rows[np.argmin(area)])

    def toggle(self, row: int) -> None:
        """Flips a detection of the shown frame between clutter and object.

        Identical detections (same box on the same frame) cannot be told apart by the labels
        file, so they flip together.
        """
        if row not in self.rows:
            raise ValueError(f"row {row} is not a detection of frame {self.frame}")
        same = (self.boxes[self.rows] == self.boxes[row]).all(axis=1)
        self.is_clutter[self.rows[same]] = not self.is_clutter[row]
        for position in np.flatnonzero(same):
            self.rectangles[position].set_edgecolor(self._colour(row))
        self._refresh()

    def on_click(self, event: MouseEvent) -> None:
        """Left click inside a detection of the shown frame: toggles it (see :meth:`toggle`).

        Clicks outside the image axes, with another button, or while the toolbar's zoom or
        pan mode is active do nothing.
        """
        if self.closed or event.inaxes is not self.ax or event.button != MouseButton.LEFT:
            return
        toolbar = self.figure.canvas.toolbar
        if toolbar is not None and toolbar.mode:
            return
        row = self.detection_at(event.xdata, event.ydata)
        if row is not None:
            self.toggle(row)

    def on_key(self, event: KeyEvent) -> None:
        """``right``/``n`` next frame, ``left``/``p`` previous, ``s`` save, ``q`` save+close."""
        if self.closed:
            return
        if event.key in NEXT_KEYS:
            if self.index + 1 < self.frames.shape[0]:
                self.show(self.index + 1)
            else:
                self._refresh("    (last frame: q saves and closes)")
        elif event.key in PREVIOUS_KEYS:
            if self.index > 0:
                self.show(self.index - 1)
        elif event.key == SAVE_KEY:
            self.save()
            self._refresh(f"    saved to {self.out_path.name}")
        elif event.key == QUIT_KEY:
            self.close()

    def on_close(self, event) -> None:
        """The window was closed: saves, unless :meth:`close` already did."""
        if not self.closed:
            self.closed = True
            self.save()

    def labels(self) -> ClutterLabels:
        """The labels so far: clutter detections on the frames shown at least once."""
        labelled = np.sort(self.frames[self.visited])
        keep = self.is_clutter & np.isin(self.frame_of_row, labelled)
        keys = np.column_stack([self.frame_of_row, self.boxes])
        _, first = np.unique(keys, axis=0, return_index=True)
        keep &= np.isin(np.arange(keep.shape[0]), first)
        order = np.flatnonzero(keep)[np.argsort(self.frame_of_row[keep], kind="stable")]
        return ClutterLabels(
            sequence=self.sequence,
            image_size=self.image_size,
            labelled_frames=labelled,
            frames=self.frame_of_row[order],
            boxes=self.boxes[order],
            pending_frames=self.frames[~self.visited],
        )

    def save(self) -> ClutterLabels:
        """Writes :meth:`labels` to :attr:`out_path` and returns them."""
        labels = self.labels()
        save_clutter_labels(self.out_path, labels)
        return labels

    def close(self) -> None:
        """Saves, stops reacting to events and closes the figure's window (if it has one)."""
        if self.closed:
            return
        self.save()
        self.closed = True
        for connection in self._connections:
            self.figure.canvas.mpl_disconnect(connection)
        from matplotlib import pyplot

        pyplot.close(self.figure)


def interactive_figure(image_size: tuple[int, int], backend: str | None = None) -> Figure:
    """Opens a pyplot figure for an image, on an interactive backend.

    Args:
        image_size: ``(width, height)`` of the frames, for the figure's aspect ratio.
        backend: matplotlib backend to use (e.g. ``"tkagg"``, ``"qtagg"``); default: the one
            matplotlib picks (``MPLBACKEND``, matplotlibrc, or the first that works).

    Returns:
        A new pyplot figure whose canvas can open a window.

    Raises:
        InputError: the backend cannot be loaded, or it is not interactive (no display).
    """
    from matplotlib import pyplot

    if backend is not None:
        try:
            pyplot.switch_backend(backend)
        except (ImportError, ValueError, RuntimeError) as err:
            raise InputError(
                f"cannot use the matplotlib backend {backend!r}: {err}. label-clutter needs a "
                "display (DISPLAY set, or a desktop session) and the backend's GUI toolkit"
            ) from None
    width, height = image_size
    figure = pyplot.figure(figsize=(10, 10 * height / width + 0.8))
    if type(figure.canvas).required_interactive_framework is None:
        pyplot.close(figure)
        raise InputError(
            f"no interactive matplotlib backend: {matplotlib.get_backend()!r} cannot open a "
            "window (headless session?). label-clutter needs a display: run it in a desktop "
            "session or over X forwarding (DISPLAY must be set), or name an interactive "
            "backend with --backend (e.g. tkagg, qtagg; needs tkinter or PyQt)"
        )
    return figure


def label_interactively(
    det_table: MotTable,
    frames: Sequence[int],
    out_path: str | Path,
    *,
    sequence: str,
    image_size: tuple[int, int],
    frame_source: Callable[[int], np.ndarray] | None = None,
    resume: ClutterLabels | None = None,
    backend: str | None = None,
) -> ClutterLabels:
    """Runs a labelling session in a window until it is closed (``q`` or the window's close).

    Args:
        det_table: detections.
        frames: frames to show, in order.
        out_path: labels file to write.
        sequence: sequence name.
        image_size: ``(width, height)``.
        frame_source: ``frame -> RGB image``, or None for a grey canvas.
        resume: labels of an earlier session to continue.
        backend: matplotlib backend (see :func:`interactive_figure`).

    Returns:
        The labels as last saved.

    Raises:
        InputError: no interactive backend (see :func:`interactive_figure`).
    """
    from matplotlib import pyplot

    figure = interactive_figure(image_size, backend)
    labeller = ClutterLabeller(
        figure,
        det_table,
        frames,
        out_path,
        sequence=sequence,
        image_size=image_size,
        frame_source=frame_source,
        resume=resume,
    )
    pyplot.show(block=True)
    labeller.close()
    return labeller.labels()
