"""``draw_levels``: the Hierarchical tracker's two levels on a frame, against pixel oracles."""

from __future__ import annotations

import numpy as np

from jaxtrack.plot.hier_frames import HierarchicalFrame, draw_levels
from jaxtrack.types import Tracks


def frame(low_boxes, low_confirmed, high_boxes, high_lost, ids, events):
    """One frame's drawing outputs (tracks unused by the drawing)."""
    empty = Tracks(np.zeros((1, 4)), np.full(1, -1), np.zeros(1), np.zeros(1, bool))
    return HierarchicalFrame(
        empty,
        empty,
        np.asarray(events),
        np.asarray(ids),
        np.asarray(low_boxes, float),
        np.ones(len(low_boxes), bool),
        np.asarray(low_confirmed),
        np.asarray(high_boxes, float),
        np.asarray(high_lost),
        np.full(len(ids), -1),
    )


def test_white_low_level_around_black_high_level():
    image = np.full((120, 160, 3), 128, np.uint8)
    box = (40.0, 20.0, 30.0, 80.0)  # ellipse through (40, 60) on its left
    drawn = draw_levels(image, frame([box], [True], [box], [False], [7], [0]))
    assert drawn[60, 40].max() < 30  # black: the high-level ellipse on top
    assert drawn[60, 36:39].min(axis=-1).max() > 200  # white: the low-level ellipse is wider
    assert (image == 128).all()  # the input is not modified
    # the label: identity and event above the box, black text on a white outline
    label = drawn[5:20, 40:100]
    assert (label.max(axis=-1) < 30).any() and (label.min(axis=-1) > 200).any()


def test_free_and_lost_slots():
    image = np.full((120, 160, 3), 128, np.uint8)
    box = (40.0, 20.0, 30.0, 80.0)
    free = draw_levels(image, frame([box], [True], [box], [False], [-1], [0]))
    assert free[60, 40].min() > 200  # no high-level tracker drawn: white only
    lost = draw_levels(image, frame([(100.0, 20.0, 30.0, 80.0)], [False], [box], [True], [7], [0]))
    assert lost[60, 40].max() < 60  # a thin black ellipse where the lost tracker is
    assert lost[60, 33:39].max() == 128  # no white around it: no low-level track there
