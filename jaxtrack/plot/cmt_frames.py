"""CMT's particles on video frames, coloured by their motion condition (``track-video --annotate``).

Each frame of a CMT run (:mod:`jaxtrack.filters.cmt`) proposes, for every living local
tracker (mixture component) ``m``, particles ``x_t^{m,i}`` from the contextual proposal after
drawing a motion condition ``h`` from ``{normal, split, merge, exit}`` (CMT Sec. IV-B, eqs.
6-10; :mod:`~jaxtrack.filters.cmt_conditions`). :func:`cmt_frame_outputs` keeps, per frame,
what drawing them needs (the particles' box centres, their conditions, the living slots, and
the tracks for the result rows); :func:`draw_particles` draws each particle as a small dot in
its condition's colour (:data:`CONDITION_COLOURS`), and :func:`draw_condition_legend` names
the colours in the top-right corner.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import cv2
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from jaxtrack.errors import InputError
from jaxtrack.filters.cmt_conditions import EXIT, MERGE, NORMAL, SPLIT
from jaxtrack.models.dynamics import POSITION
from jaxtrack.types import Tracks

#: RGB colour and name of each particle motion condition, in drawing order (the rare
#: conditions last, on top of the normal particles).
CONDITION_COLOURS: dict[int, tuple[tuple[int, int, int], str]] = {
    NORMAL: ((0, 255, 255), "normal"),
    SPLIT: ((255, 255, 0), "split"),
    MERGE: ((255, 0, 255), "merge"),
    EXIT: ((255, 64, 0), "exit"),
}
#: Radius in pixels of a particle's dot.
PARTICLE_RADIUS = 2
#: Colour of the one-pixel outline around the particle cloud (sets the dots apart from the
#: tracks' boxes and trails, whose id colours may be close to the conditions').
OUTLINE_COLOUR = (0, 0, 0)
#: Height in pixels of a legend row; the legend's margin from the image's corner.
LEGEND_ROW = 16
LEGEND_MARGIN = 6
#: Width in pixels of the legend's box.
LEGEND_WIDTH = 74


class CMTFrame(NamedTuple):
    """What ``track-video --annotate`` keeps of a CMT frame.

    Attributes:
        tracks: the confirmed components' local decisions (for the result rows).
        candidates: every supported component's local decision (for the result rows).
        centres: ``[max_components, num_particles, 2]`` the particles' box centres ``(x, y)``.
        conditions: ``[max_components, num_particles]`` their motion conditions.
        alive: ``[max_components]`` the slots alive during the frame.
    """

    tracks: Tracks
    candidates: Tracks
    centres: Float[Array, "max_components num_particles 2"]
    conditions: Int[Array, "max_components num_particles"]
    alive: Bool[Array, " max_components"]


def cmt_frame_outputs(state: Any, info: Any, index: Array) -> CMTFrame:
    """The per-frame output of a CMT run to draw (``frame_output`` of
    :func:`~jaxtrack.filters.base.run`): a :class:`CMTFrame` of its
    :class:`~jaxtrack.filters.cmt.CMTInfo` (the centres are the state's position
    coordinates ``(y1, y2)``, :data:`~jaxtrack.models.dynamics.POSITION`)."""
    del state, index
    return CMTFrame(
        info.tracks, info.candidates, info.particles[..., POSITION], info.conditions, info.alive
    )


def draw_particles(
    image: np.ndarray, centres: np.ndarray, conditions: np.ndarray, alive: np.ndarray
) -> np.ndarray:
    """Draws the living components' particles as dots coloured by their motion condition.

    Each dot is a disc of :data:`PARTICLE_RADIUS` pixels in its condition's colour; all dots
    are first drawn one pixel larger in :data:`OUTLINE_COLOUR`, which outlines the cloud. The
    conditions are drawn in the order of :data:`CONDITION_COLOURS` (within one, component by
    component, particle by particle), so a later dot covers an earlier one.

    Args:
        image: RGB ``uint8`` ``[height, width, 3]`` (not modified).
        centres: ``[max_components, num_particles, 2]`` the particles' ``(x, y)`` in pixels.
        conditions: ``[max_components, num_particles]`` their conditions (keys of
            :data:`CONDITION_COLOURS`).
        alive: ``[max_components]`` the slots whose particles are drawn.

    Returns:
        The annotated copy.

    Raises:
        InputError: a living particle with a condition that has no colour, or a
            non-finite centre.
    """
    out = image.copy()
    centres = np.asarray(centres)[np.asarray(alive)]
    conditions = np.asarray(conditions)[np.asarray(alive)]
    unknown = sorted(set(np.unique(conditions).tolist()) - set(CONDITION_COLOURS))
    if unknown:
        raise InputError(f"particle conditions {unknown} have no colour")
    if not np.all(np.isfinite(centres)):
        raise InputError("non-finite particle centres")
    points = np.round(centres).astype(int)
    for x, y in points.reshape(-1, 2).tolist():
        cv2.circle(out, (x, y), PARTICLE_RADIUS + 1, OUTLINE_COLOUR, -1)
    for condition, (colour, _) in CONDITION_COLOURS.items():
        for x, y in points[conditions == condition].tolist():
            cv2.circle(out, (x, y), PARTICLE_RADIUS, colour, -1)
    return out


def draw_condition_legend(image: np.ndarray) -> np.ndarray:
    """Draws the legend of :data:`CONDITION_COLOURS` (a dot and the name per condition, on a
    dark box) in the top-right corner of a copy of an RGB ``uint8`` image."""
    out = image.copy()
    right = out.shape[1] - LEGEND_MARGIN
    left = right - LEGEND_WIDTH
    bottom = LEGEND_MARGIN + LEGEND_ROW * len(CONDITION_COLOURS) + 4
    cv2.rectangle(out, (left, LEGEND_MARGIN), (right, bottom), (32, 32, 32), -1)
    for row, (colour, name) in enumerate(CONDITION_COLOURS.values()):
        y = LEGEND_MARGIN + LEGEND_ROW * row + LEGEND_ROW // 2 + 2
        cv2.circle(out, (left + 10, y), 4, colour, -1)
        cv2.putText(
            out, name, (left + 20, y + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1
        )
    return out
