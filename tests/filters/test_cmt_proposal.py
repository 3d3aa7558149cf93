"""CMT's contextual proposal (CMT eqs. 5-10) against independent oracles.

Oracles: float64 NumPy loops of eqs. 6-10 on hand-built scenes and of the mixture density of
eq. 5; the importance-sampling identity ``E_q[p / q f 1{no exit}] = (1 - q(exit)) E_p[f]``
with the constant-velocity transition's analytic moments; the product of Gaussians of the
prediction and a blob; finite differences.
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.stats import norm

from jaxtrack.filters.cmt_conditions import (
    EXIT,
    GROUP_IOU,
    MERGE,
    NORMAL,
    SPLIT,
    CPDParams,
    condition_probabilities,
    default_cpd_params,
    group_members,
)
from jaxtrack.filters.cmt_proposal import contextual_proposal, log_constant_velocity
from jaxtrack.filters.mixture_models import log_transition
from jaxtrack.filters.mixture_state import MixtureParams
from jaxtrack.types import Detections

MOTION = np.array([0.05, 0.05, 0.01, 0.01], np.float32)
PARAMS = default_cpd_params()
#: The defaults with group blobs on (they are off by default).
GROUPED = PARAMS._replace(group_area_ratio=jnp.float32(0.6))
NO_ZONE = (np.zeros((2, 4), np.float32), np.zeros(2, bool))


def eager_propose(key, particles, estimates, alive, blobs, zone_boxes, zone_mask, params=PARAMS):
    """The proposal with this file's motion noise (eager; :data:`propose` is compiled)."""
    return contextual_proposal(
        key,
        particles,
        estimates,
        alive,
        params,
        jnp.asarray(MOTION),
        blobs,
        zone_boxes,
        zone_mask,
    )


propose = jax.jit(eager_propose)
log_cv = jax.jit(log_constant_velocity)
probabilities_of = jax.jit(condition_probabilities)


def cv_prediction(states) -> jnp.ndarray:
    """The constant-velocity prediction of ``(cx, vx, cy, vy, w, h)`` states (``T = 1``)."""
    states = np.asarray(states, np.float32).copy()
    states[:, 0] += states[:, 1]
    states[:, 2] += states[:, 3]
    return jnp.asarray(states)


def blobs_of(boxes, mask=None) -> Detections:
    """Padded blobs from ``(x, y, w, h)`` boxes (all real unless ``mask`` says otherwise)."""
    boxes = np.asarray(boxes, np.float32).reshape(-1, 4)
    mask = np.ones(len(boxes), bool) if mask is None else np.asarray(mask, bool)
    return Detections(jnp.asarray(boxes), jnp.asarray(mask, jnp.float32), jnp.asarray(mask))


def box_at(state, dx=0.0, dy=0.0) -> list[float]:
    """The ``(x, y, w, h)`` box of a state's CV prediction, its centre moved by ``(dx, dy)``."""
    cx, vx, cy, vy, w, h = (float(v) for v in state)
    return [cx + vx + dx - w / 2, cy + vy + dy - h / 2, w, h]


def reference_iou(a, b) -> float:
    """IoU of two ``(x, y, w, h)`` boxes, float64."""
    ix = max(0.0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
    inter = ix * iy
    return inter / (a[2] * a[3] + b[2] * b[3] - inter)


def reference_groups(estimates, alive, blobs, ratio) -> np.ndarray:
    """Group membership by loops over pairs and blobs, float64 (``group_members``)."""
    boxes = [box_at(e) for e in np.asarray(estimates, np.float64)]
    num, blob_boxes = len(boxes), np.asarray(blobs.boxes, np.float64)
    out = np.zeros((num, len(blob_boxes)), bool)
    for j, (blob, real) in enumerate(zip(blob_boxes, np.asarray(blobs.mask), strict=True)):
        for m in range(num):
            for k in range(num):
                if not (real and alive[m] and alive[k] and m != k):
                    continue
                a, b = boxes[m], boxes[k]
                x0, y0 = min(a[0], b[0]), min(a[1], b[1])
                x1, y1 = max(a[0] + a[2], b[0] + b[2]), max(a[1] + a[3], b[1] + b[3])
                hull = [x0, y0, x1 - x0, y1 - y0]
                hull_iou = reference_iou(hull, blob)
                inside = all(
                    blob[0] <= c[0] + c[2] / 2 <= blob[0] + blob[2]
                    and blob[1] <= c[1] + c[3] / 2 <= blob[1] + blob[3]
                    for c in (a, b)
                )
                out[m, j] |= (
                    hull_iou >= GROUP_IOU
                    and hull_iou > max(reference_iou(a, blob), reference_iou(b, blob))
                    and max(a[2] * a[3], b[2] * b[3]) <= float(ratio) * hull[2] * hull[3]
                    and max(a[2] * a[3], b[2] * b[3]) <= float(ratio) * blob[2] * blob[3]
                    and inside
                )
    return out


def reference_probabilities(estimates, alive, zone_boxes, zone_mask, blobs, params):
    """Eqs. 6-10 by loops, float64, with the exponentials taken directly."""
    p = {k: np.asarray(v, np.float64) for k, v in params._asdict().items()}
    grouped = reference_groups(estimates, alive, blobs, p["group_area_ratio"]).any(axis=1)
    estimates = np.asarray(estimates, np.float64)
    out = np.zeros((len(estimates), 4))
    for m, (cx, vx, cy, vy, _, h) in enumerate(estimates):
        if not alive[m]:
            out[m, NORMAL] = 1.0
            continue
        d_o = [
            math.hypot(cx - estimates[j, 0], cy - estimates[j, 2]) / h
            for j in range(len(estimates))
            if alive[j] and j != m
        ]
        d_b = []
        for (x, y, w, zh), real in zip(np.asarray(zone_boxes, np.float64), zone_mask, strict=True):
            if real:
                gx = max(x - cx, 0.0, cx - x - w)
                gy = max(y - (cy + h / 2), 0.0, cy + h / 2 - y - zh)
                d_b.append(math.hypot(gx, gy))
        tilde_pair = math.exp(-min(d_o)) if d_o else 0.0
        tilde_exit = math.exp(-min(d_b) / (p["zone_scale"] * h)) if d_b else 0.0
        eps = p["normal_floor"]
        normal = min(min(d_o) / p["context_distance"], 1 - eps) if d_o else 1 - eps
        total = 2 * tilde_pair + tilde_exit
        if total == 0.0:
            normal, total = 1.0, 1.0
        row = [normal, *((1 - normal) * np.array([tilde_pair, tilde_pair, tilde_exit]) / total)]
        near = any(
            real and math.hypot(bx + bw / 2 - cx - vx, by + bh / 2 - cy - vy) <= p["blob_gate"] * h
            for (bx, by, bw, bh), real in zip(np.asarray(blobs.boxes), blobs.mask, strict=True)
        )
        if near:
            row[EXIT] *= p["exit_penalty"]
        if grouped[m]:
            row[NORMAL] *= p["group_penalty"]
            row[SPLIT] *= p["group_penalty"]
        out[m] = np.array(row) / sum(row)
    return out


def reference_log_q(new, old, probabilities, blobs, params, groups=None):
    """``log q(x | x')`` of eq. 5 by loops, float64 (module docstring of cmt_proposal); the
    blobs ``groups[k, j]`` are not near component ``k``."""
    p = {k: np.asarray(v, np.float64) for k, v in params._asdict().items()}
    new, old = np.asarray(new, np.float64), np.asarray(old, np.float64)
    boxes = np.asarray(blobs.boxes, np.float64)
    out = np.zeros(new.shape[:2])
    for k in range(new.shape[0]):
        share_blob = probabilities[k, NORMAL] + probabilities[k, SPLIT]
        for i in range(new.shape[1]):
            x, (cx, vx, cy, vy, w, h) = new[k, i], old[k, i]
            s = MOTION.astype(np.float64) * np.array([w, h, w, h])
            cv = np.prod(norm.pdf([x[1], x[3], x[4], x[5]], [vx, vy, w, h], s))
            closeness, gaussians = [], []
            for j, ((bx, by, bw, bh), real) in enumerate(zip(boxes, blobs.mask, strict=True)):
                b = np.array([bx + bw / 2, by + bh / 2, bw, bh])
                if groups is not None and groups[k, j]:
                    continue
                if not real or math.hypot(b[0] - cx - vx, b[1] - cy - vy) > p["blob_gate"] * h:
                    continue
                pred = np.array([cx + vx, cy + vy, w, h])
                prior_precision = 1 / (s * [0.5, 0.5, 1, 1]) ** 2
                blob_precision = 1 / (p["blob_spread"] * np.array([bw, bh, bw, bh])) ** 2
                var = 1 / (prior_precision + blob_precision)
                mean = var * (prior_precision * pred + blob_precision * b)
                closeness.append(
                    np.prod(norm.pdf(b, pred, np.sqrt(1 / prior_precision + 1 / blob_precision)))
                )
                gaussians.append(np.prod(norm.pdf(x[[0, 2, 4, 5]], mean, np.sqrt(var))) / 4)
            if closeness:
                c = np.array(closeness) / sum(closeness)
                beta = p["defensive_weight"]
                blob_driven = beta * cv + (1 - beta) * np.dot(c, gaussians)
            else:
                blob_driven = cv
            out[k, i] = np.log(share_blob * blob_driven + probabilities[k, MERGE] * cv)
    return out


def pair_box(first, second, pad=2.0) -> list[float]:
    """The bounding box of two states' CV prediction boxes, grown by ``pad`` on each side."""
    a, b = box_at(first), box_at(second)
    x0, y0 = min(a[0], b[0]) - pad, min(a[1], b[1]) - pad
    x1, y1 = max(a[0] + a[2], b[0] + b[2]) + pad, max(a[1] + a[3], b[1] + b[3]) + pad
    return [x0, y0, x1 - x0, y1 - y0]


ESTIMATES = np.array(
    [
        [100.0, 2.0, 200.0, 1.0, 40.0, 100.0],
        [160.0, 0.0, 210.0, 0.0, 40.0, 90.0],
        [500.0, -3.0, 260.0, 0.0, 30.0, 80.0],
        [300.0, 0.0, 300.0, 0.0, 40.0, 100.0],
    ],
    np.float32,
)
ZONES = (np.array([[0.0, 240.0, 60.0, 80.0], [0.0, 0.0, 5.0, 5.0]], np.float32), [True, False])


@pytest.mark.parametrize(
    ("alive", "zones", "blob_boxes", "expected"),
    [
        # a lone component without zones: no context, normal only
        ([True, False, False, False], NO_ZONE, [], [1.0, 0.0, 0.0, 0.0]),
        # a lone component with a zone: eps goes to exit (eq. 8), whatever the distance
        ([False, False, True, False], ZONES, [], [0.95, 0.0, 0.0, 0.05]),
        # two close components, no zone: normal = d / d_thr, the rest split = merge
        ([True, True, False, False], NO_ZONE, [], None),
        # near a zone and a neighbour; a far one alive too
        ([True, True, True, True], ZONES, [], None),
        # blob at component 0's prediction: its exit penalised; padded blob ignored
        ([True, True, True, True], ZONES, "at0", None),
        # one blob over components 0 and 1 together: their normal and split penalised
        ([True, True, True, True], ZONES, "group", None),
        ([True, True, False, False], NO_ZONE, "group", None),
    ],
)
def test_condition_probabilities_match_a_loop(alive, zones, blob_boxes, expected):
    alive = np.array(alive)
    params = PARAMS
    if blob_boxes == "at0":
        blobs = blobs_of([box_at(ESTIMATES[0], 3.0), box_at(ESTIMATES[2])], [True, False])
    elif blob_boxes == "group":
        blobs = blobs_of([pair_box(ESTIMATES[0], ESTIMATES[1]), box_at(ESTIMATES[2])])
        params = GROUPED
        assert reference_groups(ESTIMATES, alive, blobs, 0.6)[:2, 0].all()
    else:
        blobs = blobs_of(np.zeros((2, 4)), [False, False])
    got = probabilities_of(
        jnp.asarray(ESTIMATES),
        jnp.asarray(alive),
        jnp.asarray(zones[0]),
        jnp.asarray(zones[1]),
        blobs,
        params,
    )
    want = reference_probabilities(ESTIMATES, alive, zones[0], zones[1], blobs, params)
    np.testing.assert_allclose(got, want, atol=1e-6)
    np.testing.assert_allclose(np.sum(got, axis=1), 1.0, atol=1e-6)
    if expected is not None:
        np.testing.assert_allclose(got[np.flatnonzero(alive)[0]], expected, atol=1e-6)


def test_blob_penalises_exit_and_the_pair_share_grows_when_close():
    alive = jnp.ones(4, bool)
    zones = (jnp.asarray(ZONES[0]), jnp.asarray(ZONES[1]))
    none = blobs_of(np.zeros((2, 4)), [False, False])
    blob = blobs_of([box_at(ESTIMATES[0]), box_at(ESTIMATES[0])], [True, False])
    without = probabilities_of(jnp.asarray(ESTIMATES), alive, *zones, none, PARAMS)
    with_blob = probabilities_of(jnp.asarray(ESTIMATES), alive, *zones, blob, PARAMS)
    assert float(with_blob[0, EXIT]) < 0.2 * float(without[0, EXIT])
    np.testing.assert_allclose(with_blob[2:], without[2:])  # components 2, 3: no blob near
    closer = ESTIMATES.copy()
    closer[1, 0] = 120.0
    near = probabilities_of(jnp.asarray(closer), alive, *zones, none, PARAMS)
    assert float(near[0, NORMAL]) < float(without[0, NORMAL])
    assert float(near[0, SPLIT]) > float(without[0, SPLIT])


@pytest.mark.parametrize(
    ("case", "members"),
    [
        # two targets side by side under one box: both members
        ("pair", [True, True, False]),
        # the blob is component 0's own box: no group
        ("own", [False, False, False]),
        # a small second component inside component 0's box, the blob that box: no group
        ("inside", [False, False, False]),
        # the pair's box, but component 1 dead: no group
        ("dead", [False, False, False]),
        # the pair's box with group blobs turned off (ratio 0): no group
        ("off", [False, False, False]),
    ],
)
def test_group_members_match_a_loop(case, members):
    estimates = ESTIMATES[:3].copy()
    alive = np.array([True, case != "dead", True])
    ratio = 0.0 if case == "off" else 0.6
    if case == "inside":
        estimates[1] = [101.0, 2.0, 195.0, 1.0, 20.0, 50.0]
    box = box_at(estimates[0]) if case in ("own", "inside") else pair_box(*estimates[:2])
    blobs = blobs_of([box, box_at(estimates[2]), box], [True, True, False])
    got = group_members(
        cv_prediction(estimates),
        jnp.asarray(alive),
        blobs,
        jnp.float32(ratio),
    )
    want = reference_groups(estimates, alive, blobs, ratio)
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(np.asarray(got)[:, 0], members)
    assert not np.asarray(got)[:, 1:].any()


def test_a_group_member_draws_its_particles_from_the_transition_not_the_group_blob():
    # Only blob: one box over components 0 and 1. As members (ratio 0.6) all their draws
    # come from the CV transition, ``q = (1 - q(exit)) p_cv``; without groups (ratio 0) the
    # normal and split draws come from the blob-driven mixture, and ``q`` differs.
    particles, estimates, alive, _, zone_boxes, zone_mask = scene(64, 4)
    blobs = blobs_of([pair_box(ESTIMATES[0], ESTIMATES[1])])
    gaps, merges = {}, {}
    for ratio in (0.0, 0.6):
        params = PARAMS._replace(group_area_ratio=jnp.float32(ratio))
        draw = propose(
            jax.random.key(5), particles, estimates, alive, blobs, zone_boxes, zone_mask, params
        )
        kept = ~np.asarray(draw.exited)[:2]
        transition = (
            np.log1p(-np.asarray(draw.probabilities)[:2, EXIT, None])
            + np.asarray(log_cv(draw.particles, particles, jnp.asarray(MOTION)))[:2]
        )
        gaps[ratio] = np.abs(np.asarray(draw.log_q)[:2] - transition)[kept]
        merges[ratio] = np.asarray(draw.probabilities)[:2, MERGE]
    assert gaps[0.6].max() < 1e-3
    assert np.median(gaps[0.0]) > 0.02  # 20x the members' tolerance
    assert np.all(merges[0.6] > 2 * merges[0.0])


def scene(num_particles: int, seed: int):
    """Three components (one dead) with particles around them, blobs near two, one zone."""
    rng = np.random.default_rng(seed)
    estimates = ESTIMATES[:3]
    particles = estimates[:, None] + rng.normal(size=(3, num_particles, 6)) * [3, 1, 3, 1, 2, 4]
    blobs = blobs_of(
        [
            box_at(estimates[0], 4.0, -5.0),
            box_at(estimates[0], -15.0),
            box_at(estimates[1], 2.0),
            box_at(estimates[2], 500.0),
            box_at(estimates[1]),
        ],
        [True, True, True, True, False],
    )
    alive = jnp.array([True, True, False])
    return (
        jnp.asarray(particles, jnp.float32),
        jnp.asarray(estimates),
        alive,
        blobs,
        jnp.asarray(ZONES[0]),
        jnp.asarray(ZONES[1]),
    )


@pytest.mark.parametrize(("seed", "group"), [(0, False), (1, False), (2, True)])
def test_log_q_matches_a_loop_of_the_mixture_density(seed, group):
    particles, estimates, alive, blobs, zone_boxes, zone_mask = scene(32, seed)
    groups = None
    if group:  # the padded slot becomes one blob over components 0 and 1 together
        boxes = np.asarray(blobs.boxes).copy()
        boxes[4] = pair_box(ESTIMATES[0], ESTIMATES[1])
        blobs = blobs_of(boxes)
        groups = reference_groups(estimates, np.asarray(alive), blobs, 0.6)
        assert groups[:2, 4].all() and groups.sum() == 2
        got = group_members(
            cv_prediction(estimates),
            alive,
            blobs,
            GROUPED.group_area_ratio,
        )
        np.testing.assert_array_equal(got, groups)
    params = (GROUPED if group else PARAMS)._replace(
        blob_gate=jnp.asarray(0.5), defensive_weight=jnp.asarray(0.3), exit_penalty=jnp.asarray(0.5)
    )
    draw = propose(
        jax.random.key(seed), particles, estimates, alive, blobs, zone_boxes, zone_mask, params
    )
    probabilities = reference_probabilities(
        estimates, np.asarray(alive), zone_boxes, np.asarray(zone_mask), blobs, params
    )
    np.testing.assert_allclose(draw.probabilities, probabilities, atol=1e-6)
    want = reference_log_q(draw.particles, particles, probabilities, blobs, params, groups)
    np.testing.assert_allclose(draw.log_q, want, rtol=1e-5, atol=1e-3)
    conditions = np.asarray(draw.conditions)
    assert set(np.unique(conditions[:2])) == {NORMAL, SPLIT, MERGE, EXIT}
    assert np.all(conditions[2] == NORMAL)
    np.testing.assert_array_equal(draw.exited, conditions == EXIT)


def test_constant_velocity_density_is_the_mixture_transition():
    particles, *_ = scene(32, 3)
    new = particles + jax.random.normal(jax.random.key(1), particles.shape)
    mixture = MixtureParams(
        motion_noise_std=jnp.asarray(MOTION),
        measurement_noise_std=jnp.ones(4),
        background_log_likelihood=jnp.zeros(()),
        min_mixture_weight=jnp.zeros(()),
        min_log_support=jnp.zeros(()),
        birth_log_likelihood=jnp.zeros(()),
    )
    np.testing.assert_allclose(
        log_cv(new, particles, jnp.asarray(MOTION)),
        jax.jit(log_transition)(new, particles, mixture),
        rtol=1e-6,
    )


def test_importance_weights_recover_the_transition_moments():
    """``mean(p / q f 1{no exit}) = (1 - q(exit)) E_p[f]`` (exact log q in the weights)."""
    num = 20_000
    motion = jnp.asarray([0.3, 0.3, 0.05, 0.05])  # a broad prior: q differs from it
    _, estimates, _, _, zone_boxes, zone_mask = scene(1, 0)
    alive = jnp.array([True, True, False])
    old = jnp.repeat(estimates[:, None], num, axis=1)
    blobs = blobs_of([box_at(estimates[0], 3.0, -4.0), box_at(estimates[1], -2.0, 5.0)])
    draw = jax.jit(contextual_proposal)(
        jax.random.key(7), old, estimates, alive, PARAMS, motion, blobs, zone_boxes, zone_mask
    )
    log_p = log_cv(draw.particles, old, motion)
    weights = np.exp(np.asarray(log_p - draw.log_q, np.float64)) * ~np.asarray(draw.exited)
    new = np.asarray(draw.particles, np.float64)
    for k in range(2):
        keep = 1.0 - float(draw.probabilities[k, EXIT])
        exits = np.asarray(draw.exited[k], np.float64)
        assert abs(exits.mean() - (1 - keep)) < 4 * math.sqrt(keep * (1 - keep) / num)
        state = np.asarray(estimates[k], np.float64)
        width, height = state[4], state[5]
        shift = abs(np.mean(new[k, :, 3]) - state[3]) / np.std(new[k, :, 3]) * math.sqrt(num)
        assert shift > 20  # the blobs pull the unweighted draws away from the prior
        moments = {
            "one": (np.ones(num), 1.0),
            "vx": (new[k, :, 1], state[1]),
            "vy": (new[k, :, 3], state[3]),
            "vy above": (new[k, :, 3] > state[3], 0.5),
            "h": (new[k, :, 5], height),
            "w^2": (new[k, :, 4] ** 2, width**2 + (float(motion[2]) * width) ** 2),
        }
        for name, (values, expected) in moments.items():
            terms = weights[k] * values
            error = np.std(terms) / math.sqrt(num)
            assert abs(np.mean(terms) - keep * expected) < 4 * error + 1e-9, name


def test_with_a_broad_prior_blob_driven_draws_concentrate_on_the_near_blob():
    num = 4000
    motion = jnp.asarray([0.3, 0.3, 0.05, 0.05])
    state = np.array([200.0, 3.0, 150.0, -2.0, 40.0, 100.0], np.float32)
    old = jnp.broadcast_to(jnp.asarray(state), (1, num, 6))
    blobs = blobs_of([box_at(state, 60.0), box_at(state, 6.0, -8.0)])
    params = PARAMS._replace(defensive_weight=jnp.asarray(0.0), blob_spread=jnp.full(4, 0.05))
    draw = jax.jit(contextual_proposal)(
        jax.random.key(2), old, old[:, 0], jnp.array([True]), params, motion, blobs, *NO_ZONE
    )
    np.testing.assert_array_equal(draw.conditions, NORMAL)
    new = np.asarray(draw.particles[0], np.float64)
    blob = np.array([203.0 + 6.0, 148.0 - 8.0, 40.0, 100.0])
    prior_var = (np.asarray(motion) * [40.0, 100.0, 40.0, 100.0] * [0.5, 0.5, 1, 1]) ** 2
    blob_var = (0.05 * np.array([40.0, 100.0, 40.0, 100.0])) ** 2
    std = np.sqrt(prior_var * blob_var / (prior_var + blob_var))
    mean = blob + (np.array([203.0, 148.0, 40.0, 100.0]) - blob) * blob_var / (prior_var + blob_var)
    assert np.all(np.abs(mean - blob) < np.sqrt(blob_var))  # the blob dominates the prior
    measured = new[:, [0, 2, 4, 5]]
    assert np.all(np.abs(measured - mean) < 5 * std)  # never the other blob
    np.testing.assert_allclose(measured.mean(0), mean, atol=4 * std.max() / math.sqrt(num))
    np.testing.assert_allclose(measured.std(0), std, rtol=0.05)
    np.testing.assert_allclose(new[:, 1], 2 * (new[:, 0] - 200.0) - 3.0, atol=1e-3)


def test_without_a_near_blob_the_proposal_is_the_transition_less_the_exits():
    particles, estimates, alive, blobs, zone_boxes, zone_mask = scene(32, 4)
    blobs = blobs._replace(boxes=blobs.boxes.at[:, 1].add(400.0))
    draw = propose(jax.random.key(3), particles, estimates, alive, blobs, zone_boxes, zone_mask)
    log_transition_cv = log_cv(draw.particles, particles, jnp.asarray(MOTION))
    keep = 1.0 - np.asarray(draw.probabilities[:, EXIT])
    np.testing.assert_allclose(
        draw.log_q, log_transition_cv + np.log(keep)[:, None], rtol=1e-6, atol=1e-5
    )
    assert np.all(keep[:2] < 0.99)  # the exits are taken out of q


def test_padded_blobs_are_ignored():
    particles, estimates, alive, blobs, zone_boxes, zone_mask = scene(32, 5)
    moved = blobs._replace(boxes=blobs.boxes.at[-1].set(jnp.asarray(box_at(ESTIMATES[0]))))
    first = propose(jax.random.key(4), particles, estimates, alive, blobs, zone_boxes, zone_mask)
    second = propose(jax.random.key(4), particles, estimates, alive, moved, zone_boxes, zone_mask)
    for a, b in zip(first, second, strict=True):
        np.testing.assert_array_equal(a, b)


def test_jit_equals_eager_and_vmap_over_params_equals_a_loop():
    inputs = scene(32, 6)
    key = jax.random.key(5)
    eager = eager_propose(key, *inputs)
    jitted = propose(key, *inputs)
    for a, b in zip(eager, jitted, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-4)
    sweep = [
        PARAMS,
        PARAMS._replace(context_distance=jnp.asarray(3.0), defensive_weight=jnp.asarray(0.5)),
    ]
    stacked = jax.tree.map(lambda *leaves: jnp.stack(leaves), *sweep)
    batched = jax.jit(jax.vmap(functools.partial(eager_propose, key, *inputs)))(stacked)
    for i, params in enumerate(sweep):
        single = propose(key, *inputs, params)
        for a, b in zip(single, batched, strict=True):
            np.testing.assert_allclose(a, b[i], rtol=1e-5, atol=1e-4)


def test_gradients_wrt_continuous_params_are_finite():
    particles, estimates, *rest = scene(32, 7)
    inputs = (particles, estimates.at[2].set(0.0), *rest)  # a dead slot holding zeros

    def objective(params: CPDParams):
        draw = propose(jax.random.key(6), *inputs, params)
        return jnp.sum(draw.log_q) + jnp.sum(draw.probabilities * jnp.arange(4.0))

    grads = jax.jit(jax.grad(objective))(PARAMS)
    for name, value in grads._asdict().items():
        assert np.all(np.isfinite(value)), name
    for name in ("context_distance", "zone_scale", "blob_spread", "defensive_weight"):
        assert np.any(np.asarray(getattr(grads, name)) != 0.0), name


@pytest.mark.parametrize("name", ["context_distance", "zone_scale", "exit_penalty"])
def test_gradients_of_the_condition_probabilities_equal_finite_differences(name):
    _, estimates, _, blobs, zone_boxes, zone_mask = scene(32, 8)
    alive = jnp.array([True, True, True])

    def objective(value):
        params = PARAMS._replace(**{name: value})
        probabilities = probabilities_of(estimates, alive, zone_boxes, zone_mask, blobs, params)
        return jnp.sum(probabilities * jnp.arange(4.0))

    value = getattr(PARAMS, name)
    step = 1e-2 * value
    numeric = (objective(value + step) - objective(value - step)) / (2 * step)
    analytic = jax.grad(objective)(value)
    assert abs(float(analytic)) > 1e-3
    np.testing.assert_allclose(analytic, numeric, rtol=2e-2)
