"""The Hierarchical tracker's two levels and events on video frames (``track-video --annotate``).

As the paper's Fig. 3: each estimate is drawn as the ellipse of its box (the ellipse
inscribed in the box), the low-level tracks in white (confirmed: solid; tentative: thin), the
high-level trackers in black (lost ones, propagated by their motion model: thin), each
high-level tracker with its identity and its event state (Sec. 5.5) above it.
:func:`hier_frame_outputs` keeps, per frame, what drawing needs (and the tracks and events
for the result rows); :func:`draw_levels` draws one frame.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import cv2
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from jaxtrack.filters.hier_events import EVENT_NAMES
from jaxtrack.types import Tracks

#: Colours of the low-level and high-level ellipses (the paper's Fig. 3: white, black).
LOW_COLOUR = (255, 255, 255)
HIGH_COLOUR = (0, 0, 0)
#: Line widths: confirmed low-level tracks (wider than the high level's, so that the white
#: shows on both sides of a black ellipse drawn over the same box), followed high-level
#: trackers, and tentative tracks / lost trackers.
LOW_THICK, HIGH_THICK, THIN = 6, 2, 1


class HierarchicalFrame(NamedTuple):
    """What ``track-video --annotate`` keeps of a Hierarchical frame.

    Attributes:
        tracks, candidates: for the result rows.
        events, event_ids: each high-level slot's event state and identity (-1: free).
        low_boxes: ``[T, 4]`` the low-level estimates; ``low_alive``, ``low_confirmed``.
        high_boxes: ``[S, 4]`` the high-level estimates; ``high_lost`` while lost.
        merged: the identities merged into each slot's tracker on the frame (-1: none).
    """

    tracks: Tracks
    candidates: Tracks
    events: Int[Array, " S"]
    event_ids: Int[Array, " S"]
    low_boxes: Float[Array, "T 4"]
    low_alive: Bool[Array, " T"]
    low_confirmed: Bool[Array, " T"]
    high_boxes: Float[Array, "S 4"]
    high_lost: Bool[Array, " S"]
    merged: Int[Array, " S"]


def hier_frame_outputs(state: Any, info: Any, index: Array) -> HierarchicalFrame:
    """The per-frame output of a Hierarchical run to draw (``frame_output`` of
    :func:`~jaxtrack.filters.base.run`)."""
    del state, index
    return HierarchicalFrame(
        info.tracks,
        info.candidates,
        info.events,
        info.event_ids,
        info.low_boxes,
        info.low_alive,
        info.low_confirmed,
        info.high_boxes,
        info.high_lost,
        info.merged,
    )


def _ellipse(image: np.ndarray, box: np.ndarray, colour, thickness: int) -> None:
    """Draws the ellipse inscribed in ``box`` ``(x, y, w, h)`` in place."""
    x, y, w, h = (float(v) for v in box)
    centre = (round(x + w / 2), round(y + h / 2))
    axes = (max(round(w / 2), 1), max(round(h / 2), 1))
    cv2.ellipse(image, centre, axes, 0.0, 0.0, 360.0, colour, thickness, cv2.LINE_AA)


def draw_levels(image: np.ndarray, frame: HierarchicalFrame) -> np.ndarray:
    """Draws one frame's low-level tracks (white), high-level trackers (black) and events.

    Args:
        image: RGB ``uint8`` ``[height, width, 3]`` (not modified).
        frame: the frame's :class:`HierarchicalFrame` (NumPy leaves, one frame).

    Returns:
        The annotated copy.
    """
    out = image.copy()
    for box, confirmed in zip(
        frame.low_boxes[frame.low_alive], frame.low_confirmed[frame.low_alive], strict=True
    ):
        _ellipse(out, box, LOW_COLOUR, LOW_THICK if confirmed else THIN)
    alive = frame.event_ids >= 0
    for box, lost, identity, event in zip(
        frame.high_boxes[alive],
        frame.high_lost[alive],
        frame.event_ids[alive],
        frame.events[alive],
        strict=True,
    ):
        _ellipse(out, box, HIGH_COLOUR, THIN if lost else HIGH_THICK)
        text = f"{int(identity)} {EVENT_NAMES[int(event)]}" + (" (lost)" if lost else "")
        origin = (round(float(box[0])), max(round(float(box[1])) - 4, 10))
        cv2.putText(out, text, origin, cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 3)
        cv2.putText(out, text, origin, cv2.FONT_HERSHEY_SIMPLEX, 0.4, HIGH_COLOUR, 1)
    return out
