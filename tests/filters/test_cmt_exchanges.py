"""Split exchanges (jaxtrack.filters.cmt_exchanges): NumPy oracles of the gains, the checks and
the episode states, and the exchange on a drawn crossing with known truth."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.filters.base import run
from jaxtrack.filters.cmt_exchanges import (
    APART,
    CHECKED,
    EXCHANGE_IOU,
    OPEN,
    exchange_rows,
    next_episodes,
    overlaps,
    paired_likelihoods,
    slot_blobs,
    split_exchanges,
)
from jaxtrack.filters.cmt_tracker import CMTConfig, build_cmt
from jaxtrack.types import Detections
from tests.filters.test_cmt import (
    COLOURS,
    INFO,
    SMALL,
    crossing,
    frame_inputs,
    kept_the_crossing,
    scene,
    walkers,
)


def test_slot_blobs_invert_the_owners():
    owner = jnp.asarray([2, -1, 0, -1], jnp.int32)
    assert np.asarray(slot_blobs(owner, 3)).tolist() == [2, -1, 0]


def test_paired_likelihoods_match_a_numpy_loop():
    rng = np.random.default_rng(0)
    table = rng.normal(size=(5, 6)).astype(np.float32)
    held = np.array([3, 0, 5, 1, 2])
    got = np.asarray(paired_likelihoods(jnp.asarray(table), jnp.asarray(held)))
    for i in range(5):
        for j in range(5):
            assert got[i, j] == table[i, held[j]]


def _blobs(boxes, num_slots=6):
    padded = np.tile([0.0, 0.0, 1.0, 1.0], (num_slots, 1)).astype(np.float32)
    padded[: len(boxes)] = boxes
    mask = np.arange(num_slots) < len(boxes)
    return Detections(jnp.asarray(padded), jnp.asarray(mask, jnp.float32), jnp.asarray(mask))


def _swapped_likelihoods(num_slots, num_blobs, pairs):
    """``L[s, b]``: -5 everywhere except, for each pair ``(slot, slot, own blob, own blob,
    gain)``, ``-gain / 4`` on each slot's own blob and ``+gain / 4`` on the other's, so that
    the pair's gain ``L_i(b_j) + L_j(b_i) - L_i(b_i) - L_j(b_j)`` is ``gain``."""
    table = np.full((num_slots, num_blobs), -5.0, np.float32)
    for i, j, bi, bj, gain in pairs:
        table[i, bi] = table[j, bj] = -gain / 4
        table[i, bj] = table[j, bi] = gain / 4
    return jnp.asarray(table)


def test_split_exchanges_swap_open_pairs_above_the_margin_only():
    # Slots 0-5; blobs far apart; each slot owns the blob of its own index.
    boxes = np.array([[40.0 * k, 10.0, 16.0, 36.0] for k in range(6)], np.float32)
    blobs = _blobs(boxes)
    owner = jnp.arange(6, dtype=jnp.int32)
    episodes = np.full((6, 6), APART, np.int8)
    for i, j in ((0, 1), (2, 3), (4, 5)):
        episodes[i, j] = episodes[j, i] = OPEN
    table = _swapped_likelihoods(6, 6, [(0, 1, 0, 1, 3.0), (2, 3, 2, 3, 0.5), (4, 5, 4, 5, 3.0)])
    eligible = jnp.asarray([True, True, True, True, True, False])
    partner, checked = split_exchanges(
        jnp.asarray(episodes), owner, blobs, table, eligible, jnp.float32(1.0)
    )
    # (0, 1) exchanges; (2, 3) is checked but its gain 0.5 is below the margin; (4, 5) has an
    # ineligible member: not checked.
    assert np.asarray(partner).tolist() == [1, 0, 2, 3, 4, 5]
    want = np.zeros((6, 6), bool)
    for i, j in ((0, 1), (2, 3)):
        want[i, j] = want[j, i] = True
    np.testing.assert_array_equal(np.asarray(checked), want)


def test_split_exchanges_need_distinct_blobs_apart():
    boxes = np.array([[10.0, 10.0, 16.0, 36.0], [12.0, 10.0, 16.0, 36.0]], np.float32)
    blobs = _blobs(boxes, 2)
    episodes = jnp.asarray([[APART, OPEN], [OPEN, APART]], jnp.int8)
    table = _swapped_likelihoods(2, 2, [(0, 1, 0, 1, 3.0)])
    eligible = jnp.ones(2, bool)
    # The blobs overlap by more than EXCHANGE_IOU: not yet apart, not checked.
    partner, checked = split_exchanges(
        episodes, jnp.asarray([0, 1]), blobs, table, eligible, jnp.float32(0.0)
    )
    assert np.asarray(partner).tolist() == [0, 1] and not np.any(np.asarray(checked))
    # One slot holds no blob (the other one's was given to nobody): not checked either.
    apart = _blobs(np.array([[10.0, 10.0, 16.0, 36.0], [80.0, 10.0, 16.0, 36.0]]), 2)
    partner, checked = split_exchanges(
        episodes, jnp.asarray([0, -1]), apart, table, eligible, jnp.float32(0.0)
    )
    assert np.asarray(partner).tolist() == [0, 1] and not np.any(np.asarray(checked))
    # Apart and both held: checked and exchanged.
    partner, checked = split_exchanges(
        episodes, jnp.asarray([0, 1]), apart, table, eligible, jnp.float32(0.0)
    )
    assert np.asarray(partner).tolist() == [1, 0] and bool(np.asarray(checked)[0, 1])


def test_a_slot_exchanges_once_with_its_best_partner():
    # Slot 1 has open episodes with 0 (gain 2) and 2 (gain 6): it exchanges with 2 only.
    boxes = np.array([[60.0 * k, 10.0, 16.0, 36.0] for k in range(3)], np.float32)
    blobs = _blobs(boxes, 3)
    episodes = np.full((3, 3), APART, np.int8)
    for i, j in ((0, 1), (1, 2)):
        episodes[i, j] = episodes[j, i] = OPEN
    table = np.full((3, 3), -5.0, np.float32)
    np.fill_diagonal(table, 0.0)
    table[0, 1], table[1, 0] = 1.0, 1.0  # gain(0, 1) = 1 + 1 - 0 - 0 = 2
    table[1, 2], table[2, 1] = 3.0, 3.0  # gain(1, 2) = 6
    partner, _ = split_exchanges(
        jnp.asarray(episodes),
        jnp.arange(3, dtype=jnp.int32),
        blobs,
        jnp.asarray(table),
        jnp.ones(3, bool),
        jnp.float32(0.5),
    )
    assert np.asarray(partner).tolist() == [0, 2, 1]


def test_exchange_rows_permute_every_leaf():
    tree = (jnp.arange(4.0), jnp.arange(8).reshape(4, 2))
    got = exchange_rows(jnp.asarray([1, 0, 2, 3]), tree)
    assert np.asarray(got[0]).tolist() == [1.0, 0.0, 2.0, 3.0]
    assert np.asarray(got[1]).tolist() == [[2, 3], [0, 1], [4, 5], [6, 7]]


def advance(episodes, checked, boxes, live):
    """The episode states after a frame whose decisions are ``boxes``."""
    return next_episodes(episodes, checked, overlaps(boxes, live), live)


def test_episode_states_follow_their_rules():
    # Four slots; 0 and 1 overlap, 2 and 3 are far apart from everything.
    boxes = jnp.asarray(
        [[10.0, 10, 16, 36], [12.0, 10, 16, 36], [90.0, 10, 16, 36], [150.0, 10, 16, 36]]
    )
    live = jnp.ones(4, bool)
    none = jnp.zeros((4, 4), bool)
    start = jnp.full((4, 4), APART, jnp.int8)
    opened = np.asarray(advance(start, none, boxes, live))
    assert opened[0, 1] == opened[1, 0] == OPEN and np.sum(opened != APART) == 2
    # Checked while still overlapping: CHECKED, and it stays so while they overlap.
    checked = none.at[0, 1].set(True).at[1, 0].set(True)
    after = advance(jnp.asarray(opened), checked, boxes, live)
    assert int(after[0, 1]) == CHECKED
    assert int(advance(after, none, boxes, live)[0, 1]) == CHECKED
    # Apart: a checked pair is APART, an open unchecked one stays OPEN.
    far = boxes.at[1].set(jnp.asarray([60.0, 10.0, 16.0, 36.0]))
    assert int(advance(after, none, far, live)[0, 1]) == APART
    assert int(advance(jnp.asarray(opened), none, far, live)[0, 1]) == OPEN
    assert int(advance(jnp.asarray(opened), checked, far, live)[0, 1]) == APART
    # A dead or new slot ends its pairs.
    one_dead = live.at[1].set(False)
    assert int(advance(jnp.asarray(opened), none, boxes, one_dead)[0, 1]) == APART
    # The threshold: 10 x 10 boxes 4 px apart overlap by IoU 60 / 140 = 0.43, 5 px apart by
    # 50 / 150 = 0.33, either side of EXCHANGE_IOU.
    assert 50 / 150 < EXCHANGE_IOU < 60 / 140
    for shift, want in ((4.0, OPEN), (5.0, APART)):
        pair = jnp.asarray([[0.0, 0.0, 10.0, 10.0], [shift, 0.0, 10.0, 10.0]])
        got = advance(jnp.full((2, 2), APART, jnp.int8), none[:2, :2], pair, live[:2])
        assert int(got[0, 1]) == want


def test_exchanges_give_back_identities_a_crossing_swapped():
    # Without the merge velocity the components bounce back at the split in some seeds (the
    # motion's pairing is the wrong one); the people are dressed differently, so the
    # observation model says which is which and the exchange puts the identities back. (The
    # cmt variant is not this case: in this drawn scene its hidden person's component dies
    # under the merged box in every seed, and a dead component has nothing to exchange.)
    variant = "cpd"
    truth, detections = crossing()
    inputs = frame_inputs(np.asarray(scene(truth, COLOURS).frame), detections)
    kept = {}
    for margin in (-1.0, 0.1):
        config = CMTConfig(variant=variant, velocity_rate=0.0, exchange_margin=margin, **SMALL)
        filt, params = build_cmt(config, INFO)
        track = jax.jit(lambda k, p, i, filt=filt: run(filt, k, p, i)[1])
        kept[margin] = sum(
            kept_the_crossing(track(jax.random.PRNGKey(seed), params, inputs), truth)
            for seed in range(10)
        )
    assert kept[0.1] >= 9 and kept[-1.0] <= 7, kept


def test_exchanges_change_nothing_without_collisions():
    inputs = scene(walkers(), COLOURS)
    outputs = []
    for margin in (-1.0, 0.0):
        config = CMTConfig(variant="cmt", exchange_margin=margin, **SMALL)
        filt, params = build_cmt(config, INFO)
        outputs.append(
            jax.jit(lambda k, p, i, filt=filt: run(filt, k, p, i)[1].tracks)(
                jax.random.PRNGKey(6), params, inputs
            )
        )
    for got, want in zip(jax.tree.leaves(outputs[1]), jax.tree.leaves(outputs[0]), strict=True):
        np.testing.assert_array_equal(np.asarray(got), np.asarray(want))
