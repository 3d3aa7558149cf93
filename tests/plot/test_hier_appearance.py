"""Fig. 4b-c helpers of the Hierarchical tracker: against loop references and hand-made runs."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pytest

from jaxtrack.filters.hier_events import EVENT_NAMES
from jaxtrack.plot.hier_appearance import (
    distance_figure,
    feature_trace,
    pool_figure,
    slot_updates,
    state_runs,
    tracker_slots,
)

NUM_FRAMES, NUM_SLOTS, POOL = 30, 4, 6


@pytest.fixture(name="run")
def fixture_run():
    """A random run: identities 1-3 moving between 4 slots, pools, distances, counts."""
    rng = np.random.default_rng(0)
    event_ids = rng.integers(-1, 4, (NUM_FRAMES, NUM_SLOTS))
    event_ids[event_ids == 0] = -1
    pool = rng.integers(0, 49, (NUM_FRAMES, NUM_SLOTS, POOL))
    distances = rng.uniform(0, 0.9, (NUM_FRAMES, NUM_SLOTS, 49))
    counts = np.cumsum(rng.integers(0, 2, (NUM_FRAMES, NUM_SLOTS)), axis=0).astype(float)
    return event_ids, pool, distances, counts


def _slots_loop(event_ids, identity):
    out = []
    for row in event_ids:
        found = [s for s, value in enumerate(row) if value == identity]
        out.append(found[0] if found else -1)
    return np.array(out)


def test_tracker_slots_match_a_loop(run):
    event_ids = run[0]
    for identity in (1, 2, 3, 7):
        np.testing.assert_array_equal(
            tracker_slots(event_ids, identity), _slots_loop(event_ids, identity)
        )
    assert np.all(tracker_slots(event_ids, 7) == -1)


def test_slot_updates_hand_made():
    counts = np.array([[0, 5], [1, 5], [1, 6], [2, 6], [0, 1]], float)
    slots = np.array([0, 0, 1, 0, 1])
    # frame 0: count 0 (no update); 1: 0 -> 1 in the same slot; 2-4: a change of slot counts
    # any model (n > 0) in the new slot as updated.
    np.testing.assert_array_equal(slot_updates(counts, slots), [False, True, True, True, True])
    np.testing.assert_array_equal(
        slot_updates(counts, np.array([0, 0, 0, -1, 0])), [False, True, False, False, False]
    )


def test_feature_trace_matches_a_loop(run):
    event_ids, pool, distances, counts = run
    slots = tracker_slots(event_ids, 2)
    updated = slot_updates(counts, slots)
    for feature in range(49):
        expected = np.ones(NUM_FRAMES)
        for t in range(NUM_FRAMES):
            s = slots[t]
            if s >= 0 and updated[t] and feature in pool[t, s]:
                expected[t] = distances[t, s, feature]
        got = feature_trace(distances, pool, slots, updated, feature)
        np.testing.assert_array_equal(got, expected)
    assert np.any(updated) and np.any(slots >= 0)  # the random run exercises both branches


def test_feature_trace_is_one_when_not_pooled_or_not_updated():
    distances = np.full((3, 1, 49), 0.25)
    pool = np.tile(np.arange(POOL), (3, 1, 1))
    slots = np.zeros(3, int)
    updated = np.array([True, False, True])
    np.testing.assert_array_equal(
        feature_trace(distances, pool, slots, updated, 2), [0.25, 1, 0.25]
    )
    np.testing.assert_array_equal(feature_trace(distances, pool, slots, updated, 40), [1, 1, 1])


def test_state_runs_hand_made():
    frames = np.array([10, 11, 12, 13, 20, 21])
    codes = np.array([0, 0, 1, 1, 1, 2])
    assert state_runs(frames, codes, EVENT_NAMES) == [
        (10, 11, "single"),
        (12, 13, "grouping"),
        (20, 20, "grouping"),
        (21, 21, "grouped"),
    ]
    assert state_runs(np.array([], int), np.array([], int), EVENT_NAMES) == []


def test_pool_figure_draws_every_pooled_feature():
    frames = np.arange(5, 10)
    pool = np.tile(np.array([3, 4, 5, 6, 7, 8]), (5, 1))
    pool[0] = -1  # no tracker on the first frame
    fig = pool_figure(frames, pool, 3, (6, 8), "pool")
    current, longrun = (c.get_offsets() for c in fig.axes[0].collections)
    assert len(current) == 4 * 3 and len(longrun) == 4 * 3
    assert set(np.asarray(current)[:, 1]) == {3, 4, 5}
    assert set(np.asarray(longrun)[:, 1]) == {6, 7, 8}
    assert np.asarray(current)[:, 0].min() == 6
    plt.close(fig)


def test_distance_figure_draws_the_curves():
    frames = np.arange(1, 6)
    intra = np.array([1.0, 0.2, 0.3, 1.0, 0.1])
    fig = distance_figure(
        frames, intra, {"to 2": (np.array([2, 4]), np.array([0.5, 0.6]))}, (2, 3), "d"
    )
    lines = fig.axes[0].get_lines()
    np.testing.assert_array_equal(lines[0].get_ydata(), intra)
    np.testing.assert_array_equal(lines[1].get_xdata(), [2, 4])
    np.testing.assert_array_equal(lines[1].get_ydata(), [0.5, 0.6])
    plt.close(fig)
