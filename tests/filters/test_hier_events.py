"""Event management of the Hierarchical tracker: collision map, group births, the state
machine (every transition on hand-made scenes) and the offline exit labelling (with zones
learned from drawn walks whose entries and exits are known)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.filters.hier_events import (
    ENTERING,
    EVENT_NAMES,
    EXITING,
    GROUPED,
    GROUPING,
    SINGLE,
    SPLITTING,
    EventParams,
    collision_map,
    default_event_params,
    drop_short_groups,
    event_step,
    is_group_birth,
    label_exits,
    moving_ends,
    rows_at_zones,
    unlabel_entries,
)


def collision_loop(boxes, alive, min_overlap):
    """Slow NumPy oracle of the collision map."""
    size = len(boxes)
    out = np.zeros((size, size), bool)
    for i in range(size):
        for j in range(size):
            if i == j or not (alive[i] and alive[j]):
                continue
            xi, yi, wi, hi = boxes[i]
            xj, yj, wj, hj = boxes[j]
            w = min(xi + wi, xj + wj) - max(xi, xj)
            h = min(yi + hi, yj + hj) - max(yi, yj)
            inter = max(w, 0.0) * max(h, 0.0)
            out[i, j] = inter > 0 and inter >= min_overlap * min(wi * hi, wj * hj)
    return out


def test_names_match_codes():
    codes = (SINGLE, GROUPING, GROUPED, SPLITTING, ENTERING, EXITING)
    assert [EVENT_NAMES[c] for c in codes] == [
        "single",
        "grouping",
        "grouped",
        "splitting",
        "entering",
        "exiting",
    ]


@pytest.mark.parametrize("min_overlap", [0.05, 0.3, 0.6])
def test_collision_map_matches_loop(min_overlap):
    rng = np.random.default_rng(0)
    corners = rng.uniform(0, 40, (16, 2))
    sides = rng.uniform(4, 30, (16, 2))
    boxes = np.concatenate([corners, sides], 1).astype(np.float32)
    alive = rng.random(16) < 0.8
    expected = collision_loop(boxes.astype(np.float64), alive, min_overlap)
    got = np.asarray(collision_map(jnp.asarray(boxes), jnp.asarray(alive), min_overlap))
    assert expected.sum() >= 4 and (~expected).sum() >= 4  # both outcomes exercised
    np.testing.assert_array_equal(got, expected)
    jitted = jax.jit(collision_map)(jnp.asarray(boxes), jnp.asarray(alive), min_overlap)
    np.testing.assert_array_equal(np.asarray(jitted), expected)


def test_collision_analytic_cases():
    boxes = jnp.array(
        [[0, 0, 10, 10], [10, 0, 10, 10], [5, 5, 10, 10], [0, 0, 2, 2]], jnp.float32
    )  # 0 and 1 touch (no area); 0 and 2 share 25/100; 3 lies inside 0
    got = np.asarray(collision_map(boxes, jnp.ones(4, bool), 0.25))
    assert not got[0, 1] and got[0, 2] and got[2, 0] and got[0, 3]
    assert not np.asarray(collision_map(boxes, jnp.ones(4, bool), 0.26))[0, 2]


def test_group_birth():
    collisions = jnp.array(
        [
            [0, 1, 1, 0],
            [1, 0, 0, 0],
            [1, 0, 0, 1],
            [0, 0, 1, 0],
        ],
        bool,
    )
    born = jnp.array([True, False, False, True])
    # slot 0 collides with existing 1 and 2: a group; slot 3 only with 2.
    np.testing.assert_array_equal(np.asarray(is_group_birth(collisions, born)), [1, 0, 0, 0])
    # two new-borns colliding count only the existing ones.
    born = jnp.array([True, True, False, False])
    np.testing.assert_array_equal(np.asarray(is_group_birth(collisions, born)), [0, 0, 0, 0])


def run_machine(boxes_over_time, alive_over_time, group, reassociated, params):
    """Runs collision_map + event_step over a hand-made scene; returns [T, S] states."""
    states = []
    previous = jnp.zeros(boxes_over_time.shape[1], jnp.int32)
    age = jnp.zeros(boxes_over_time.shape[1], jnp.int32)
    for boxes, alive in zip(boxes_over_time, alive_over_time, strict=True):
        collisions = collision_map(jnp.asarray(boxes), jnp.asarray(alive), params.min_overlap)
        previous = event_step(
            previous, collisions, jnp.asarray(group), jnp.asarray(alive), age, reassociated, params
        )
        states.append(np.asarray(previous))
        age = age + jnp.asarray(alive, jnp.int32)
    return np.stack(states)


def test_state_machine_every_transition():
    """Two people (slots 0, 1) approach, overlap, a group tracker (slot 2) appears over
    them, leaves, and they separate; slot 3 is dead throughout."""
    params = EventParams(jnp.float32(0.1), jnp.int32(2))
    # x positions of the two people per frame; the group box spans both on frames 4-5.
    x0 = [0, 0, 10, 15, 15, 15, 15, 10, 0, 0]
    x1 = [60, 60, 30, 20, 20, 20, 20, 30, 60, 60]
    num = len(x0)
    boxes = np.zeros((num, 4, 4), np.float32)
    boxes[:, 0] = [[x, 0, 10, 20] for x in x0]
    boxes[:, 1] = [[x, 0, 10, 20] for x in x1]
    boxes[:, 2] = [10, 0, 25, 20]
    boxes[:, 3] = [15, 0, 10, 20]  # dead slot lying over both: must not count
    alive = np.zeros((num, 4), bool)
    alive[:, :2] = True
    alive[4:6, 2] = True
    group = np.array([False, False, True, False])
    states = run_machine(boxes, alive, group, jnp.zeros(4, bool), params)
    expected0 = [
        ENTERING,  # frame 0: new, alone
        ENTERING,  # frame 1: still within entering_frames = 2
        SINGLE,  # apart (x 10 vs 30)
        GROUPING,  # overlap with another single tracker
        GROUPED,  # a confirmed group tracker appears over them
        GROUPED,
        SPLITTING,  # group tracker gone, still colliding with each other
        SINGLE,  # apart again
        SINGLE,
        SINGLE,
    ]
    np.testing.assert_array_equal(states[:, 0], expected0)
    np.testing.assert_array_equal(states[:, 1], expected0)
    # the group tracker collides with (non-group) members: grouping; dead slots: single.
    np.testing.assert_array_equal(states[4:6, 2], [GROUPING, GROUPING])
    assert (states[:, 3] == SINGLE).all()
    assert (states[:4, 2] == SINGLE).all() and (states[6:, 2] == SINGLE).all()


def test_single_to_grouped_and_splitting_back_to_grouped():
    params = EventParams(jnp.float32(0.1), jnp.int32(0))
    collide = jnp.array([[0, 1], [1, 0]], bool)
    apart = jnp.zeros((2, 2), bool)
    alive = jnp.ones(2, bool)
    age = jnp.full(2, 10, jnp.int32)
    no = jnp.zeros(2, bool)
    group = jnp.array([False, True])
    single = jnp.array([SINGLE, SINGLE])
    state = event_step(single, collide, group, alive, age, no, params)
    assert int(state[0]) == GROUPED  # single straight to grouped
    state = event_step(jnp.array([SPLITTING, 0]), collide, group, alive, age, no, params)
    assert int(state[0]) == GROUPED  # splitting back to grouped
    state = event_step(jnp.array([SPLITTING, 0]), collide, no, alive, age, no, params)
    assert int(state[0]) == SPLITTING  # still colliding, no group tracker
    state = event_step(jnp.array([GROUPED, 0]), apart, group, alive, age, no, params)
    assert int(state[0]) == SINGLE  # any state, no collision: single


def test_reassociated_tracker_is_not_entering():
    params = default_event_params()
    zeros = jnp.zeros(2, jnp.int32)
    apart = jnp.zeros((2, 2), bool)
    alive = jnp.ones(2, bool)
    state = event_step(zeros, apart, alive & False, alive, zeros, jnp.array([False, True]), params)
    np.testing.assert_array_equal(np.asarray(state), [ENTERING, SINGLE])


def test_a_tracker_enters_once():
    """Born colliding (grouping), alone a frame later: single, not entering."""
    params = EventParams(jnp.float32(0.1), jnp.int32(10))
    collide = jnp.array([[0, 1], [1, 0]], bool)
    apart = jnp.zeros((2, 2), bool)
    alive, no = jnp.ones(2, bool), jnp.zeros(2, bool)
    born = event_step(
        jnp.zeros(2, jnp.int32), collide, no, alive, jnp.zeros(2, jnp.int32), no, params
    )
    np.testing.assert_array_equal(np.asarray(born), [GROUPING, GROUPING])
    later = event_step(born, apart, no, alive, jnp.ones(2, jnp.int32), no, params)
    np.testing.assert_array_equal(np.asarray(later), [SINGLE, SINGLE])
    still = event_step(jnp.array([ENTERING, SINGLE]), apart, no, alive, jnp.full(2, 9), no, params)
    np.testing.assert_array_equal(np.asarray(still), [ENTERING, SINGLE])


def test_event_step_jit_and_vmap_over_params():
    rng = np.random.default_rng(3)
    boxes = jnp.asarray(rng.uniform(0, 40, (6, 4)).astype(np.float32) + np.array([0, 0, 5, 5]))
    alive = jnp.asarray(rng.random(6) < 0.9)
    previous = jnp.asarray(rng.integers(0, 6, 6), jnp.int32)
    group = jnp.asarray(rng.random(6) < 0.3)
    age = jnp.asarray(rng.integers(0, 5, 6), jnp.int32)
    reassociated = jnp.asarray(rng.random(6) < 0.3)

    def frame(params):
        collisions = collision_map(boxes, alive, params.min_overlap)
        return event_step(previous, collisions, group, alive, age, reassociated, params)

    batch = EventParams(jnp.array([0.05, 0.5, 0.9], jnp.float32), jnp.array([0, 3, 6], jnp.int32))
    mapped = jax.jit(jax.vmap(frame))(batch)
    for k in range(3):
        single = frame(EventParams(batch.min_overlap[k], batch.entering_frames[k]))
        np.testing.assert_array_equal(np.asarray(mapped[k]), np.asarray(single))
    assert len({tuple(np.asarray(row)) for row in mapped}) > 1  # the parameters matter


def test_label_exits():
    # id 1 ends at frame 6 alone (exits); id 2 ends in a group (not exiting);
    # id 3 lasts to the sequence's end (not exiting).
    frames = np.array([1, 2, 3, 4, 5, 6, 1, 2, 3, 4, 8, 9, 10])
    ids = np.array([1, 1, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3])
    events = np.array(
        [
            *(ENTERING, SINGLE, GROUPING, SINGLE, SINGLE, SINGLE),
            *(SINGLE, SINGLE, SINGLE, GROUPED),
            *(ENTERING, SINGLE, SINGLE),
        ]
    )
    out = label_exits(frames, ids, events, last_frame=10, exiting_frames=4)
    expected = events.copy()
    expected[3:6] = EXITING  # frames 4-6: the trailing single run inside 3 < f <= 6
    np.testing.assert_array_equal(out, expected)
    out = label_exits(frames, ids, events, last_frame=10, exiting_frames=2)
    expected = events.copy()
    expected[4:6] = EXITING  # frames 5-6
    np.testing.assert_array_equal(out, expected)
    # with the sequence ending on frame 6, id 1 no longer leaves early: nothing changes.
    np.testing.assert_array_equal(label_exits(frames, ids, events, 6, 4), events)


def walks():
    """Rows of six people crossing a 640 x 480 image from the left edge to the right one
    (frames 20k+10 .. 20k+73) and of two fragments: id 7 starts at x = 320 (frame 50) and
    walks out on the right, id 8 walks in from the left and ends at x = 320 (frame 70)."""
    frames, ids, boxes = [], [], []
    for k in range(6):
        for step in range(64):
            frames.append(20 * k + 10 + step)
            ids.append(k + 1)
            boxes.append((10.0 * step - 10, 260.0 + 5 * k, 20.0, 50.0))
    for step in range(33):
        frames.append(50 + step)
        ids.append(7)
        boxes.append((310.0 + 10 * step, 272.0, 20.0, 50.0))
    for step in range(33):
        frames.append(38 + step)
        ids.append(8)
        boxes.append((10.0 * step - 10, 268.0, 20.0, 50.0))
    return np.array(frames), np.array(ids), np.array(boxes)


def test_zones_learned_from_the_rows_mark_the_edges_not_the_middle():
    frames, ids, boxes = walks()
    at_zone = rows_at_zones(frames, ids, boxes, (1, 200), (640, 480))
    first = {i: np.flatnonzero(ids == i)[0] for i in range(1, 9)}
    last = {i: np.flatnonzero(ids == i)[-1] for i in range(1, 9)}
    assert all(at_zone[first[i]] and at_zone[last[i]] for i in range(1, 7))
    assert not at_zone[first[7]] and at_zone[last[7]]  # starts in the middle
    assert at_zone[first[8]] and not at_zone[last[8]]  # ends in the middle
    # mid-walk rows are in no zone
    assert not at_zone[(ids == 1) & (frames == 40)].any()
    # no track starts or ends inside the run (one track spanning it): no zones, None
    whole = ids == 1
    assert rows_at_zones(frames[whole], ids[whole], boxes[whole], (10, 73), (640, 480)) is None


def test_zones_gate_entries_and_exits():
    frames, ids, boxes = walks()
    at_zone = rows_at_zones(frames, ids, boxes, (1, 200), (640, 480))
    order = np.lexsort((ids, frames))
    frames, ids, at_zone = frames[order], ids[order], at_zone[order]
    events = np.full(len(ids), SINGLE)
    for i in range(1, 9):  # every track enters for its first 5 frames, as online
        events[np.flatnonzero(ids == i)[:5]] = ENTERING
    entries = unlabel_entries(frames, ids, events, at_zone)
    assert (entries[ids == 7] == SINGLE).all()  # born in the middle: not entering
    for i in (1, 2, 3, 4, 5, 6, 8):
        np.testing.assert_array_equal(entries[ids == i], events[ids == i])
    exits = label_exits(frames, ids, entries, last_frame=200, exiting_frames=4, at_zone=at_zone)
    for i in (1, 2, 3, 4, 5, 6, 7):
        assert (exits[ids == i][-4:] == EXITING).all() and (exits[ids == i][:-4] != EXITING).all()
    assert not (exits[ids == 8] == EXITING).any()  # lost in the middle: not exiting
    # without zones, every track end is an exit
    assert (label_exits(frames, ids, entries, 200, 4)[ids == 8][-4:] == EXITING).all()


def drop_short_oracle(codes: list[int], k: int) -> list[int]:
    """One identity, frame order: a slow loop over runs (fill short breaks, then drop short
    group runs), written independently of the vectorised run finding."""
    out = list(codes)
    for inside in (False, True):
        grouped = [c in (GROUPING, GROUPED) for c in out]
        t = 0
        while t < len(out):
            u = t
            while u < len(out) and grouped[u] == grouped[t]:
                u += 1
            between = t > 0 and u < len(out)
            if grouped[t] == inside and u - t < k and (inside or between):
                fill = out[t - 1] if t > 0 else SINGLE
                for v in range(t, u):
                    out[v] = fill
            t = u
    return out


def test_drop_short_groups_against_a_loop():
    # id 1: a 2-frame flicker while entering, a real group with a 1-frame break, a 2-frame
    # flicker at its end; id 2 (rows out of order): a short group at its start.
    g, d, s, p, e = GROUPING, GROUPED, SINGLE, SPLITTING, ENTERING
    one = [e, e, e, g, g, s, s, s, s, g, d, d, p, d, d, d, s, s, s, s, g, g]
    two = [g, g, s, s, s, s]
    frames = np.r_[np.arange(1, 23), np.arange(6, 0, -1)]
    ids = np.r_[np.ones(22, int), np.full(6, 2)]
    events = np.r_[one, two[::-1]]
    out = drop_short_groups(frames, ids, events, min_frames=3)
    expected_one = [e, e, e, e, e, s, s, s, s, g, d, d, d, d, d, d, s, s, s, s, s, s]
    assert out[:22].tolist() == expected_one == drop_short_oracle(one, 3)
    assert out[22:][::-1].tolist() == [s, s, s, s, s, s] == drop_short_oracle(two, 3)
    np.testing.assert_array_equal(drop_short_groups(frames, ids, events, 1), events)
    rng = np.random.default_rng(0)
    for _ in range(50):
        codes = rng.choice([SINGLE, GROUPING, GROUPED, SPLITTING], size=30, p=[0.4, 0.2, 0.3, 0.1])
        k = int(rng.integers(1, 6))
        got = drop_short_groups(np.arange(30), np.zeros(30, int), codes, k)
        assert got.tolist() == drop_short_oracle(codes.tolist(), k)


def _track(speeds, height=50.0):
    """One track's boxes, its foot point moving ``speeds[k]`` box heights per frame."""
    x = np.concatenate([[0.0], np.cumsum(speeds)]) * height
    return np.stack([x, np.full_like(x, 100.0), np.full_like(x, 20.0), np.full_like(x, height)], 1)


def test_moving_ends_walkers_pass_still_tracks_do_not():
    """Passages by motion: the six walkers of :func:`walks` (5 box heights a second at 25
    frames/s) may enter and exit; a track that stands still neither enters nor exits; one
    that walks in and then stands still enters only; a one-row track does neither."""
    frames, ids, boxes = walks()
    assert moving_ends(frames, ids, boxes, 25.0).all()
    walk_then_stand = _track([0.2] * 30 + [0.0] * 60)
    still = _track([0.001] * 90)
    boxes = np.concatenate([walk_then_stand, still, still[:1]])
    frames = np.concatenate([np.arange(91), np.arange(91), [5]])
    ids = np.repeat([1, 2, 3], [91, 91, 1])
    moving = moving_ends(frames, ids, boxes, 25.0)
    assert moving[0] and not moving[90]  # walks in, stands at the end
    assert not moving[91] and not moving[181]  # stands throughout
    assert not moving[182]  # one row
    assert moving[1:90].all() and moving[92:181].all()  # inner rows are never refused
    # the end is not an exit: label_exits, with the motion as the gate, leaves it single
    events = label_exits(frames, ids, np.full(len(ids), SINGLE), 500, 4, at_zone=moving)
    assert not (events == EXITING).any()


@pytest.mark.parametrize(("speed", "passes"), [(0.2, False), (0.3, True)])
def test_moving_ends_threshold_is_the_speed_over_the_first_and_last_second(speed, passes):
    """A track walking at ``speed`` box heights a second for 3 s at 10 frames/s: over its
    first and last second (10 frames) the foot point moves ``speed`` heights, against the
    default 0.25 a second."""
    boxes = _track([speed / 10.0] * 30)
    moving = moving_ends(np.arange(31), np.ones(31, int), boxes, 10.0)
    assert moving[0] == passes and moving[-1] == passes
    # a stricter or a looser threshold decides the other way
    other = moving_ends(np.arange(31), np.ones(31, int), boxes, 10.0, min_speed=speed + 0.05)
    assert not other[0] and not other[-1]
