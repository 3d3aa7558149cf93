"""Recursive MAP-EM mixture learning: recovery, extinction, uniform share, NumPy oracle."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.stats import multivariate_normal

from jaxtrack.context.intensity import log_density, log_intensity
from jaxtrack.context.map_em import (
    UNIFORM_FLOOR,
    dirichlet_beta,
    estimate_magnitude,
    fit,
    grid_init_birth,
    grid_init_clutter,
    init_state,
    map_em_learner,
    num_free_parameters,
    to_intensity,
)

TRUE_WEIGHTS = np.array([0.5, 0.3, 0.2])
TRUE_MEANS = np.array([[25.0, 30.0], [70.0, 70.0], [60.0, 20.0]])
TRUE_COVS = np.array(
    [[[16.0, 6.0], [6.0, 9.0]], [[25.0, 0.0], [0.0, 4.0]], [[9.0, -3.0], [-3.0, 16.0]]]
)

fit_jit = jax.jit(fit, static_argnums=0, static_argnames="num_epochs")


def mixture_samples(seed, num, uniform_share=0.0):
    """Samples of the known 3-component mixture in [0, 100]^2, plus a uniform share."""
    rng = np.random.default_rng(seed)
    comp = rng.choice(3, num, p=TRUE_WEIGHTS)
    noise = rng.normal(size=(num, 2))
    x = TRUE_MEANS[comp] + np.einsum("nij,nj->ni", np.linalg.cholesky(TRUE_COVS)[comp], noise)
    uniform = rng.random(num) < uniform_share
    x[uniform] = rng.uniform(0, 100, (uniform.sum(), 2))
    return x


def grid_2d(grid=6, extent=100.0, dtype=jnp.float32):
    """A ``grid x grid`` starting state over ``[0, extent]^2`` (std = grid spacing)."""
    step = extent / grid
    cols, rows = np.meshgrid((np.arange(grid) + 0.5) * step, (np.arange(grid) + 0.5) * step)
    means = np.stack([cols.ravel(), rows.ravel()], -1)
    covs = np.broadcast_to(np.eye(2) * step**2, (grid * grid, 2, 2))
    return init_state(means, covs, [0.0, 0.0], [extent, extent], dtype=dtype)


@pytest.fixture(scope="module")
def learned_three():
    """6x6 grid learned from 3000 samples of the known mixture, 4 passes."""
    samples = mixture_samples(0, 3000)
    state = fit_jit(map_em_learner(), grid_2d(), samples, num_epochs=4)
    return samples, state


def test_free_parameters_and_beta():
    assert num_free_parameters(6) == 27 and dirichlet_beta(6) == 13.5
    assert num_free_parameters(4) == 14 and dirichlet_beta(4) == 7.0


def test_recovers_three_component_mixture(learned_three):
    _, state = learned_three
    alive = np.asarray(state.alive)
    pi_g = 1 - float(state.uniform_weight)
    weights = pi_g * np.asarray(state.weights)
    means, covs = np.asarray(state.means), np.asarray(state.covs)
    # duplicates may share a true component's mass: compare the mass of each basin
    # (live components nearest to that true component in its Mahalanobis metric) ...
    inv = np.linalg.inv(TRUE_COVS)
    diff = means[:, None] - TRUE_MEANS
    basin = np.einsum("mki,kij,mkj->mk", diff, inv, diff).argmin(axis=1)
    for k in range(3):
        mass = weights[alive & (basin == k)].sum()
        np.testing.assert_allclose(mass, TRUE_WEIGHTS[k], atol=0.03)
        # ... and the dominant component of the basin with the true mean and covariance
        members = np.flatnonzero(alive & (basin == k))
        top = members[np.argmax(weights[members])]
        assert weights[top] > 0.75 * TRUE_WEIGHTS[k]
        np.testing.assert_allclose(means[top], TRUE_MEANS[k], atol=0.8)  # < 0.3 std
        cov_error = np.linalg.norm(covs[top] - TRUE_COVS[k]) / np.linalg.norm(TRUE_COVS[k])
        assert cov_error < 0.15
    # and the density itself: L1 distance to the true density over the volume
    xs, ys = np.meshgrid(np.arange(0.25, 100, 0.5), np.arange(0.25, 100, 0.5))
    points = np.stack([xs.ravel(), ys.ravel()], -1)
    truth = sum(
        w * multivariate_normal(m, c).pdf(points)
        for w, m, c in zip(TRUE_WEIGHTS, TRUE_MEANS, TRUE_COVS, strict=True)
    )
    learned = np.exp(np.asarray(log_density(to_intensity(state, 1.0), jnp.asarray(points))))
    assert np.abs(learned - truth).sum() * 0.25 < 0.12


def test_surplus_grid_components_go_extinct(learned_three):
    _, state = learned_three
    start = grid_2d()
    alive = np.asarray(state.alive)
    assert 3 <= alive.sum() <= 10  # of 36
    # every grid cell whose centre is far from all the data dies
    distance = np.linalg.norm(np.asarray(start.means)[:, None] - TRUE_MEANS, axis=-1).min(axis=1)
    far = distance > 30
    assert far.sum() >= 10 and not alive[far].any()
    assert np.all(np.asarray(state.weights)[~alive] == 0)
    np.testing.assert_allclose(np.asarray(state.weights).sum(), 1.0, rtol=1e-5)


def test_hierarchical_uniform_share():
    """``pi_u`` by ML: ~1 for uniform data, -> floor for clusters, in between for a mix."""
    learner = map_em_learner()
    uniform = np.random.default_rng(1).uniform(0, 100, (2000, 2))
    state = fit_jit(learner, grid_2d(), uniform, num_epochs=2)
    assert float(state.uniform_weight) > 0.99  # the Gaussians never take over uniform data
    clean = fit_jit(learner, grid_2d(), mixture_samples(1, 3000), num_epochs=4)
    assert float(clean.uniform_weight) < 0.02
    # 30% background: the split is not identifiable (broad Gaussians can model part of the
    # background), so check the share loosely and the density tightly
    mixed = fit_jit(learner, grid_2d(), mixture_samples(1, 3000, uniform_share=0.3), num_epochs=4)
    assert 0.1 < float(mixed.uniform_weight) < 0.35
    xs, ys = np.meshgrid(np.arange(0.25, 100, 0.5), np.arange(0.25, 100, 0.5))
    points = np.stack([xs.ravel(), ys.ravel()], -1)
    truth = 0.3 / 100.0**2 + 0.7 * sum(
        w * multivariate_normal(m, c).pdf(points)
        for w, m, c in zip(TRUE_WEIGHTS, TRUE_MEANS, TRUE_COVS, strict=True)
    )
    learned = np.exp(np.asarray(log_density(to_intensity(mixed, 1.0), jnp.asarray(points))))
    assert np.abs(learned - truth).sum() * 0.25 < 0.25


def test_uniform_weight_never_below_floor():
    learner = map_em_learner("constant", rate=0.05)
    rng = np.random.default_rng(2)
    tight = TRUE_MEANS[rng.integers(0, 3, 1000)] + rng.normal(size=(1000, 2))  # std 1
    samples = jnp.asarray(tight, jnp.float32)

    def body(state, x):
        state = learner.update(state, x)
        return state, state.uniform_weight

    _, trace = jax.lax.scan(body, grid_2d(), samples)
    trace = np.asarray(trace)
    floor = np.float32(UNIFORM_FLOOR)
    assert trace.min() == floor  # reached: the unclipped ML update would go below it
    assert np.all(trace >= floor) and trace[0] < 1.0  # and it escaped from pi_u = 1
    assert trace[-1] == floor


def test_learning_rate_schedules():
    state = grid_2d(3)  # K = 9
    lam, lam_u = map_em_learner(prior_count=2.0).learning_rates(state, 5)
    np.testing.assert_allclose([lam, lam_u], [1 / (5 + 18), 1 / 6], rtol=1e-6)
    lam, lam_u = map_em_learner(min_rate=0.01).learning_rates(state, 1000)
    np.testing.assert_allclose([lam, lam_u], [0.01, 0.01], rtol=1e-6)
    lam, lam_u = map_em_learner("constant", rate=0.02).learning_rates(state, 7)
    np.testing.assert_allclose([lam, lam_u], [0.02, 0.02], rtol=1e-6)
    with pytest.raises(ValueError, match="schedule"):
        map_em_learner("cosine")
    with pytest.raises(ValueError, match="max_prior_mass"):
        map_em_learner(max_prior_mass=1.0)


# ---------------------------------------------------------------- NumPy loop oracle


def reference_fit(
    state, samples, mask, num_epochs, schedule, rate, prior_count, min_rate, max_prior_mass
):
    """Slow float64 loop over samples and components of the documented recursion."""
    pi_u = float(state.uniform_weight)
    weights = np.array(state.weights, np.float64)
    means = np.array(state.means, np.float64)
    covs = np.array(state.covs, np.float64)
    alive = np.array(state.alive)
    lower, upper = np.array(state.lower, np.float64), np.array(state.upper, np.float64)
    floor = np.diag(np.array(state.variance_floor, np.float64))
    num_slots, dim = means.shape
    beta = (dim + dim * (dim + 1) / 2) / 2
    volume = np.prod(upper - lower)
    count = 0
    capped_steps = exact_steps = 0
    for epoch in range(num_epochs):
        for x, valid in zip(samples, mask, strict=True):
            if not valid:
                continue
            if epoch == 0:
                count += 1
            if schedule == "constant":
                lam = lam_u = rate
            else:
                lam = max(1.0 / (count + prior_count * num_slots), min_rate)
                lam_u = max(1.0 / (count + 1), min_rate)
            joint = np.zeros(num_slots)
            for m in range(num_slots):
                if alive[m]:
                    joint[m] = weights[m] * multivariate_normal(means[m], covs[m]).pdf(x)
            gauss = joint.sum()
            own = joint / gauss
            share = max(1 - pi_u, UNIFORM_FLOOR)
            own_u = pi_u / volume / (pi_u / volume + share * gauss)
            pi_u = min(max(pi_u + lam_u * (own_u - pi_u), UNIFORM_FLOOR), 1.0)
            num_alive = alive.sum()
            if lam * beta < max_prior_mass / num_alive:
                prior, exact_steps = lam * beta, exact_steps + 1
            else:
                prior, capped_steps = max_prior_mass / num_alive, capped_steps + 1
            denominator = 1 - num_alive * prior
            new_weights = weights.copy()
            for m in range(num_slots):
                if not alive[m]:
                    continue
                new_weights[m] = weights[m] + lam * (
                    own[m] / denominator - weights[m] - prior / denominator
                )
                step = min(lam * own[m] / weights[m], 1.0)
                diff = x - means[m]
                means[m] = means[m] + step * diff
                covs[m] = covs[m] + step * (np.outer(diff, diff) + floor - covs[m])
            for m in range(num_slots):
                if alive[m] and new_weights[m] <= 0:
                    alive[m] = False
                    new_weights[m] = 0.0
            weights = new_weights / new_weights.sum()
    result = dict(
        uniform_weight=pi_u, weights=weights, means=means, covs=covs, alive=alive, count=count
    )
    return result, capped_steps, exact_steps


REFERENCE_CASES = {
    "inverse-2d": dict(
        schedule="inverse", rate=0.01, prior_count=2.0, min_rate=0.0, max_prior_mass=0.5
    ),
    "inverse-floor-2d": dict(
        schedule="inverse", rate=0.01, prior_count=1.0, min_rate=0.004, max_prior_mass=0.7
    ),
    "constant-4d": dict(
        schedule="constant", rate=0.01, prior_count=2.0, min_rate=0.0, max_prior_mass=0.5
    ),
}


@pytest.mark.parametrize("case", sorted(REFERENCE_CASES))
def test_matches_numpy_reference(case):
    """jit == NumPy loop == eager, all in float64 (so 1e-6 relative is ~1e9 ulps of slack for
    the different summation orders, yet far below any modelling difference)."""
    settings = REFERENCE_CASES[case]
    rng = np.random.default_rng(3)
    with jax.enable_x64(True):
        if case.endswith("4d"):
            state = grid_init_clutter(
                768, 576, (30.0, 70.0), grid=(4, 3), dtype=jnp.float64
            )  # 12 components
            centres = np.array([[130.0, 130.0, 34.0, 60.0], [660.0, 480.0, 50.0, 70.0]])
            spread = np.array([12.0, 10.0, 6.0, 10.0])
            samples = centres[rng.integers(0, 2, 160)] + spread * rng.normal(size=(160, 4))
        else:
            state = grid_2d(4, dtype=jnp.float64)  # 16 components
            samples = mixture_samples(3, 160, uniform_share=0.2)
        mask = rng.random(len(samples)) > 0.1
        samples[~mask] = np.nan  # padded slots may hold anything
        learner = map_em_learner(
            settings["schedule"],
            rate=settings["rate"],
            prior_count=settings["prior_count"],
            min_rate=settings["min_rate"],
            max_prior_mass=settings["max_prior_mass"],
        )
        got = fit_jit(learner, state, jnp.asarray(samples), jnp.asarray(mask), num_epochs=2)
        expected, capped, exact = reference_fit(state, samples, mask, 2, **settings)
        eager_samples = jnp.asarray(samples[:40])  # un-jitted lax.scan is a slow Python loop
        with jax.disable_jit():
            eager = fit(learner, state, eager_samples, jnp.asarray(mask[:40]))
        jitted = fit_jit(learner, state, eager_samples, jnp.asarray(mask[:40]))
    # the run exercises the capped prior, the exact eq. 18 and extinction
    assert capped > 0 and exact > 0
    assert 0 < expected["alive"].sum() < len(expected["alive"])
    np.testing.assert_array_equal(np.asarray(got.alive), expected["alive"])
    assert int(got.count) == expected["count"] == mask.sum()
    for field in ("uniform_weight", "weights", "means", "covs"):
        np.testing.assert_allclose(
            np.asarray(getattr(got, field)), expected[field], rtol=1e-6, atol=1e-8, err_msg=field
        )
    for field, value in eager._asdict().items():
        np.testing.assert_allclose(
            np.asarray(getattr(jitted, field)), np.asarray(value), rtol=1e-6, atol=1e-8
        )


# ---------------------------------------------------------------- masks, gradients, intensity


def test_padded_samples_are_ignored():
    samples = mixture_samples(4, 200)
    padded = np.concatenate([samples[:120], np.full((30, 2), np.nan), samples[120:]])
    mask = np.arange(len(padded)) < 120
    mask[150:] = True
    learner = map_em_learner()
    plain = fit_jit(learner, grid_2d(), samples)
    masked = fit_jit(learner, grid_2d(), padded, mask)
    for a, b in zip(plain, masked, strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_gradients_are_finite():
    samples = jnp.asarray(mixture_samples(5, 150), jnp.float32)
    test_points = jnp.asarray(mixture_samples(6, 20), jnp.float32)
    learner = map_em_learner()

    def loss(x):
        state = fit(learner, grid_2d(4), x)
        return jnp.sum(log_density(to_intensity(state, 1.0), test_points))

    grad = jax.grad(loss)(samples)
    assert np.all(np.isfinite(np.asarray(grad)))
    assert float(jnp.abs(grad).sum()) > 0
    state = fit(learner, grid_2d(4), samples)
    assert not np.all(np.asarray(state.alive))  # gradients also flow past extinctions


def test_intensity_integrates_to_magnitude(learned_three):
    _, state = learned_three
    intensity = to_intensity(state, 2.5)
    points = jax.random.uniform(jax.random.PRNGKey(0), (400_000, 2), minval=0.0, maxval=100.0)
    integral = float(jnp.mean(jnp.exp(log_intensity(intensity, points)))) * 100.0**2
    # live components lie > 4 std inside the volume, so no mass leaks out; MC error ~1%
    np.testing.assert_allclose(integral, 2.5, rtol=0.03)


def test_clutter_intensity_integrates_to_magnitude():
    """4-D: importance sampling, proposal (half uniform, half the learned Gaussians) evaluated
    with SciPy; Gaussian mass outside the volume measured by sampling each component."""
    rng = np.random.default_rng(7)
    centres = np.array([[130.0, 130.0, 34.0, 60.0], [660.0, 480.0, 50.0, 70.0]])
    spread = np.array([12.0, 10.0, 6.0, 10.0])
    samples = centres[rng.integers(0, 2, 800)] + spread * rng.normal(size=(800, 4))
    samples = np.concatenate([samples, rng.uniform([0, 0, 8, 16], [768, 576, 64, 150], (200, 4))])
    start = grid_init_clutter(768, 576, (35.0, 65.0), size_range=((8, 16), (64, 150)))
    state = fit_jit(map_em_learner(), start, rng.permutation(samples), num_epochs=2)
    magnitude = 1.7
    intensity = to_intensity(state, magnitude)
    lower, upper = np.asarray(state.lower, np.float64), np.asarray(state.upper, np.float64)
    live = np.flatnonzero(np.asarray(state.alive))
    weights = np.asarray(state.weights, np.float64)[live]
    weights /= weights.sum()  # exactly, in float64
    means = np.asarray(state.means, np.float64)[live]
    chols = np.linalg.cholesky(np.asarray(state.covs, np.float64)[live])

    def draw_gaussians(num):
        which = rng.choice(len(live), num, p=weights)
        return which, means[which] + np.einsum(
            "nij,nj->ni", chols[which], rng.normal(size=(num, 4))
        )

    num = 200_000
    _, gauss_draws = draw_gaussians(num // 2)
    draws = np.concatenate([rng.uniform(lower, upper, (num // 2, 4)), gauss_draws])
    gauss_pdf = sum(
        w * multivariate_normal(m, c @ c.T).pdf(draws)
        for w, m, c in zip(weights, means, chols, strict=True)
    )
    proposal = 0.5 / np.prod(upper - lower) + 0.5 * gauss_pdf
    inside = np.all((draws >= lower) & (draws <= upper), axis=1)
    values = np.exp(np.asarray(log_intensity(intensity, jnp.asarray(draws, jnp.float32))))
    integral = np.mean(np.where(inside, values / proposal, 0.0))
    which, check = draw_gaussians(400_000)
    inside_share = np.all((check >= lower) & (check <= upper), axis=1)
    mass_inside = np.bincount(which, inside_share, len(live)) / np.bincount(which, None, len(live))
    pi_u = float(state.uniform_weight)
    expected = magnitude * (pi_u + (1 - pi_u) * np.sum(weights * mass_inside))
    assert 0.1 < pi_u < 0.35  # 20% of the samples are uniform
    np.testing.assert_allclose(integral, expected, rtol=0.01)
    assert expected > 0.95 * magnitude  # (the Gaussians stay nearly inside the image)


def test_grid_initialisation():
    birth = grid_init_birth(768, 576, (30.0, 70.0), max_speed=8.0)
    assert birth.means.shape == (120, 6) and birth.covs.shape == (120, 6, 6)
    assert float(birth.uniform_weight) == 1.0 and bool(birth.alive.all())
    np.testing.assert_allclose(np.asarray(birth.weights), 1 / 120, rtol=1e-6)
    means = np.asarray(birth.means)
    np.testing.assert_allclose(np.unique(means[:, 0]), (np.arange(12) + 0.5) * 64)
    np.testing.assert_allclose(np.unique(means[:, 2]), (np.arange(10) + 0.5) * 57.6, rtol=1e-6)
    np.testing.assert_array_equal(means[:, [1, 3]], 0.0)  # zero velocity
    np.testing.assert_allclose(means[:, 4:], np.broadcast_to([30.0, 70.0], (120, 2)))
    np.testing.assert_allclose(birth.lower, [0, -8, 0, -8, 7.5, 17.5])
    np.testing.assert_allclose(birth.upper, [768, 8, 576, 8, 120, 280])
    np.testing.assert_allclose(np.sqrt(np.diagonal(birth.covs[0])), [64, 4, 57.6, 4, 15, 35])

    clutter = grid_init_clutter(768, 576, (30.0, 70.0), size_range=((8, 16), (64, 150)))
    assert clutter.means.shape == (224, 4) and int(clutter.count) == 0
    np.testing.assert_allclose(np.unique(clutter.means[:, 0]), (np.arange(16) + 0.5) * 48)
    np.testing.assert_allclose(clutter.lower, [0, 0, 8, 16])
    np.testing.assert_allclose(clutter.upper, [768, 576, 64, 150])
    assert np.all(np.linalg.eigvalsh(np.asarray(clutter.covs)) > 0)


def test_init_state_floors_eigenvalues_and_pads():
    covs = np.array([[[1.0, 1.0], [1.0, 1.0]], [[4.0, 0.0], [0.0, 1e-9]]])  # singular, tiny
    state = init_state(
        [[1.0, 2.0], [3.0, 4.0]], covs, [0, 0], [10, 10], variance_floor=[0.01, 0.04], capacity=4
    )
    assert state.weights.shape == (4,)
    np.testing.assert_array_equal(np.asarray(state.alive), [True, True, False, False])
    np.testing.assert_allclose(np.asarray(state.weights), [0.5, 0.5, 0, 0])
    scale = np.sqrt([0.01, 0.04])
    for cov in np.asarray(state.covs, np.float64):
        whitened = cov / np.outer(scale, scale)
        assert np.linalg.eigvalsh(whitened).min() >= 1 - 1e-5
    np.testing.assert_allclose(state.covs[1, 0, 0], 4.0, rtol=1e-6)
    with pytest.raises(ValueError, match="capacity"):
        init_state(np.zeros((2, 2)), np.eye(2)[None].repeat(2, 0), [0, 0], [1, 1], capacity=1)
    with pytest.raises(ValueError, match="upper"):
        init_state(np.zeros((1, 2)), np.eye(2)[None], [0, 0], [1, 0])


def test_covariances_stay_above_floor_and_symmetric(learned_three):
    _, state = learned_three
    covs = np.asarray(state.covs, np.float64)
    np.testing.assert_array_equal(covs, np.swapaxes(covs, 1, 2))
    scale = np.sqrt(np.asarray(state.variance_floor, np.float64))
    whitened = covs / np.outer(scale, scale)
    assert np.linalg.eigvalsh(whitened).min() > 1 - 1e-3


def test_to_intensity_and_magnitude():
    state = grid_2d(3)._replace(
        alive=jnp.asarray([True] * 4 + [False] * 5),
        weights=jnp.asarray([0.25] * 4 + [0.0] * 5),
    )
    intensity = to_intensity(state, estimate_magnitude(30, 12))
    assert float(intensity.magnitude) == 2.5
    np.testing.assert_array_equal(np.asarray(intensity.weights)[4:], 0.0)
    assert intensity.means.shape == (9, 2)
    with pytest.raises(ValueError, match="num_frames"):
        estimate_magnitude(3, 0)
