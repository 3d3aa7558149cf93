"""Collins' variance ratio on constructed target/background pairs; the M + N feature pool."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.appearance import init_pool, log_likelihood_ratio, select_features, variance_ratio
from jaxtrack.errors import InputError

RNG = np.random.default_rng(8)
DELTA = 1e-3


def _collins(p, q, delta):
    """VR(L; p, q) = var(L; (p + q) / 2) / (var(L; p) + var(L; q)), Collins et al. 2005."""
    ratio = np.log(np.maximum(p, delta) / np.maximum(q, delta))

    def var(a):
        return np.sum(a * ratio**2) - np.sum(a * ratio) ** 2

    return var((p + q) / 2) / (var(p) + var(q))


def _gaussian_histogram(centre, width, bins=64):
    h = np.exp(-0.5 * ((np.arange(bins) - centre) / width) ** 2)
    return h / h.sum()


def test_variance_ratio_matches_definition():
    p = RNG.dirichlet(np.ones(32), 10)
    q = RNG.dirichlet(np.ones(32), 10)
    expected = [_collins(a, b, DELTA) for a, b in zip(p, q, strict=True)]
    np.testing.assert_allclose(variance_ratio(p, q, DELTA), expected, rtol=1e-4)
    np.testing.assert_allclose(
        log_likelihood_ratio(p, q, DELTA),
        np.log(np.maximum(p, DELTA) / np.maximum(q, DELTA)),
        rtol=1e-5,
    )


def test_constructed_pairs_rank_by_separability():
    target = _gaussian_histogram(20, 3)
    pairs = {
        "perfect": (np.eye(64)[5], np.eye(64)[40]),  # disjoint one-hot: both variances 0
        "far": (target, _gaussian_histogram(40, 3)),
        "near": (target, _gaussian_histogram(26, 3)),
        "identical": (target, target),
    }
    p = np.stack([a for a, _ in pairs.values()])
    q = np.stack([b for _, b in pairs.values()])
    ratios = np.asarray(jax.jit(variance_ratio, static_argnums=2)(p, q, DELTA))
    assert ratios[0] > ratios[1] > ratios[2] > ratios[3]
    assert ratios[3] == 0.0  # L = 0 everywhere: 0, not 0/0
    assert ratios[0] == pytest.approx(np.log(1 / DELTA) ** 2 / 1e-6, rel=1e-3)
    assert ratios[1] == pytest.approx(_collins(*pairs["far"], DELTA), rel=1e-4)
    assert np.all(np.isfinite(ratios))


def _select_loop(ratio_history, m, n):
    wins = np.zeros(ratio_history.shape[1])
    selections = []
    for ratios in ratio_history:
        current = list(np.argsort(-ratios, kind="stable")[:m])
        wins[current] += 1
        rest = [k for k in range(len(ratios)) if k not in current]
        rest.sort(key=lambda k: (-wins[k], -ratios[k]))
        selections.append(current + rest[:n])
    return wins, selections


def test_select_features_matches_loop():
    frames, features, m, n = 12, 10, 3, 2
    # Distinct ratios; features 0-2 are strong in early frames only, so that the long-run
    # choice differs from the current one.
    history = RNG.permutation(frames * features).reshape(frames, features) / 10.0
    history[:6, :3] += 100.0
    wins, selections = _select_loop(history, m, n)
    pool = init_pool(features)
    select = jax.jit(select_features, static_argnums=(2, 3))
    for t in range(frames):
        pool, selected = select(pool, jnp.asarray(history[t], jnp.float32), m, n)
        assert list(np.asarray(selected)) == selections[t]
    np.testing.assert_array_equal(pool.wins, wins)


def test_select_features_refuses_impossible_sizes():
    with pytest.raises(InputError, match="long-run"):
        select_features(init_pool(5), jnp.zeros(5), 4, 2)
    with pytest.raises(InputError, match="long-run"):
        select_features(init_pool(5), jnp.zeros(5), 0, 2)
