"""The held-out selection of the shares and the learner's setting (jaxtrack.context.heldout).

Oracles: an independent EM on the mixing weights of fixed component densities (the classic
fixed point ``pi_k = mean_i r_ik``), analytic densities, and synthetic events with known
structure (a tight zone: the learned density must win; events uniform over the volume: the
learned density must fall back to uniform).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.stats import multivariate_normal

from jaxtrack.context.heldout import (
    Candidate,
    HeldOut,
    combine,
    log_gaussian_part,
    log_uniform,
    select_density,
    select_shares,
    time_folds,
)
from jaxtrack.context.intensity import log_density
from jaxtrack.context.map_em import grid_init_clutter, init_state, to_intensity

CANDIDATES = (Candidate(3, 1.0), Candidate(1, 1.0))


def test_time_folds_are_contiguous_equal_blocks_keeping_frames_together():
    frames = np.array([9, 1, 2, 2, 3, 4, 5, 6, 7, 8, 10, 11])
    folds = time_folds(frames, 4)
    order = np.argsort(frames, kind="stable")
    assert np.all(np.diff(folds[order]) >= 0)  # later events never in an earlier fold
    assert folds[2] == folds[3]  # the two events of frame 2
    assert sorted(np.bincount(folds)) == [3, 3, 3, 3]
    with pytest.raises(ValueError):
        time_folds(frames[:3], 4)


def _em_weights(log_densities, iterations=5000):
    """Oracle: EM for the mixing weights of fixed densities ``[components, n]``."""
    weights = np.full(log_densities.shape[0], 1.0 / log_densities.shape[0])
    for _ in range(iterations):
        joint = np.log(weights)[:, None] + log_densities
        resp = np.exp(joint - np.logaddexp.reduce(joint, axis=0))
        weights = resp.mean(axis=1)
    return weights


def test_shares_match_an_em_oracle_on_fixed_densities():
    rng = np.random.default_rng(0)
    n = 3000
    # 1-D: u = U[0, 10]; g = N(2, 0.5); b = N(7, 1.5); true weights 0.3 / 0.5 / 0.2
    kind = rng.choice(3, size=n, p=[0.3, 0.5, 0.2])
    x = np.where(
        kind == 0,
        rng.uniform(0, 10, n),
        np.where(kind == 1, rng.normal(2, 0.5, n), rng.normal(7, 1.5, n)),
    )

    def log_normal(v, mean, std):
        return -0.5 * ((v - mean) / std) ** 2 - np.log(std * np.sqrt(2 * np.pi))

    log_u = -np.log(10.0)
    log_g, log_b = log_normal(x, 2, 0.5), log_normal(x, 7, 1.5)
    pi_u, pi_b, _, loglik = select_shares(log_g, log_b, log_u, prior_events=0.0, grid_size=120)
    oracle = _em_weights(np.stack([np.full(n, log_u), log_b, log_g]))
    assert pi_u == pytest.approx(oracle[0], abs=0.03)
    assert pi_b == pytest.approx(oracle[1], abs=0.03)
    assert abs(oracle[0] - 0.3) < 0.1 and abs(oracle[1] - 0.2) < 0.1  # sanity: near the truth
    best = np.logaddexp.reduce(
        np.stack(
            [
                np.full(n, np.log(oracle[0]) + log_u),
                np.log(oracle[1]) + log_b,
                np.log(oracle[2]) + log_g,
            ]
        ),
        axis=0,
    ).mean()
    assert loglik == pytest.approx(best, abs=2e-3)  # the grid's optimum is the EM optimum


def test_a_density_worse_than_uniform_falls_back_to_uniform():
    rng = np.random.default_rng(1)
    x = rng.uniform(0, 10, 200)
    log_u = -np.log(10.0)
    log_g = -0.5 * ((x - 2) / 0.3) ** 2 - np.log(0.3 * np.sqrt(2 * np.pi))  # wrong and sharp
    pi_u, pi_b, _, loglik = select_shares(log_g, np.full(200, -np.inf), log_u)
    assert pi_u == 1.0 and pi_b == 0.0
    assert loglik == pytest.approx(log_u)


def _volume_events(rng, n, zone):
    """4-D events ``(y1, y2, w, h)`` over a 640x480 image: in one tight zone or uniform."""
    if zone:
        centre = rng.normal([200, 150, 30, 80], [4, 4, 2, 4], (n, 4))
        return centre
    return rng.uniform([0, 0, 1, 1], [640, 480, 640, 480], (n, 4))


@pytest.fixture(scope="module")
def grids():
    grid = grid_init_clutter(640, 480, (30, 80), size_range=((1, 1), (640, 480)))
    background = grid_init_clutter(640, 480, (30, 80), grid=(8, 7), size_range=((1, 1), (640, 480)))
    return grid, background


@pytest.mark.parametrize("zone", [True, False])
def test_select_density_wins_on_a_zone_and_falls_back_on_uniform_events(grids, zone):
    grid, background = grids
    rng = np.random.default_rng(2)
    n = 240
    events = _volume_events(rng, n, zone)
    frames = np.sort(rng.integers(1, 300, n))
    candidate, held = select_density(
        grid, background, events, frames, jax.random.PRNGKey(0), CANDIDATES
    )
    assert candidate in CANDIDATES and held.num_folds == 4
    assert held.uniform == pytest.approx(log_uniform(grid))
    if zone:  # plenty of evidence for one place: the paper's density, no fall-back mass
        assert held.uniform_weight + held.background_weight < 0.05
        assert held.gain > 5.0
    else:  # events spread over the whole volume: nothing beats the uniform
        assert held.uniform_weight > 0.9
        assert held.gain == pytest.approx(0.0, abs=0.05)


def test_too_few_events_give_the_background_density(grids):
    grid, background = grids
    events = _volume_events(np.random.default_rng(3), 5, True)
    _, held = select_density(
        grid, background, events, np.arange(5), jax.random.PRNGKey(0), CANDIDATES
    )
    assert held == HeldOut(1e-3, 1 - 1e-3, held.uniform, held.uniform, 0, (), 0)


def _log_mixture(state, points):
    """Oracle: ``log sum_m pi_m N(x; mu_m, Sigma_m)`` with SciPy's Gaussian density."""
    densities = [
        weight * multivariate_normal(np.asarray(mean), np.asarray(cov)).pdf(np.asarray(points))
        for weight, mean, cov in zip(state.weights, state.means, state.covs, strict=True)
    ]
    return np.log(np.sum(densities, axis=0))


def test_gaussian_part_matches_a_scipy_oracle(grids):
    grid, _ = grids
    points = _volume_events(np.random.default_rng(5), 40, zone=True)
    got = np.asarray(log_gaussian_part(grid, jnp.asarray(points, jnp.float32)))
    np.testing.assert_allclose(got, _log_mixture(grid, points), rtol=1e-4)


def test_combine_is_the_three_part_mixture():
    lower, upper = np.zeros(2), np.array([10.0, 8.0])
    learned = init_state(
        np.array([[2.0, 2.0], [6.0, 5.0]]),
        np.stack([np.eye(2)] * 2),
        lower,
        upper,
        weights=np.array([0.25, 0.75]),
        dtype=jnp.float64,
    )
    background = init_state(
        np.array([[5.0, 4.0]]), 9.0 * np.eye(2)[None], lower, upper, dtype=jnp.float64
    )
    held = HeldOut(0.2, 0.3, 0.0, 0.0, 0, (0.0,), 4)
    combined = combine(learned, background, held)
    points = jnp.asarray(np.random.default_rng(4).uniform(0, 8, (50, 2)))
    got = np.asarray(log_density(to_intensity(combined, 1.0), points))
    parts = np.stack(
        [
            np.full(50, np.log(0.2) + log_uniform(learned)),
            np.log(0.3) + _log_mixture(background, points),
            np.log(0.5) + _log_mixture(learned, points),
        ]
    )
    np.testing.assert_allclose(got, np.logaddexp.reduce(parts, axis=0), rtol=1e-6)
