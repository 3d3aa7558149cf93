"""Identity exchanges undone when two trackers separate (``jaxtrack.filters.hier_exchanges``)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.appearance.model import init_model
from jaxtrack.filters.hier_appearance import NUM_BINS, NUM_FEATURES, init_table
from jaxtrack.filters.hier_exchanges import (
    DEFAULT_MARGIN,
    exchanges,
    model_distances,
    trained_features,
)
from jaxtrack.filters.hierarchical_tracker import HierarchicalConfig
from tests.filters.test_cmt import COLOURS, scene
from tests.filters.test_hierarchical import tracked


def _histograms(rng, shape):
    values = rng.random((*shape, NUM_FEATURES, NUM_BINS))
    return values / values.sum(-1, keepdims=True)


def test_model_distances_match_a_numpy_oracle():
    """``D[s, t]`` = the mean, over ``s``'s features with ``min_updates`` updates, of
    ``sqrt(1 - sum sqrt(m p))`` (Bhattacharyya), written out in NumPy."""
    rng = np.random.default_rng(3)
    models, boxes = _histograms(rng, (3,)), _histograms(rng, (3,))
    counts = np.zeros((3, NUM_FEATURES))
    counts[0] = 5.0
    counts[1, :10] = 3.0
    counts[1, 10:] = 2.0  # untrained
    table = init_table(3)
    table = table._replace(
        models=init_model(jnp.asarray(models, jnp.float32))._replace(
            count=jnp.asarray(counts, jnp.float32)
        )
    )
    trained = trained_features(table, jnp.float32(3)).any(axis=-1)
    got = model_distances(
        table, jnp.asarray(boxes, jnp.float32), trained_features(table, jnp.float32(3))
    )
    coefficient = np.sqrt(models[:, None] * boxes[None]).sum(-1)  # [S, T, 49]
    distance = np.sqrt(np.maximum(1 - coefficient, 0))
    expected = np.zeros((3, 3))
    expected[0] = distance[0].mean(-1)
    expected[1] = distance[1, :, :10].mean(-1)
    np.testing.assert_allclose(np.asarray(got), expected, rtol=1e-5, atol=1e-6)
    assert np.asarray(trained).tolist() == [True, True, False]


def test_exchanges_swap_pairs_greedily_by_gain_above_the_margin():
    """Trackers 0-1 gain 0.6, 2-3 gain 0.3, 0-2 gain 0.8 (but 0 and 2 are not partners),
    1-3 gain 0.05 (below the margin). Only ready pairs swap, each tracker once."""
    own = 0.2
    distances = np.full((4, 4), 0.9)
    np.fill_diagonal(distances, own)
    distances[0, 1] = distances[1, 0] = own - 0.3  # gain 2 * 0.3 = 0.6
    distances[2, 3] = distances[3, 2] = own - 0.15  # gain 0.3
    distances[0, 2] = distances[2, 0] = own - 0.4  # gain 0.8, not ready
    distances[1, 3] = distances[3, 1] = own - 0.025  # gain 0.05
    ready = np.zeros((4, 4), bool)
    for i, j in ((0, 1), (2, 3), (1, 3)):
        ready[i, j] = ready[j, i] = True
    partner = exchanges(jnp.asarray(distances), jnp.asarray(ready), jnp.float32(DEFAULT_MARGIN))
    assert np.asarray(partner).tolist() == [1, 0, 3, 2]
    # a margin above 0.3 keeps only the 0-1 swap; above 0.6, none
    assert np.asarray(exchanges(jnp.asarray(distances), jnp.asarray(ready), 0.4)).tolist() == [
        1,
        0,
        -1,
        -1,
    ]
    assert (np.asarray(exchanges(jnp.asarray(distances), jnp.asarray(ready), 0.7)) == -1).all()
    # 0-1 not ready: 2-3 still swaps, then 1-3 is blocked by 3
    ready[0, 1] = ready[1, 0] = False
    partner = exchanges(jnp.asarray(distances), jnp.asarray(ready), jnp.float32(DEFAULT_MARGIN))
    assert np.asarray(partner).tolist() == [-1, -1, 3, 2]


NUM_FRAMES, MEET = 50, 24


def bounce_scene():
    """Two differently dressed targets walk towards each other on one row, meet (their boxes
    coincide on frame ``MEET``) and walk back the way they came. Under constant velocity each
    track goes on through the meeting and takes the other's box: the low level exchanges
    them."""
    boxes = []
    for t in range(NUM_FRAMES):
        step = t if t <= MEET else 2 * MEET - t
        boxes.append(
            [(10.0 + 2.5 * step, 40.0, 16.0, 36.0), (130.0 - 2.5 * step, 40.0, 16.0, 36.0)]
        )
    return scene(boxes, COLOURS)


def _identities_on_each_side(rows):
    """The identities of the boxes on the left and on the right half of the image, before
    the meeting and after the targets are apart again."""
    centre = rows.boxes[:, 0] + rows.boxes[:, 2] / 2
    sides = {}
    for name, frames in (("before", rows.frames <= MEET - 8), ("after", rows.frames > MEET + 8)):
        left = set(rows.ids[frames & (centre < 80)].tolist())
        right = set(rows.ids[frames & (centre >= 80)].tolist())
        sides[name] = (left, right)
    return sides


@pytest.mark.parametrize(("margin", "kept"), [(DEFAULT_MARGIN, True), (-1.0, False)])
def test_an_exchange_at_a_meeting_is_undone_by_appearance(margin, kept):
    """Target 0 (red / blue) is on the left before and after the meeting, target 1 on the
    right. The low level exchanges their tracks at the meeting; with the check (default) the
    trackers swap back once apart and each identity stays with its target; without it
    (margin < 0) the identities end on the wrong sides."""
    assert HierarchicalConfig().exchange_margin == DEFAULT_MARGIN
    _, rows = tracked("full", bounce_scene(), exchange_margin=margin)
    assert_sides(rows, kept)


def assert_sides(rows, kept):
    """One identity on each side before and after the meeting; ``kept``: each ends on its
    own side, else on the other's."""
    sides = _identities_on_each_side(rows)
    (left, right), (left_after, right_after) = sides["before"], sides["after"]
    assert len(left) == 1 and len(right) == 1 and left != right
    assert len(left_after) == 1 and len(right_after) == 1
    assert (left_after == left and right_after == right) == kept
    assert (left_after == right and right_after == left) == (not kept)
