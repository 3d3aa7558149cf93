"""``draw_fusion`` and its key: the Fusion tracker's pool and fused boxes, against pixel oracles."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.errors import InputError
from jaxtrack.filters.fusion import FusionInfo
from jaxtrack.filters.fusion_voting import EMPTY, ENDED, TARGET, TENTATIVE
from jaxtrack.io.video import id_colour
from jaxtrack.plot.fusion_frames import (
    DASH,
    HYPOTHESIS_COLOUR,
    LEGEND_MARGIN,
    LEGEND_ROW,
    LEGEND_WIDTH,
    MEMBER_COLOURS,
    STYLE_ROWS,
    FusionFrame,
    draw_fusion,
    draw_fusion_legend,
    fusion_frame_outputs,
)
from jaxtrack.types import Tracks

GREY = 128
HEIGHT, WIDTH = 140, 260
#: Slot 0: a visible target (id 7) with its detection and classifier responses (the predictor
#: did not respond: its box must not be drawn); slot 1: an occluded target (id 9); slot 2: a
#: hypothesis (id 12); slots 3 and 4 (empty, ended): never drawn.
FUSED = np.array(
    [
        [40.0, 20.0, 30.0, 60.0],
        [100.0, 20.0, 30.0, 60.0],
        [160.0, 20.0, 20.0, 40.0],
        [200.0, 90.0, 20.0, 20.0],
        [220.0, 20.0, 20.0, 20.0],
    ]
)
MEMBER_BOXES = np.array(
    [
        [[20.0, 15.0, 30.0, 60.0], [50.0, 30.0, 12.0, 30.0], [5.0, 100.0, 20.0, 20.0]],
        [[100.0, 20.0, 30.0, 60.0]] * 3,
        [[160.0, 20.0, 20.0, 40.0]] * 3,
        [[200.0, 90.0, 20.0, 20.0]] * 3,
        [[220.0, 20.0, 20.0, 20.0]] * 3,
    ]
)
MEMBER_VALID = np.array(
    [[True, True, False], [False] * 3, [False] * 3, [True] * 3, [True] * 3], bool
)


STATUS = (TARGET, TARGET, TENTATIVE, EMPTY, ENDED)
OCCLUDED = (False, True, False, False, False)


def frame(status=STATUS, occluded=OCCLUDED, fused=FUSED, members=MEMBER_BOXES) -> FusionFrame:
    """One frame's drawing outputs (``tracks`` unused by the drawing)."""
    status = np.asarray(status)
    live = (status == TARGET) | (status == TENTATIVE)
    ids = np.array([7, 9, 12, 3, 4])
    candidates = Tracks(np.asarray(fused), np.where(live, ids, -1), live * 1.0, live)
    return FusionFrame(candidates, candidates, members, MEMBER_VALID, status, np.asarray(occluded))


def colour_at(image, x, y):
    return tuple(int(c) for c in image[y, x])


def near(image, colour, tolerance=40):
    """Pixels within ``tolerance`` (sum of channel differences) of ``colour``: text is drawn
    anti-aliased (OpenCV 5), so only its cores carry the colour itself."""
    return np.abs(image.astype(int) - np.array(colour)).sum(axis=-1) < tolerance


def test_members_thin_fused_box_thick_in_the_identity_colour():
    image = np.full((HEIGHT, WIDTH, 3), GREY, np.uint8)
    drawn = draw_fusion(image, frame())
    assert (image == GREY).all()  # the input is not modified
    seven = id_colour(7)
    # the fused box: 4 pixels wide on the left edge (x = 40), the identity's colour
    assert [colour_at(drawn, x, 50) for x in range(38, 42)] == [seven] * 4
    assert colour_at(drawn, 36, 50) == (GREY,) * 3 and colour_at(drawn, 43, 50) == (GREY,) * 3
    # the detection's response: one pixel wide at x = 20, cyan
    assert colour_at(drawn, 20, 50) == MEMBER_COLOURS[0]
    assert colour_at(drawn, 19, 50) == (GREY,) * 3 and colour_at(drawn, 21, 50) == (GREY,) * 3
    # the classifier's response inside the fused box, magenta; the predictor's: not drawn
    assert colour_at(drawn, 50, 45) == MEMBER_COLOURS[1]
    assert colour_at(drawn, 62, 45) == MEMBER_COLOURS[1]
    assert (drawn[95:125, 0:30] == GREY).all()
    # the identity written under the box on a black tag, in its colour (anti-aliased: each
    # text pixel is the colour scaled by its coverage)
    tag = drawn[83:97, 40:50].reshape(-1, 3).astype(float)
    text = tag[tag.any(axis=-1)]
    assert len(text) >= 10 and len(tag) - len(text) >= 50
    coverage = text @ np.array(seven) / np.dot(seven, seven)
    assert np.abs(text - coverage[:, None] * np.array(seven)).max() < 4.0
    assert coverage.max() > 0.9


def test_occluded_target_dashed_and_labelled():
    image = np.full((HEIGHT, WIDTH, 3), GREY, np.uint8)
    drawn = draw_fusion(image, frame())
    nine = id_colour(9)
    # the top edge (y = 20) from x = 100: dashes of DASH pixels, gaps of DASH pixels
    top = [colour_at(drawn, x, 20) == nine for x in range(100, 131)]
    assert all(top[2 : DASH - 1]) and all(top[2 * DASH + 2 : 3 * DASH - 1])
    assert not any(top[DASH + 3 : 2 * DASH - 2])  # in a gap: the background
    assert colour_at(drawn, 100 + DASH + 3, 20) == (GREY,) * 3
    # "9 occluded" under the box writes more of its colour than "9" alone
    visible = draw_fusion(image, frame(occluded=(False,) * 5))
    below = (slice(84, 98), slice(100, 200))  # under the edge (4 px around y = 80)
    occluded_text = near(drawn[below], nine).sum()
    visible_text = near(visible[below], nine).sum()
    assert occluded_text > 3 * visible_text > 0
    # the visible target's box is solid where the occluded one has a gap
    assert colour_at(visible, 100 + DASH + 3, 20) == nine


def test_hypothesis_grey_and_free_slots_not_drawn():
    image = np.full((HEIGHT, WIDTH, 3), GREY, np.uint8)
    drawn = draw_fusion(image, frame())
    # the hypothesis's box: grey, 2 pixels, never its identity's colour
    assert colour_at(drawn, 160, 40) == HYPOTHESIS_COLOUR
    assert not np.all(drawn[10:75, 150:190] == id_colour(12), axis=-1).any()
    # empty and ended slots: nothing drawn (their boxes and responses are valid numbers)
    assert (drawn[85:115, 195:225] == GREY).all() and (drawn[15:45, 215:245] == GREY).all()
    # a hypothesis voted in becomes a thick box in its colour
    voted = draw_fusion(image, frame(status=(TARGET, TARGET, TARGET, EMPTY, ENDED)))
    assert colour_at(voted, 159, 40) == colour_at(voted, 161, 40) == id_colour(12)


def test_non_finite_boxes_of_live_slots_are_refused():
    image = np.zeros((HEIGHT, WIDTH, 3), np.uint8)
    fused = FUSED.copy()
    fused[3] = np.nan  # an empty slot: not drawn, not checked
    members = MEMBER_BOXES.copy()
    members[0, 2] = np.nan  # the predictor did not respond: not checked
    draw_fusion(image, frame(fused=fused, members=members))
    fused[0, 1] = np.nan
    with pytest.raises(InputError, match="non-finite box"):
        draw_fusion(image, frame(fused=fused))
    members[1, 0, 0] = np.inf
    valid = frame(members=members)._replace(member_valid=np.ones((5, 3), bool))
    with pytest.raises(InputError, match="non-finite box"):
        draw_fusion(image, valid)


def test_legend_lists_the_members_shown_then_the_styles():
    image = np.zeros((120, 240, 3), np.uint8)
    out = draw_fusion_legend(image, [True, False, True])
    left = 240 - LEGEND_MARGIN - LEGEND_WIDTH
    rows = [MEMBER_COLOURS[0], MEMBER_COLOURS[2]] + [style[0] for style in STYLE_ROWS]
    for row, colour in enumerate(rows):
        y = LEGEND_MARGIN + LEGEND_ROW * row + LEGEND_ROW // 2 + 2
        assert colour_at(out, left + 8, y) == colour, row
    assert not np.all(out == MEMBER_COLOURS[1], axis=-1).any()  # the classifier is not listed
    bottom = LEGEND_MARGIN + LEGEND_ROW * len(rows) + 4
    changed = np.any(out != 0, axis=-1)
    assert changed[: bottom + 1, left : 240 - LEGEND_MARGIN + 1].mean() > 0.9  # the box
    changed[: bottom + 1, left : 240 - LEGEND_MARGIN + 1] = False
    assert not changed.any()  # nothing outside it
    # the occluded style's sample is dashed: a gap between two dashes
    y = LEGEND_MARGIN + LEGEND_ROW * (len(rows) - 2) + LEGEND_ROW // 2 + 2
    assert colour_at(out, left + 6 + DASH + 2, y) == (32, 32, 32)


def test_frame_outputs_keep_the_info_fields_drawn():
    slots = 4
    tracks = Tracks(jnp.ones((slots, 4)), jnp.arange(slots), jnp.ones(slots), jnp.ones(slots, bool))
    info = FusionInfo(
        tracks=tracks,
        candidates=tracks._replace(ids=jnp.arange(slots) + 10),
        members=jnp.arange(slots * 3 * 4.0).reshape(slots, 3, 4),
        member_valid=jnp.eye(slots, 3, dtype=bool),
        weights=jnp.full((slots, 3), 1 / 3),
        status=jnp.array([EMPTY, TENTATIVE, TARGET, ENDED]),
        occluded=jnp.array([False, False, True, False]),
        overflow=jnp.bool_(False),
    )
    kept = fusion_frame_outputs(None, info, jnp.int32(0))
    assert kept.tracks is info.tracks and kept.candidates is info.candidates
    assert kept.members is info.members and kept.member_valid is info.member_valid
    assert kept.status is info.status and kept.occluded is info.occluded
