"""The shared track table against a loop oracle; the PHD labelling and the Kalman tracker use it."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.association.estimates import Estimates
from jaxtrack.association.labelling import LabelParams, init_labels, label_step
from jaxtrack.association.track_table import (
    TrackTable,
    commit_tracks,
    count_missed,
    start_tracks,
)
from jaxtrack.context.scores import identity_calibration
from jaxtrack.filters.kalman import default_kalman_params, kalman_filter
from jaxtrack.types import Detections


def _oracle(ids, active, missed, next_id, linked, starts, max_missed):
    """One frame of the table rules as a plain loop."""
    missed = [0 if link else m + 1 for m, link in zip(missed, linked, strict=True)]
    alive = [a and m <= max_missed for a, m in zip(active, missed, strict=True)]
    free = [slot for slot, a in enumerate(alive) if not a]
    new_ids = [i if a else -1 for i, a in zip(ids, alive, strict=True)]
    new_missed = [m if a else 0 for m, a in zip(missed, alive, strict=True)]
    overflow = False
    for start in starts:
        if not start:
            continue
        if not free:
            overflow = True
            continue
        slot = free.pop(0)
        new_ids[slot], new_missed[slot], alive[slot] = next_id, 0, True
        next_id += 1
    return new_ids, alive, new_missed, next_id, overflow


def test_table_rules_match_a_loop_oracle():
    rng = np.random.default_rng(0)
    step = jax.jit(lambda table, linked, starts: _frame(table, linked, starts, jnp.asarray(2.0)))
    for _ in range(40):
        num_tracks, num_items = rng.integers(1, 7), rng.integers(1, 7)
        active = rng.random(num_tracks) < 0.6
        ids = np.where(active, rng.permutation(num_tracks) + 1, -1)
        missed = np.where(active, rng.integers(0, 4, num_tracks), 0)
        linked = active & (rng.random(num_tracks) < 0.5)
        starts = rng.random(num_items) < 0.6
        table = TrackTable(
            ids=jnp.asarray(ids, jnp.int32),
            active=jnp.asarray(active),
            confirmed=jnp.asarray(active),
            missed=jnp.asarray(missed, jnp.int32),
            next_id=jnp.asarray(num_tracks + 1, jnp.int32),
        )
        new_table, overflow = step(table, jnp.asarray(linked), jnp.asarray(starts))
        expected = _oracle(ids, active, missed, num_tracks + 1, linked, starts, 2)
        np.testing.assert_array_equal(new_table.ids, expected[0])
        np.testing.assert_array_equal(new_table.active, expected[1])
        np.testing.assert_array_equal(new_table.missed, expected[2])
        assert int(new_table.next_id) == expected[3] and bool(overflow) == expected[4]


def _frame(table, linked, starts, max_missed):
    missed, alive = count_missed(table, linked, max_missed)
    new = start_tracks(alive, starts, table.next_id)
    return commit_tracks(new, table, alive, missed, alive & table.confirmed), new.overflow


def test_phd_labelling_and_kalman_tracker_share_the_table_rules():
    """Three new targets and two slots: both trackers store the first two, with identities 1
    and 2, flag the overflow, and give the next target identity 3."""
    boxes = jnp.array([[10.0, 10.0, 20.0, 40.0], [100, 10, 20, 40], [200, 10, 20, 40]])
    mask = jnp.array([True, True, True])
    params = LabelParams(
        min_iou=jnp.asarray(0.3),
        max_missed_frames=jnp.asarray(0.0),
        confirm_score=jnp.asarray(0.0),
        new_track_max_iou=jnp.asarray(1.0),
        velocity_smoothing=jnp.asarray(0.0),
        score_calibration=identity_calibration(),
    )
    centres = boxes.at[:, :2].add(boxes[:, 2:] / 2)
    states = jnp.zeros((3, 6)).at[:, jnp.array([0, 2, 4, 5])].set(centres)
    estimates = Estimates(states=states, masses=jnp.ones(3), scores=jnp.ones(3), mask=mask)
    label_state, labels = label_step(init_labels(2), params, estimates)

    kalman = kalman_filter(max_tracks=2)
    kalman_params = default_kalman_params()._replace(max_missed_frames=jnp.asarray(0.0))
    detections = Detections(boxes=boxes, scores=jnp.ones(3), mask=mask)
    kalman_state, info = kalman.step(None, kalman.init(None, None), kalman_params, detections)

    for table in (label_state.table, kalman_state.table):
        assert isinstance(table, TrackTable)
        np.testing.assert_array_equal(table.ids, [1, 2])
        assert int(table.next_id) == 3
    assert bool(labels.overflow) and bool(info.track_overflow)
    np.testing.assert_array_equal(labels.ids, [1, 2, -1])

    # Next frame: only the third target; both tables end the unseen tracks and give it id 3.
    third = jnp.array([False, False, True])
    label_state, labels = label_step(label_state, params, estimates._replace(mask=third))
    kalman_state, _ = kalman.step(
        None, kalman_state, kalman_params, detections._replace(mask=third)
    )
    assert int(labels.ids[2]) == 3
    for table in (label_state.table, kalman_state.table):
        np.testing.assert_array_equal(np.sort(np.asarray(table.ids)), [-1, 3])
