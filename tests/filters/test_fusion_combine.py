"""Fusion of pool responses: analytic cases, eq. 6 by a pairwise NumPy loop, vmap == loop."""

from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.filters.fusion_combine import (
    accordance,
    confidence,
    fuse,
    fusion_weights,
    naive_weights,
    speed_similarity,
)


@pytest.fixture(autouse=True)
def _float64():
    """Float64 so that tolerances reflect the formulas, not float32 rounding."""
    with jax.enable_x64(True):
        yield


def _eq6_loop(confidences, accordances, valid, responses):
    """Fusion eq. 6 literally: a loop over the valid pairs i < j with S_i + S_j > 0."""
    total, a_sum = np.zeros(responses.shape[1:]), 0.0
    for i, j in itertools.combinations(range(len(confidences)), 2):
        s_i, s_j = confidences[i], confidences[j]
        if not (valid[i] and valid[j]) or s_i + s_j == 0:
            continue
        total = total + accordances[i, j] * (s_i * responses[i] + s_j * responses[j]) / (s_i + s_j)
        a_sum += accordances[i, j]
    if a_sum == 0:
        return responses[valid].mean(axis=0)
    return total / a_sum


def _random_pool(rng, num_members, response_shape):
    confidences = rng.uniform(0.0, 1.0, num_members)
    a = rng.uniform(0.0, 1.0, (num_members, num_members))
    valid = rng.random(num_members) < 0.8
    valid[rng.integers(num_members)] = True
    responses = rng.normal(size=(num_members, *response_shape))
    return confidences, (a + a.T) / 2, valid, responses


def test_speed_similarity_analytic():
    past, valid = jnp.array([2.0, 2.0, 2.0, 100.0]), jnp.array([True, True, True, False])
    assert float(speed_similarity(past, valid, jnp.array(1.0))) == pytest.approx(0.5)
    assert float(speed_similarity(past, valid, jnp.array(4.0))) == pytest.approx(0.5)
    assert float(speed_similarity(past, valid, jnp.array(2.0))) == pytest.approx(1.0)
    assert float(speed_similarity(past, ~valid, jnp.array(50.0))) == pytest.approx(0.5)
    assert float(speed_similarity(past, valid & False, jnp.array(3.0))) == 1.0  # no history
    zero = jnp.zeros(4)
    assert float(speed_similarity(zero, valid, jnp.array(0.0))) == 1.0  # standing still
    assert float(speed_similarity(zero, valid, jnp.array(3.0))) == 0.0
    assert float(confidence(jnp.array(0.5), jnp.array(0.9))) == pytest.approx(0.7)


def test_accordance_analytic_and_symmetric():
    boxes = jnp.array([[0.0, 0.0, 50.0, 100.0], [100.0, 0.0, 50.0, 100.0], [0.0, 0.0, 50.0, 100.0]])
    app = jnp.array([[1.0, 0.4, 1.0], [0.4, 1.0, 0.4], [1.0, 0.4, 1.0]])
    a = np.asarray(accordance(boxes, app))
    assert a[0, 2] == pytest.approx(1.0)  # same box, same look
    assert a[0, 1] == pytest.approx((np.exp(-1.0) + 0.0 + 0.4) / 3)  # 100 px apart, h = 100
    rng = np.random.default_rng(3)
    boxes = np.concatenate([rng.uniform(0, 200, (6, 2)), rng.uniform(20, 80, (6, 2))], axis=1)
    app = rng.uniform(0, 1, (6, 6))
    a = np.asarray(accordance(jnp.asarray(boxes), jnp.asarray((app + app.T) / 2)))
    np.testing.assert_allclose(a, a.T, rtol=1e-12)
    assert np.all((a >= 0) & (a <= 1))
    # the overlap cue is the IoU: two boxes half covering each other (IoU 1/3), same centre
    # height: exp(-25 / 100)
    pair = jnp.array([[0.0, 0.0, 50.0, 100.0], [25.0, 0.0, 50.0, 100.0]])
    a = accordance(pair, jnp.zeros((2, 2)))
    assert float(a[0, 1]) == pytest.approx((np.exp(-0.25) + 1 / 3) / 3)


def test_identical_members_fuse_to_that_member():
    box = jnp.array([10.0, 20.0, 30.0, 60.0])
    responses = jnp.stack([box, box, box])
    weights = fusion_weights(jnp.array([0.2, 0.9, 0.5]), jnp.full((3, 3), 0.7), jnp.ones(3, bool))
    np.testing.assert_allclose(fuse(weights, responses), box, rtol=1e-12)
    assert float(jnp.sum(weights)) == pytest.approx(1.0)


def test_zero_confidence_member_is_ignored():
    rng = np.random.default_rng(4)
    confidences, a, _, responses = _random_pool(rng, 4, (4,))
    confidences[2] = 0.0
    valid = np.ones(4, bool)
    weights = fusion_weights(jnp.asarray(confidences), jnp.asarray(a), jnp.asarray(valid))
    assert float(weights[2]) == 0.0
    moved = responses.copy()
    moved[2] += 1000.0
    np.testing.assert_allclose(fuse(weights, moved), fuse(weights, responses), rtol=1e-12)
    # two members, one with S = 0: the other alone
    pair = fusion_weights(jnp.array([0.0, 0.6]), jnp.full((2, 2), 0.5), jnp.ones(2, bool))
    np.testing.assert_allclose(pair, [0.0, 1.0])


def test_pool_of_one_and_all_zero_confidence():
    responses = jnp.arange(12.0).reshape(3, 4)
    one = fusion_weights(jnp.array([0.3, 0.8, 0.9]), jnp.ones((3, 3)), jnp.array([0, 1, 0], bool))
    np.testing.assert_allclose(fuse(one, responses), responses[1])
    zero = fusion_weights(jnp.zeros(3), jnp.ones((3, 3)), jnp.ones(3, bool))
    np.testing.assert_allclose(fuse(zero, responses), responses.mean(axis=0))
    naive = naive_weights(jnp.array([1, 0, 1], bool))
    np.testing.assert_allclose(fuse(naive, responses), (responses[0] + responses[2]) / 2)


def test_symmetric_pair_gives_confidence_weighted_mean():
    weights = fusion_weights(jnp.array([0.25, 0.75]), jnp.full((2, 2), 0.3), jnp.ones(2, bool))
    np.testing.assert_allclose(weights, [0.25, 0.75], rtol=1e-12)


@pytest.mark.parametrize("response_shape", [(4,), (6, 5)])
def test_fusion_matches_eq6_loop(response_shape):
    rng = np.random.default_rng(5)
    for _ in range(30):
        confidences, a, valid, responses = _random_pool(rng, 5, response_shape)
        confidences[rng.random(5) < 0.2] = 0.0
        weights = fusion_weights(jnp.asarray(confidences), jnp.asarray(a), jnp.asarray(valid))
        np.testing.assert_allclose(
            fuse(weights, jnp.asarray(responses)),
            _eq6_loop(confidences, a, valid, responses),
            rtol=1e-10,
            atol=1e-12,
        )


def test_vmap_over_targets_equals_loop_and_jit_equals_eager():
    rng = np.random.default_rng(6)
    pools = [_random_pool(rng, 3, (4,)) for _ in range(7)]
    s, a, v, r = (jnp.asarray(np.stack(parts)) for parts in zip(*pools, strict=True))
    boxes = jnp.asarray(rng.uniform(10, 90, (7, 3, 4)))

    def fused(s, a, v, r, boxes):
        acc = accordance(boxes, a)
        return fuse(fusion_weights(s, acc, v), r)

    batched = jax.vmap(fused)(s, a, v, r, boxes)
    looped = jnp.stack([fused(s[t], a[t], v[t], r[t], boxes[t]) for t in range(7)])
    np.testing.assert_allclose(batched, looped, rtol=1e-12)
    np.testing.assert_allclose(jax.jit(jax.vmap(fused))(s, a, v, r, boxes), batched, rtol=1e-12)
    past = jnp.asarray(rng.uniform(0, 5, (7, 4)))
    past_valid = jnp.asarray(rng.random((7, 4)) < 0.7)
    now = jnp.asarray(rng.uniform(0, 5, 7))
    speeds = jax.vmap(speed_similarity)(past, past_valid, now)
    for t in range(7):
        history = np.asarray(past[t])[np.asarray(past_valid[t])]
        mean = history.mean() if history.size else float(now[t])
        expected = min(mean, float(now[t])) / max(mean, float(now[t]))
        assert float(speeds[t]) == pytest.approx(expected, rel=1e-12)
