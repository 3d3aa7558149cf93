"""Fusion voting: calibration on hand-made det/gt pairs, regions, the vote's state machine."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.context.zones import SceneZones
from jaxtrack.errors import InputError
from jaxtrack.filters.fusion_voting import (
    ACTIVE,
    EMPTY,
    ENDED,
    INACTIVE,
    TARGET,
    TENTATIVE,
    ZONE,
    Runs,
    calibrate_init,
    calibrate_init_cost,
    calibrate_term,
    detection_gaps,
    false_positive_runs,
    initiation_runs,
    point_regions,
    region_thresholds,
    voting_init,
    voting_step,
)
from jaxtrack.types import MotTable

PERSON = (100.0, 100.0, 50.0, 100.0)


def _table(rows):
    rows = np.asarray(rows, np.float64)
    return MotTable.from_arrays(rows[:, 0], rows[:, 1], rows[:, 2:6], confs=rows[:, 6])


def _scene_pair():
    """One target (frames 1-10) missed in frames 4, 5 and 8; known false-positive runs.

    Runs: a still box in frames 1-3 (3); a box drifting 2 px a frame in frames 2-8 (7); a box
    moving 1 px in frames 1-2 (2) then jumping away (IoU 0 with it: a new run of 3 in frames
    3-5); two lone boxes in frame 9 (1 and 1). The boxes on an ignored gt person
    (``conf = 0``) are matched, hence no run.
    """
    gt = [[f, 1, *PERSON, 1] for f in range(1, 11)] + [[f, 2, 300, 300, 40, 80, 0] for f in (1, 2)]
    det = [[f, -1, *PERSON, 1] for f in range(1, 11) if f not in (4, 5, 8)]
    det += [[f, -1, 400, 50, 40, 80, 1] for f in (1, 2, 3)]
    det += [[f, -1, 600 + 2 * f, 300, 30, 60, 1] for f in range(2, 9)]
    det += [[1, -1, 10, 400, 30, 60, 1], [2, -1, 11, 400, 30, 60, 1]]
    det += [[f, -1, 200, 400, 30, 60, 1] for f in (3, 4, 5)]
    det += [[9, -1, 700, 10, 20, 40, 1], [9, -1, 10, 10, 20, 40, 1]]
    det += [[f, -1, 301, 300, 40, 80, 1] for f in (1, 2)]  # the ignored person: matched
    rng = np.random.default_rng(0)
    det = np.asarray(det, np.float64)[rng.permutation(len(det))]  # file order is no help
    return _table(det), _table(gt)


def test_false_positive_runs_match_the_hand_made_scene():
    det, gt = _scene_pair()
    runs = false_positive_runs(det, gt)
    assert sorted(runs.lengths.tolist()) == [1, 1, 2, 3, 3, 7]
    # each run is placed at the foot point of its first box
    found = {tuple(p): int(n) for p, n in zip(runs.points.tolist(), runs.lengths, strict=True)}
    assert found[(420.0, 130.0)] == 3
    assert found[(619.0, 360.0)] == 7
    assert found[(25.0, 460.0)] == 2
    assert found[(215.0, 460.0)] == 3


def test_false_positive_runs_on_random_scenes_with_known_runs():
    """Tracks on distinct cells of a 100 px grid (no ambiguity): the runs are the tracks."""
    rng = np.random.default_rng(7)
    for _ in range(5):
        cells = rng.permutation(64)[:24]
        det, gt, truth = [], [], []
        for k, cell in enumerate(cells):
            x, y = 100.0 * (cell % 8), 100.0 * (cell // 8)
            first, length = rng.integers(1, 30), rng.integers(1, 12)
            frames = range(first, first + length)
            if k % 3 == 0:  # a detected gt person, missed now and then: no run
                gt += [[f, k, x, y, 40, 80, 1] for f in frames]
                det += [[f, -1, x + 1, y, 40, 80, 1] for f in frames if rng.random() < 0.7]
            else:
                det += [[f, -1, x + rng.uniform(-2, 2), y, 40, 80, 1] for f in frames]
                truth.append(length)
        runs = false_positive_runs(_table(det), _table(gt))
        assert sorted(runs.lengths.tolist()) == sorted(truth)


def test_linking_threshold_splits_a_drifting_run():
    det, gt = _scene_pair()
    # the drifting box moves 2 px a frame: IoU (28 / 32) ~ 0.875 links it at 0.3, not at 0.9
    runs = false_positive_runs(det, gt, link_iou=0.9)
    assert sorted(runs.lengths.tolist()) == [1] * 9 + [2, 3, 3]


def test_detection_gaps_of_the_true_target_only():
    det, gt = _scene_pair()
    gaps = detection_gaps(det, gt)
    assert gaps.lengths.tolist() == [2, 1]
    np.testing.assert_array_equal(gaps.points, [[125.0, 200.0], [125.0, 200.0]])


def test_detection_gaps_at_the_support_gate():
    # a target whose box in frames 4-6 is shifted by 20 px: IoU 30 / 70 = 0.43, below 0.5
    # (a gap of 3 at 0.5) but inside the tracker's gate of 0.3 (no gap there)
    gt = _table([[f, 1, *PERSON, 1] for f in range(1, 11)])
    det = _table([[f, -1, PERSON[0] + 20 * (f in (4, 5, 6)), *PERSON[1:], 1] for f in range(1, 11)])
    assert detection_gaps(det, gt).lengths.tolist() == [3]
    assert detection_gaps(det, gt, match_iou=0.3).lengths.tolist() == []


def test_the_fusion_context_calibrates_gaps_at_the_trackers_gate():
    from jaxtrack.filters.fusion_tracker import FusionConfig
    from jaxtrack.pipelines.fusion_context import _thresholds

    # shifted (IoU 0.43) in frames 4-6, missed in frames 8-9; one lone false positive
    shifted = (4, 5, 6)
    gt = _table([[f, 1, *PERSON, 1] for f in range(1, 13)])
    rows = [[f, -1, PERSON[0] + 20 * (f in shifted), *PERSON[1:], 1] for f in range(1, 13)]
    det = _table([row for row in rows if row[0] not in (8, 9)] + [[2, -1, 500, 50, 30, 60, 1]])
    scene = SceneZones(np.zeros((0, 4), np.float32), np.ones((8, 8), bool), 100.0)
    assert calibrate_term(detection_gaps(det, gt).lengths) == 4  # gaps 3 and 2 at IoU 0.5
    notes = []
    found = _thresholds(det, gt, scene, FusionConfig(), notes)
    assert found.term.tolist() == [3, 3, 3]  # the gap of 2 alone: the shifted boxes support
    assert "1 detection gaps" in notes[0]


def test_calibrate_init_exact_on_known_runs():
    det, gt = _scene_pair()
    lengths = false_positive_runs(det, gt).lengths  # 1, 1, 2, 3, 3, 7
    assert calibrate_init(lengths) == 8  # 99% of 6 runs: all must be shorter
    assert calibrate_init(lengths, reject=5 / 6) == 4  # 5 runs < 4, 4 runs < 3
    assert calibrate_init(lengths, reject=0.5) == 3  # 3 runs < 3, 2 runs < 2
    assert calibrate_term(detection_gaps(det, gt).lengths) == 3


def test_calibration_matches_brute_force():
    rng = np.random.default_rng(1)
    for _ in range(50):
        lengths = rng.geometric(0.3, size=rng.integers(1, 300))
        share = rng.uniform(0.05, 1.0)
        brute = next(
            th for th in range(1, lengths.max() + 2) if np.mean(lengths < th) >= share - 1e-12
        )
        assert calibrate_init(lengths, share) == brute


def test_calibration_refuses_bad_input():
    with pytest.raises(InputError, match="no false-positive runs"):
        calibrate_init(np.zeros(0, np.int64))
    with pytest.raises(InputError, match="share"):
        calibrate_term(np.array([1, 2]), keep=0.0)
    det, gt = _scene_pair()
    with pytest.raises(InputError, match="IoU"):
        false_positive_runs(det, gt, link_iou=0.0)


def test_initiation_runs_are_the_targets_first_detected_runs():
    det, gt = _scene_pair()
    # target 1 is detected in frames 1-3, missed in 4-5: its first run is 3 frames long; the
    # ignored person (conf 0) is no target
    starts = initiation_runs(det, gt)
    assert starts.lengths.tolist() == [3]
    np.testing.assert_array_equal(starts.points, [[125.0, 200.0]])
    # a target first detected in frame 3 and then to its end; one never detected
    gt = _table(
        [[f, 1, *PERSON, 1] for f in range(1, 8)] + [[f, 2, 400, 300, 40, 80, 1] for f in (1, 2)]
    )
    det = _table([[f, -1, *PERSON, 1] for f in range(3, 8)])
    assert initiation_runs(det, gt).lengths.tolist() == [5]
    assert initiation_runs(_table(np.zeros((0, 7))), gt).lengths.tolist() == []


def test_calibrate_init_cost_by_hand():
    runs, starts = [1, 1, 2, 3, 3, 7], [5, 10]
    # false-target frames sum(max(0, L - th + 1)) + late frames sum(min(S, th - 1)):
    # th 1: 17 + 0, 2: 11 + 2, 3: 7 + 4, 4: 4 + 6, 5: 3 + 8
    assert calibrate_init_cost(runs, starts) == 4
    # without targets every run is rejected (the share rule at 100 %), without runs th 1
    assert calibrate_init_cost(runs, []) == 8 == calibrate_init(runs, 1.0)
    assert calibrate_init_cost([], starts) == 1
    with pytest.raises(InputError, match="no false-positive runs and no targets"):
        calibrate_init_cost([], [])


def test_calibrate_init_cost_matches_brute_force():
    rng = np.random.default_rng(3)
    for _ in range(50):
        runs = rng.geometric(0.3, size=rng.integers(0, 200))
        starts = rng.geometric(0.05, size=rng.integers(1, 30))
        costs = {}
        for th in range(1, 200):
            false = sum(max(0, int(length) - th + 1) for length in runs)
            late = sum(min(int(length), th - 1) for length in starts)
            costs[th] = false + late
        best = min(costs.values())
        assert calibrate_init_cost(runs, starts) == min(t for t, c in costs.items() if c == best)


def _scene() -> SceneZones:
    """200 x 100 image, 10 px cells; left half active; a zone box over x in [0, 20]."""
    activity = np.zeros((10, 20), bool)
    activity[:, :10] = True
    return SceneZones(boxes=np.array([[0.0, 0.0, 20.0, 100.0]]), activity=activity, cell_size=10.0)


def test_point_regions_on_a_hand_made_mask():
    scene = _scene()
    points = jnp.array([[5.0, 50.0], [20.0, 99.0], [50.0, 50.0], [150.0, 50.0], [300.0, 10.0]])
    regions = point_regions(scene.boxes, scene.activity, scene.cell_size, points)
    assert regions.tolist() == [ZONE, ZONE, ACTIVE, INACTIVE, INACTIVE]
    jitted = jax.jit(point_regions, static_argnums=2)(
        scene.boxes, scene.activity, scene.cell_size, points
    )
    np.testing.assert_array_equal(jitted, regions)


def _runs(placed):
    lengths = [n for n, _ in placed]
    points = [p for _, p in placed]
    return Runs(np.asarray(lengths, np.int64), np.asarray(points, np.float64))


def test_region_thresholds_follow_the_documented_rule():
    zone, active, inactive = (10.0, 50.0), (50.0, 50.0), (150.0, 50.0)
    runs = _runs(
        [(1, zone), (1, zone), (2, active), (3, active), (4, active)] + [(6, inactive)] * 2
    )
    gaps = _runs([(9, zone), (2, active), (5, active), (3, inactive)])
    thresholds = region_thresholds(runs, gaps, _scene())
    # init: own statistic 5 (active), 7 (inactive, raised to >= global 7), 2 (zone, <= global)
    assert thresholds.init.tolist() == [5, 7, 2]
    # term: global 10; active own 6; inactive min(4, 10); zone min(10, 10)
    assert thresholds.term.tolist() == [6, 4, 10]


def test_region_without_runs_takes_the_global_value_and_zones_never_rise():
    zone, active = (10.0, 50.0), (50.0, 50.0)
    runs = _runs([(9, zone), (1, active), (2, active)])  # global 10, zone own 10, active 3
    gaps = _runs([(2, active)])
    thresholds = region_thresholds(runs, gaps, _scene())
    assert thresholds.init.tolist() == [3, 10, 10]
    assert thresholds.term.tolist() == [3, 3, 3]
    with pytest.raises(InputError, match="activity mask"):
        region_thresholds(runs, gaps, SceneZones(_scene().boxes, None, None))


def test_region_thresholds_by_cost_per_region():
    zone, active, inactive = (10.0, 50.0), (50.0, 50.0), (150.0, 50.0)
    runs = _runs([(1, zone), (1, active), (1, active), (2, active), (5, inactive), (1, inactive)])
    gaps = _runs([(2, active)])
    starts = _runs([(9, zone), (9, zone), (4, active), (6, active), (20, inactive)])
    thresholds = region_thresholds(runs, gaps, _scene(), starts=starts)
    # own: active runs 1, 1, 2 vs starts 4, 6: th 2 (3 errors); inactive runs 5, 1 vs a
    # start of 20: th 2 (5 errors); zone run 1 vs starts 9, 9: th 1 (1 error)
    own = [
        calibrate_init_cost([1, 1, 2], [4, 6]),
        calibrate_init_cost([5, 1], [20]),
        calibrate_init_cost([1], [9, 9]),
    ]
    whole = calibrate_init_cost([1, 1, 1, 2, 5, 1], [9, 9, 4, 6, 20])
    assert own == [2, 2, 1] and whole == 2
    # inactive: max(own, whole); zone: min(own, whole)
    assert thresholds.init.tolist() == [own[0], max(own[1], whole), min(own[2], whole)]
    assert thresholds.term.tolist() == region_thresholds(runs, gaps, _scene()).term.tolist()


def test_the_fusion_context_calibrates_by_the_configured_rule():
    from jaxtrack.filters.fusion_tracker import FusionConfig
    from jaxtrack.pipelines.fusion_context import _thresholds

    det, gt = _scene_pair()
    # a second target, detected on all its 10 frames, away from every other box
    steady = [[f, 3, 450, 150, 40, 80, 1] for f in range(1, 11)]
    gt = _table(np.r_[np.c_[gt.frames, gt.ids, gt.boxes, gt.confs], steady])
    det = _table(np.r_[np.c_[det.frames, det.ids, det.boxes, det.confs], steady])
    scene = SceneZones(np.zeros((0, 4), np.float32), np.ones((8, 8), bool), 100.0)
    share_notes, cost_notes = [], []
    share = _thresholds(det, gt, scene, FusionConfig(init_rule="share"), share_notes)
    cost = _thresholds(det, gt, scene, FusionConfig(init_rule="cost"), cost_notes)
    # the run's training note says which rule set th_init
    assert "cost rule" not in share_notes[0]
    assert cost_notes[0].endswith("2 target starts (cost rule)")
    assert share.init.tolist() == [8, 8, 8]  # 99 % of the runs 1, 1, 2, 3, 3, 7
    # the targets' first runs (3 and 10 frames) against the runs: 10 errors at th 4 to 8
    assert calibrate_init_cost([1, 1, 2, 3, 3, 7], [3, 10]) == 4
    assert cost.init.tolist() == [4, 4, 4]
    assert cost.term.tolist() == share.term.tolist()
    with pytest.raises(InputError, match="init_rule"):
        FusionConfig(init_rule="median")
    assert FusionConfig.from_dict(FusionConfig(init_rule="cost").to_dict()).init_rule == "cost"


def _one_slot(supported, th_init, th_term):
    state = voting_init(1)
    statuses = []
    for s in supported:
        state = voting_step(state, jnp.array([bool(s)]), jnp.array([th_init]), jnp.array([th_term]))
        statuses.append(int(state.status[0]))
    return statuses


def test_voting_transitions_by_hand():
    T, G = TENTATIVE, TARGET
    assert _one_slot([1, 1, 1, 0, 1, 0, 0, 0, 1], 3, 2) == [T, T, G, G, G, G, ENDED, EMPTY, T]
    assert _one_slot([1, 1, 0, 1, 1, 1], 3, 2) == [T, T, EMPTY, T, T, G]  # must be consecutive
    assert _one_slot([1, 0, 0, 0], 1, 3) == [G, G, G, ENDED]
    assert _one_slot([1, 1, 0, 0, 1, 0, 0], 2, 3) == [T, G, G, G, G, G, G]  # support resets


def _reference_vote(supported, th_init, th_term):
    """Slot-by-slot loop of the documented rules (independent of the JAX code)."""
    num_frames, num_slots = supported.shape
    status = [EMPTY] * num_slots
    support = [0] * num_slots
    missed = [0] * num_slots
    history = np.zeros((num_frames, num_slots), np.int64)
    for t in range(num_frames):
        for s in range(num_slots):
            if status[s] == TARGET:
                if supported[t, s]:
                    support[s], missed[s] = support[s] + 1, 0
                else:
                    support[s], missed[s] = 0, missed[s] + 1
                    if missed[s] >= th_term[s]:
                        status[s] = ENDED
            elif supported[t, s]:
                support[s] = support[s] + 1 if status[s] == TENTATIVE else 1
                missed[s] = 0
                status[s] = TARGET if support[s] >= th_init[s] else TENTATIVE
            else:
                status[s], support[s], missed[s] = EMPTY, 0, 0
        history[t] = status
    return history


def test_voting_scan_matches_loop_reference_and_jit():
    rng = np.random.default_rng(2)
    supported = rng.random((60, 16)) < 0.7
    th_init = rng.integers(1, 6, 16)
    th_term = rng.integers(1, 6, 16)

    def step(state, s):
        state = voting_step(state, s, jnp.asarray(th_init), jnp.asarray(th_term))
        return state, state.status

    _, eager = jax.lax.scan(step, voting_init(16), jnp.asarray(supported))
    _, jitted = jax.jit(lambda xs: jax.lax.scan(step, voting_init(16), xs))(jnp.asarray(supported))
    expected = _reference_vote(supported, th_init, th_term)
    np.testing.assert_array_equal(eager, expected)
    np.testing.assert_array_equal(jitted, expected)
    assert {TENTATIVE, TARGET, ENDED, EMPTY} <= set(np.unique(expected).tolist())
