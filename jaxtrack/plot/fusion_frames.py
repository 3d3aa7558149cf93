"""The Fusion tracker's pool and fused boxes on video frames (``track-video --annotate``).

Per slot alive on the frame (a target or a hypothesis,
:data:`~jaxtrack.filters.fusion_voting.TARGET` / ``TENTATIVE``):

* each pool member's response box ``R_i`` (paper Sec. 3.2: the assigned detection, the
  classifier's peak, the motion model's prediction) as a thin rectangle in the member's
  colour (:data:`MEMBER_COLOURS`);
* a target's fused box ``R`` (paper eq. 6, or the naive mean) as a thick rectangle in its
  identity's colour, with the identity on a black tag below it; an occluded target's (Sec.
  2.2, eq. 2: ``Q > 0.3`` and not the occluder) dashed, labelled ``occluded``;
* a hypothesis (a detection not yet voted in, Sec. 3.1) as a grey rectangle labelled
  ``hyp`` and the identity it keeps when voted in.

:func:`fusion_frame_outputs` keeps, per frame, what drawing needs (and the tracks for the
result rows); :func:`draw_fusion` draws one frame and :func:`draw_fusion_legend` the key in
the top-right corner.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import cv2
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from jaxtrack.errors import InputError
from jaxtrack.filters.fusion import MEMBERS
from jaxtrack.filters.fusion_voting import TARGET, TENTATIVE
from jaxtrack.io.video import id_colour
from jaxtrack.types import Tracks

#: RGB colour of each pool member's response box, in :data:`MEMBERS` order (not white: the
#: detections are drawn in white).
MEMBER_COLOURS = ((0, 255, 255), (255, 0, 255), (255, 255, 0))
#: Colour of a hypothesis's box.
HYPOTHESIS_COLOUR = (160, 160, 160)
#: Line widths: a member's response, a hypothesis, a target's fused box (wider than the
#: 2-pixel result boxes drawn under it, which it covers).
MEMBER_THICK, HYPOTHESIS_THICK, FUSED_THICK = 1, 2, 4
#: Lengths in pixels of the dashes of an occluded target's box and of the gaps between them.
DASH = 6
#: Font and scale of the labels under the boxes (on a black tag).
LABEL_FONT, LABEL_SCALE = cv2.FONT_HERSHEY_SIMPLEX, 0.4
#: Height in pixels of a legend row; the legend's margin from the image's corner and width.
LEGEND_ROW, LEGEND_MARGIN, LEGEND_WIDTH = 16, 6, 112
#: The legend's rows after the members': a sample line's colour, width, dashing, and name.
STYLE_ROWS = (
    ((255, 255, 255), FUSED_THICK, False, "fused"),
    ((255, 255, 255), FUSED_THICK, True, "occluded"),
    (HYPOTHESIS_COLOUR, HYPOTHESIS_THICK, False, "hypothesis"),
)


class FusionFrame(NamedTuple):
    """What ``track-video --annotate`` keeps of a Fusion frame.

    Attributes:
        tracks, candidates: for the result rows; ``candidates`` holds every live slot's
            fused box and identity.
        members: ``[S, M, 4]`` each member's response box ``(x, y, w, h)`` (:data:`MEMBERS`).
        member_valid: ``[S, M]`` the member is in the pool and responded.
        status: ``[S]`` voting status (``TENTATIVE``: hypothesis, ``TARGET``).
        occluded: ``[S]`` occluded targets.
    """

    tracks: Tracks
    candidates: Tracks
    members: Float[Array, "S M 4"]
    member_valid: Bool[Array, "S M"]
    status: Int[Array, " S"]
    occluded: Bool[Array, " S"]


def fusion_frame_outputs(state: Any, info: Any, index: Array) -> FusionFrame:
    """The per-frame output of a Fusion run to draw (``frame_output`` of
    :func:`~jaxtrack.filters.base.run`), from its :class:`~jaxtrack.filters.fusion.FusionInfo`."""
    del state, index
    return FusionFrame(
        info.tracks,
        info.candidates,
        info.members,
        info.member_valid,
        info.status,
        info.occluded,
    )


def _corners(box: np.ndarray) -> tuple[tuple[int, int], tuple[int, int]]:
    x, y, w, h = (float(v) for v in box)
    return (round(x), round(y)), (round(x + w), round(y + h))


def _dashed_rectangle(image: np.ndarray, box: np.ndarray, colour, thickness: int) -> None:
    """Draws the rectangle of ``box`` in place as dashes of :data:`DASH` pixels, gaps of
    :data:`DASH` pixels, each side starting with a dash at its first corner."""
    (left, top), (right, bottom) = _corners(box)
    sides = (
        ((left, top), (right, top)),
        ((right, top), (right, bottom)),
        ((right, bottom), (left, bottom)),
        ((left, bottom), (left, top)),
    )
    for start, end in sides:
        length = max(abs(end[0] - start[0]), abs(end[1] - start[1]))
        step = np.sign(np.subtract(end, start))
        for offset in range(0, length + 1, 2 * DASH):
            first = np.add(start, step * offset)
            last = np.add(start, step * min(offset + DASH - 1, length))
            cv2.line(image, tuple(first.tolist()), tuple(last.tolist()), colour, thickness)


def _label(image: np.ndarray, text: str, box: np.ndarray, colour) -> None:
    """Writes ``text`` in place on a black tag under ``box``, in ``colour``."""
    (left, _), (_, bottom) = _corners(box)
    (width, height), baseline = cv2.getTextSize(text, LABEL_FONT, LABEL_SCALE, 1)
    top = bottom + FUSED_THICK // 2 + 1
    cv2.rectangle(
        image, (left, top), (left + width + 2, top + height + baseline + 2), (0, 0, 0), -1
    )
    cv2.putText(image, text, (left + 1, top + height + 1), LABEL_FONT, LABEL_SCALE, colour, 1)


def draw_fusion(image: np.ndarray, frame: FusionFrame) -> np.ndarray:
    """Draws one frame's member responses, fused boxes, occlusions and hypotheses.

    The members' boxes are drawn first, then the hypotheses, then the targets, so a fused
    box covers the responses along its edges.

    Args:
        image: RGB ``uint8`` ``[height, width, 3]`` (not modified).
        frame: the frame's :class:`FusionFrame` (NumPy leaves, one frame).

    Returns:
        The annotated copy.

    Raises:
        InputError: a non-finite box of a live slot or of a valid response.
    """
    out = image.copy()
    status = np.asarray(frame.status)
    live = (status == TENTATIVE) | (status == TARGET)
    boxes = np.asarray(frame.candidates.boxes)[live]
    members = np.asarray(frame.members)[live]
    valid = np.asarray(frame.member_valid)[live]
    if not (np.isfinite(boxes).all() and np.isfinite(members[valid]).all()):
        raise InputError("non-finite box of a live Fusion slot")
    ids = np.asarray(frame.candidates.ids)[live]
    target = status[live] == TARGET
    occluded = np.asarray(frame.occluded)[live]
    for slot_members, slot_valid in zip(members, valid, strict=True):
        for box, colour, responded in zip(slot_members, MEMBER_COLOURS, slot_valid, strict=True):
            if responded:
                cv2.rectangle(out, *_corners(box), colour, MEMBER_THICK)
    for box, identity in zip(boxes[~target], ids[~target], strict=True):
        cv2.rectangle(out, *_corners(box), HYPOTHESIS_COLOUR, HYPOTHESIS_THICK)
        _label(out, f"hyp {int(identity)}", box, HYPOTHESIS_COLOUR)
    for box, identity, hidden in zip(boxes[target], ids[target], occluded[target], strict=True):
        colour = id_colour(int(identity))
        if hidden:
            _dashed_rectangle(out, box, colour, FUSED_THICK)
        else:
            cv2.rectangle(out, *_corners(box), colour, FUSED_THICK)
        _label(out, f"{int(identity)} occluded" if hidden else str(int(identity)), box, colour)
    return out


def draw_fusion_legend(image: np.ndarray, shown: Sequence[bool]) -> np.ndarray:
    """Draws the key in the top-right corner of a copy of an RGB ``uint8`` image, on a dark
    box: a sample line per member of :data:`MEMBERS` with ``shown`` (e.g. the members that
    responded in the run), then the fused, occluded and hypothesis boxes' styles."""
    rows = [
        (colour, MEMBER_THICK, False, name)
        for colour, name, show in zip(MEMBER_COLOURS, MEMBERS, shown, strict=True)
        if show
    ]
    rows += STYLE_ROWS
    out = image.copy()
    right = out.shape[1] - LEGEND_MARGIN
    left = right - LEGEND_WIDTH
    bottom = LEGEND_MARGIN + LEGEND_ROW * len(rows) + 4
    cv2.rectangle(out, (left, LEGEND_MARGIN), (right, bottom), (32, 32, 32), -1)
    for row, (colour, thickness, dashed, name) in enumerate(rows):
        y = LEGEND_MARGIN + LEGEND_ROW * row + LEGEND_ROW // 2 + 2
        start, end = (left + 6, y), (left + 6 + 2 * DASH + DASH, y)
        if dashed:
            cv2.line(out, start, (start[0] + DASH - 1, y), colour, thickness)
            cv2.line(out, (start[0] + 2 * DASH, y), end, colour, thickness)
        else:
            cv2.line(out, start, end, colour, thickness)
        cv2.putText(
            out, name, (left + 30, y + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1
        )
    return out
