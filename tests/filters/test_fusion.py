"""The Fusion tracker's step on drawn scenes with known truth: voting, pool members, fusion
rules, regions, occlusion and re-identification."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.boxes import cxcywh_to_xywh, xywh_to_cxcywh
from jaxtrack.context.zones import SceneZones
from jaxtrack.filters.base import run
from jaxtrack.filters.fusion import (
    MEMBERS,
    _signatures,
    fusion_filter,
)
from jaxtrack.filters.fusion_profile import signature_distance
from jaxtrack.filters.fusion_tracker import (
    FusionConfig,
    FusionContext,
    build_fusion,
    default_context,
)
from jaxtrack.filters.fusion_voting import EMPTY, TARGET, TENTATIVE, Thresholds
from jaxtrack.filters.kalman import kalman_birth, kalman_predict, mahalanobis_costs
from jaxtrack.models.dynamics import MEASURED
from jaxtrack.pipelines.tracking import output_rows
from jaxtrack.types import Detections, FrameInputs
from tests.filters.test_cmt import COLOURS, INFO, SIZE, frame_inputs, two_tone

BACKGROUND = np.full((SIZE[1], SIZE[0], 3), 128, np.uint8)
#: One walker 16 x 36 moving right 1.5 px per frame, detected in frames 0..39 of 60.
NUM_FRAMES, DETECTED = 60, 40


def walker(t: int, y: float = 30.0, x0: float = 20.0, speed: float = 1.5):
    return (x0 + speed * t, y, 16.0, 36.0)


def drawn_scene(people, detected, num_frames=NUM_FRAMES, num_slots=4):
    """Frames and padded detections: ``people[k](t)`` the box of person ``k`` (drawn in
    ``COLOURS[k]`` when not None), detected when ``detected[k](t)``."""
    frames, kept = [], []
    for t in range(num_frames):
        image = BACKGROUND.copy()
        detected_now = []
        for k, person in enumerate(people):
            box = person(t)
            if box is None:
                continue
            two_tone(image, box, *COLOURS[k % len(COLOURS)])
            if detected[k](t):
                detected_now.append(box)
        frames.append(image)
        kept.append(detected_now)
    return frame_inputs(frames, kept, num_slots=num_slots)


def tracked(config: FusionConfig, inputs: FrameInputs, context=None):
    filt, params = build_fusion(config, INFO, context)
    _, info = _runner(filt)(jax.random.PRNGKey(0), params, inputs)
    return jax.device_get(info), output_rows(jax.device_get(info), config, 1)


@functools.cache
def _runner(filt):
    """One compiled run per filter (the filters are cached per setting)."""
    return jax.jit(functools.partial(run, filt))


def one_walker():
    return drawn_scene([walker], [lambda t: t < DETECTED])


def iou(a, b):
    ax, ay, aw, ah = a
    bx, by, bw, bh = b
    w = max(0.0, min(ax + aw, bx + bw) - max(ax, bx))
    h = max(0.0, min(ay + ah, by + bh) - max(ay, by))
    return w * h / (aw * ah + bw * bh - w * h)


def test_a_walker_is_voted_in_after_th_init_and_ends_after_th_term():
    info, rows = tracked(FusionConfig(max_targets=8), one_walker())  # paper: 3 and 8
    shown = info.tracks.mask.any(axis=1)
    assert np.flatnonzero(shown)[0] == 2  # third consecutive detection
    assert np.flatnonzero(shown)[-1] == DETECTED + 8 - 2  # ended on the 8th missed frame
    status = info.status.max(axis=1)
    assert list(status[:3]) == [TENTATIVE, TENTATIVE, TARGET]
    assert set(np.unique(info.tracks.ids[info.tracks.mask])) == {1}
    # offline: from its first detection to its last one (coasting tail trimmed)
    assert rows.frames.min() == 1 and rows.frames.max() == DETECTED
    assert set(rows.ids.tolist()) == {1}
    for frame, box in zip(rows.frames, rows.boxes, strict=True):
        assert iou(box, walker(frame - 1)) > 0.8


def test_a_pool_of_the_detection_member_follows_the_detections_and_coasts_at_constant_velocity():
    info, _ = tracked(FusionConfig(pool="detection", max_targets=8), one_walker())
    slot = info.tracks.mask.any(axis=0).argmax()
    boxes = info.tracks.boxes[:, slot]
    for t in range(2, DETECTED):
        np.testing.assert_allclose(boxes[t], walker(t), atol=1e-4)
    for t in range(DETECTED, DETECTED + 6):  # no detection: the constant-velocity box
        np.testing.assert_allclose(boxes[t], walker(t), atol=1e-3)
    assert not info.member_valid[:, :, 1:].any()  # classifier and predictor not in the pool


def test_the_detection_members_mahalanobis_gate_refuses_a_jump_the_iou_gate_would_take():
    # the walker's detection drops by half a box height from frame 20 on (a merged box, a
    # neighbour's): IoU 1/3 with the walker's box, outside its Kalman filter's gate
    jump = 20

    def detected_box(t):
        x, y, w, h = walker(t)
        return (x, y + (0.5 * h if t >= jump else 0.0), w, h)

    inputs = drawn_scene([detected_box], [lambda t: True], num_frames=jump + 1)
    config = FusionConfig(pool="detection", max_targets=8)
    filt, params = build_fusion(config, INFO)
    before = jax.tree.map(lambda x: x[:jump], inputs)
    state, _ = _runner(filt)(jax.random.PRNGKey(0), params, before)
    slot = int(np.flatnonzero(np.asarray(state.voting.status) == TARGET)[0])
    mean, cov = kalman_predict(state.means[slot], state.covs[slot], params.motion_noise_std)
    measured = xywh_to_cxcywh(jnp.asarray([detected_box(jump)], jnp.float32), jnp)
    distance, _ = mahalanobis_costs(mean[None], cov[None], measured, params.measurement_noise_std)
    predicted = np.asarray(cxcywh_to_xywh(mean[jnp.array(MEASURED)], jnp))
    assert iou(predicted, detected_box(jump)) > 0.32  # the premise: inside the IoU gate (0.3)
    assert float(distance[0, 0]) > 1.3 * float(params.chi2_gate)  # and outside this one

    info, _ = tracked(config, inputs)
    identity = int(state.ids[slot])
    assert info.member_valid[jump - 1, slot, 0] and not info.member_valid[jump, slot, 0]
    np.testing.assert_allclose(info.tracks.boxes[jump, slot], walker(jump), atol=0.5)  # coasts
    others = info.candidates.mask[jump] & (info.candidates.ids[jump] != identity)
    assert others.sum() == 1  # the jumped detection opens a hypothesis of its own
    np.testing.assert_allclose(
        info.candidates.boxes[jump][others][0], detected_box(jump), atol=1e-4
    )


SIZE_24_48 = (24.0, 48.0)
#: Two places 90 px apart: where the two targets' signatures were taken (and, in the
#: exchange tests, where the two targets stand).
APART = [(20.0, 40.0, *SIZE_24_48), (110.0, 40.0, *SIZE_24_48)]


def _drawn(places, dressed) -> np.ndarray:
    """The background with person ``k`` at ``places[k]`` dressed in ``COLOURS[dressed[k]]``."""
    frame = BACKGROUND.copy()
    for place, colours in zip(places, dressed, strict=True):
        two_tone(frame, place, *COLOURS[colours])
    return frame


def _two_targets_step(config, slots, people, dressed, met=False):
    """Targets 1 and 2 in slots 0 and 1 at ``slots`` (each a model of a person dressed in
    ``COLOURS[0]`` / ``COLOURS[1]``, taken at :data:`APART`), ``met`` or not, and one step on
    a frame with people at ``people`` dressed in ``COLOURS[dressed[k]]``, each detected.
    Returns ``(stored models, state, info)``."""
    filt, params = build_fusion(config, INFO)
    pad = [(0.0, 0.0, 1.0, 1.0)] * 2
    stored = _signatures(jnp.asarray(_drawn(APART, (0, 1))), jnp.asarray(APART + pad))
    state = _hand_built(
        filt,
        params,
        slots + pad,
        [1, 2, -1, -1],
        [TARGET, TARGET, EMPTY, EMPTY],
        [20, 20, 0, 0],
        [11, 11, 0, 0],
    )
    pair = jnp.zeros((4, 4), bool).at[0, 1].set(met).at[1, 0].set(met)
    state = state._replace(
        signature=state.signature._replace(histogram=stored.histograms, count=jnp.ones((4, 2))),
        met=pair,
    )
    detections = Detections(
        jnp.asarray(people, jnp.float32), jnp.full((2,), 0.99, jnp.float32), jnp.ones(2, bool)
    )
    frame = jnp.asarray(_drawn(people, dressed))
    state, info = jax.jit(filt.step)(
        jax.random.PRNGKey(0), state, params, FrameInputs(detections, frame)
    )
    assert info.member_valid[:2, 0].all()  # both targets take a detection
    return stored.histograms, state, info


@pytest.mark.parametrize("weight", [0.0, None])
def test_the_signature_term_keeps_crossing_targets_on_their_own_detections(weight):
    # two targets predicted 2 px apart between two people who stand 20 px apart: by motion
    # alone each takes the person on its own side, which swaps the two (target 1 is dressed
    # as the person on the right); the signature distance in the cost puts each on its own
    # person (weight None: the default)
    config = FusionConfig(max_targets=4)
    if weight is not None:
        config = FusionConfig(max_targets=4, appearance_weight=weight)
    assert config.appearance_weight > 0 or weight == 0.0
    slots = [(57.0, 40.0, *SIZE_24_48), (59.0, 40.0, *SIZE_24_48)]
    people = [(68.0, 40.0, *SIZE_24_48), (48.0, 40.0, *SIZE_24_48)]
    _, _, info = _two_targets_step(config, slots, people, (0, 1))
    taken = np.asarray(info.members[:2, 0])
    expected = people[::-1] if weight == 0.0 else people  # swapped by motion alone
    np.testing.assert_allclose(taken, np.asarray(expected), atol=1e-4)


def _exchange_case(dressed, met, config):
    """Targets 1 and 2 at :data:`APART`, each detected at its own place (the gates allow
    nothing else) on a person dressed in ``COLOURS[dressed[k]]``; ``met``: the two were in
    one occlusion group since they were last checked."""
    stored, state, info = _two_targets_step(config, APART, APART, dressed, met)
    np.testing.assert_allclose(np.asarray(info.members[:2, 0]), np.asarray(APART), atol=1e-4)
    return stored, state, info


def _exchange_gain(dressed) -> float:
    """``D(0, 0) + D(1, 1) - D(0, 1) - D(1, 0)`` of :func:`_exchange_case`'s pair, from the
    signatures of the two drawings (the models have one observation each)."""
    places = jnp.asarray(APART)
    models = _signatures(jnp.asarray(_drawn(APART, (0, 1))), places).histograms
    seen = _signatures(jnp.asarray(_drawn(APART, dressed)), places).histograms
    d = np.asarray(signature_distance(models[:, None], seen[None, :]))
    return float(d[0, 0] + d[1, 1] - d[0, 1] - d[1, 0])


@pytest.mark.parametrize(
    "dressed, met, margin, swapped",
    [
        ((1, 0), True, None, True),  # the default check undoes the exchange
        ((1, 0), False, None, False),  # the two never met: nothing to check
        ((1, 0), True, -1.0, False),  # the check off
        ((1, 0), True, "below", True),  # a margin just below the pair's gain
        ((1, 0), True, "above", False),  # just above it
        ((0, 1), True, None, False),  # each on its own person
    ],
)
def test_two_targets_that_met_swap_identities_when_each_looks_like_the_other(
    dressed, met, margin, swapped
):
    config = FusionConfig(max_targets=4)
    if isinstance(margin, str):
        gain = _exchange_gain(dressed)
        margin = gain - 0.01 if margin == "below" else gain + 0.01
    if margin is not None:
        config = FusionConfig(max_targets=4, exchange_margin=margin)
    stored, state, info = _exchange_case(dressed, met, config)
    expected = [2, 1] if swapped else [1, 2]
    assert np.asarray(info.tracks.ids[:2]).tolist() == expected
    assert np.asarray(state.ids[:2]).tolist() == expected
    # the models went with the identities (then learned from the detections); the places,
    # motion and votes stayed with the slots
    own = signature_distance(state.signature.histogram[:2], stored[:2])
    other = signature_distance(state.signature.histogram[:2], stored[1::-1])
    assert bool(jnp.all(other < own)) == swapped
    np.testing.assert_array_equal(np.asarray(state.voting.support[:2]), [21, 21])
    # a pair is checked once: its episode is closed whatever the outcome
    assert not bool(state.met.any())


def test_targets_in_one_occlusion_group_are_marked_as_met():
    # two targets whose boxes overlap (Q > 0.3), each detected: the pair is marked for a
    # check once they are apart; a third target far away is not
    filt, params = build_fusion(FusionConfig(max_targets=4), INFO)
    places = [(x, 40.0, *SIZE_24_48) for x in (40.0, 50.0, 120.0)]
    frame = _drawn(places, (0, 1, 0))
    state = _hand_built(
        filt,
        params,
        [*places, (0.0, 0.0, 1.0, 1.0)],
        [1, 2, 3, -1],
        [TARGET, TARGET, TARGET, EMPTY],
        [20, 20, 20, 0],
        [11, 11, 11, 0],
    )
    detections = Detections(
        jnp.asarray(places, jnp.float32), jnp.full((3,), 0.99, jnp.float32), jnp.ones(3, bool)
    )
    state, info = jax.jit(filt.step)(
        jax.random.PRNGKey(0), state, params, FrameInputs(detections, jnp.asarray(frame))
    )
    assert np.asarray(info.tracks.ids[:3]).tolist() == [1, 2, 3]
    expected = np.zeros((4, 4), bool)
    expected[0, 1] = expected[1, 0] = True
    np.testing.assert_array_equal(np.asarray(state.met), expected)


def test_a_coasting_targets_evidence_is_its_filters_prediction():
    # after the walker's last detection the evidence history (the predictor's tracklet and
    # the speed reference) takes the filter's predicted box, not the fused box
    config = FusionConfig(max_targets=8)
    filt, params = build_fusion(config, INFO)
    inputs = jax.tree.map(lambda x: x[: DETECTED + 3], one_walker())
    state, _ = _runner(filt)(jax.random.PRNGKey(0), params, inputs)
    slot = int(np.flatnonzero(np.asarray(state.voting.status) == TARGET)[0])
    assert int(state.voting.missed[slot]) == 3
    predicted = cxcywh_to_xywh(state.means[slot][jnp.array(MEASURED)], jnp)
    np.testing.assert_allclose(state.history[slot, -1], predicted, atol=1e-4)
    np.testing.assert_allclose(state.history[slot, -1], walker(DETECTED + 2), atol=0.5)
    # while detected, the evidence is the detection itself
    np.testing.assert_allclose(state.history[slot, -4], walker(DETECTED - 1), atol=1e-4)


@pytest.mark.parametrize("fusion", ["naive", "proposed"])
def test_the_fused_box_is_the_weighted_sum_of_the_valid_responses(fusion):
    info, _ = tracked(FusionConfig(fusion=fusion, max_targets=8), one_walker())
    target = info.status == TARGET
    target[1:] &= target[:-1]  # a target since the frame before (voted in: its detection)
    valid = info.member_valid[target]
    weights = info.weights[target]
    assert valid.any(axis=1).all()
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, atol=1e-5)
    assert (weights[~valid] == 0).all()
    fused = np.einsum("sm,smk->sk", weights, info.members[target])
    np.testing.assert_allclose(info.tracks.boxes[target], fused, atol=1e-3)
    if fusion == "naive":
        np.testing.assert_allclose(weights, valid / valid.sum(axis=1, keepdims=True), atol=1e-6)
    else:  # the dynamic weights are not the mean on every frame
        assert np.abs(weights - valid / valid.sum(axis=1, keepdims=True)).max() > 1e-3
    # all three members respond while the walker is detected
    assert info.member_valid[target][:20].all()


def test_a_short_false_positive_run_never_becomes_a_target():
    flicker = lambda t: (100.0, 70.0, 16.0, 36.0) if 10 <= t < 12 else None  # noqa: E731
    inputs = drawn_scene([walker, flicker], [lambda t: t < DETECTED, lambda t: True])
    info, rows = tracked(FusionConfig(max_targets=8), inputs)
    assert set(rows.ids.tolist()) == {1}  # the run of 2 < th_init 3 frames is never output
    assert (info.candidates.boxes[info.candidates.mask][:, 0] == 100.0).sum() == 2


def _context(init, term, zone_boxes):
    base = default_context(INFO)
    activity = np.ones_like(base.scene.activity)
    scene = SceneZones(np.asarray(zone_boxes, np.float32).reshape(-1, 4), activity, 8)
    thresholds = Thresholds(np.asarray(init), np.asarray(term))
    return FusionContext(scene, base.motion, thresholds, "drawn")


def test_thresholds_follow_the_region_of_the_foot_point():
    # a zone over the left part of the image: the walker starts inside it
    inputs = drawn_scene([walker, lambda t: walker(t, y=70.0, x0=100.0)], [lambda t: True] * 2)
    context = _context([5, 9, 2], [8, 8, 8], [(0, 0, 60, 120)])
    info, _ = tracked(FusionConfig(max_targets=8), inputs, context)
    first = [
        int(np.flatnonzero(((info.status == TARGET) & close).any(axis=1))[0])
        for close in (np.abs(info.candidates.boxes[..., 1] - y) < 3 for y in (30.0, 70.0))
    ]
    assert first == [1, 4]  # zone: th_init 2; active area: th_init 5


def test_targets_that_overlap_have_one_occluder():
    # two walkers cross: the second walks left on nearly the same row
    inputs = drawn_scene(
        [walker, lambda t: walker(t, y=34.0, x0=110.0, speed=-1.5)], [lambda t: True] * 2
    )
    info, _ = tracked(FusionConfig(max_targets=8), inputs)
    occluded = info.occluded.sum(axis=1)
    assert occluded.max() == 1  # never both
    crossing = np.flatnonzero(occluded)
    assert crossing.size > 0
    # only while the two boxes overlap (they meet at t = 30)
    assert 20 <= crossing.min() and crossing.max() <= 40


def test_a_new_target_near_an_occluded_one_takes_its_identity_back():
    state, params, frame, detections = _reidentification_case(COLOURS[0])
    after, _ = _step()(jax.random.PRNGKey(0), state, params, FrameInputs(detections, frame))
    assert int(after.voting.status[1]) == TARGET and int(after.ids[1]) == 7  # former identity
    assert int(after.voting.status[0]) == EMPTY and int(after.ids[0]) == -1  # its slot freed


def test_a_differently_dressed_new_target_keeps_its_own_identity():
    state, params, frame, detections = _reidentification_case(((250, 250, 250), (10, 10, 10)))
    after, _ = _step()(jax.random.PRNGKey(0), state, params, FrameInputs(detections, frame))
    assert int(after.voting.status[1]) == TARGET and int(after.ids[1]) == 9
    assert int(after.voting.status[0]) == TARGET and int(after.ids[0]) == 7


@functools.cache
def _step():
    return jax.jit(build_fusion(FusionConfig(max_targets=4), INFO)[0].step)


def _filters_at(boxes, params):
    """Kalman filters (``means``, ``covs``) of new slots on ``boxes``."""
    means, covs = jax.vmap(kalman_birth, in_axes=(0, None, None))(
        xywh_to_cxcywh(boxes, jnp), params.measurement_noise_std, params.initial_velocity_std
    )
    return {"means": means, "covs": covs}


def _hand_built(filt, params, boxes, ids, status, support, count):
    """A state of four slots at ``boxes`` (Kalman filters born there, the history filled
    with them) with ``ids``, ``status``, ``support`` and evidence ``count``; the next identity
    after the largest."""
    boxes = jnp.asarray(boxes, jnp.float32)
    state = filt.init(jax.random.PRNGKey(0), params)
    return state._replace(
        ids=jnp.asarray(ids, jnp.int32),
        next_id=jnp.int32(max(ids) + 1),
        voting=state.voting._replace(
            status=jnp.asarray(status, jnp.int32), support=jnp.asarray(support, jnp.int32)
        ),
        boxes=boxes,
        history=jnp.broadcast_to(boxes[:, None], state.history.shape),
        count=jnp.asarray(count, jnp.int32),
        **_filters_at(boxes, params),
    )


def _reidentification_case(new_colours):
    """Slot 0: target 7, occluded, at ``old``; slot 1: hypothesis 9 one detection short of
    th_init (3), detected at ``new`` 12 px to the right, dressed in ``new_colours``."""
    filt, params = build_fusion(FusionConfig(max_targets=4), INFO)
    old, new = (40.0, 30.0, 16.0, 36.0), (52.0, 30.0, 16.0, 36.0)
    stored_frame = BACKGROUND.copy()
    two_tone(stored_frame, old, *COLOURS[0])
    stored = _signatures(jnp.asarray(stored_frame), jnp.asarray([old] * 4)).histograms
    frame = BACKGROUND.copy()
    two_tone(frame, new, *new_colours)
    pad = (0, 0, 1, 1)
    state = _hand_built(
        filt,
        params,
        [old, new, pad, pad],
        [7, 9, -1, -1],
        [TARGET, TENTATIVE, EMPTY, EMPTY],
        [5, 2, 0, 0],
        [11, 2, 0, 0],
    )
    state = state._replace(
        signature=state.signature._replace(histogram=stored, count=jnp.ones((4, 2))),
        occluded=jnp.asarray([True, False, False, False]),
    )
    detections = Detections(
        jnp.asarray([new, (0, 0, 1, 1)], jnp.float32),
        jnp.asarray([0.99, 0.0], jnp.float32),
        jnp.asarray([True, False]),
    )
    return state, params, jnp.asarray(frame), detections


def test_jit_and_eager_steps_agree():
    inputs = one_walker()
    filt, params = build_fusion(FusionConfig(max_targets=4), INFO)
    state = filt.init(jax.random.PRNGKey(0), params)
    jitted = _step()
    eager_state, jit_state = state, state
    for t in range(3):
        frame = jax.tree.map(lambda x: x[t], inputs)  # noqa: B023
        eager_state, eager_info = filt.step(jax.random.PRNGKey(t), eager_state, params, frame)
        jit_state, jit_info = jitted(jax.random.PRNGKey(t), jit_state, params, frame)
    np.testing.assert_allclose(eager_info.tracks.boxes, jit_info.tracks.boxes, atol=1e-4)
    np.testing.assert_array_equal(eager_info.status, jit_info.status)


def test_more_detections_than_slots_flag_an_overflow():
    people = [lambda t, k=k: walker(t, y=10.0 + 25 * k, x0=10.0) for k in range(4)]
    inputs = drawn_scene(people, [lambda t: True] * 4)
    info, _ = tracked(FusionConfig(max_targets=2), inputs)
    assert bool(info.overflow[0])


@pytest.mark.parametrize(
    ("pool", "fusion", "message"),
    [((), "proposed", "non-empty"), (("radar",), "proposed", "subset"), (MEMBERS, "max", "fusion")],
)
def test_bad_filter_settings_are_refused(pool, fusion, message):
    with pytest.raises(ValueError, match=message):
        fusion_filter(pool, fusion, 4)
