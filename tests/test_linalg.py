"""Unrolled small linear algebra against NumPy/LAPACK, batched, with gradients."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.linalg import (
    cholesky,
    cholesky_loop,
    solve_lower,
    solve_lower_loop,
    solve_spd,
    solve_upper_transposed,
)


def _spd(rng, batch, n):
    a = rng.normal(size=(*batch, n, n))
    return a @ np.swapaxes(a, -1, -2) + n * np.eye(n)


@pytest.mark.parametrize("n", [1, 2, 4, 6])
def test_cholesky_and_solves_match_numpy(n):
    rng = np.random.default_rng(n)
    a = _spd(rng, (3, 5), n)
    b = rng.normal(size=(3, 5, n))
    lower = np.asarray(cholesky(jnp.asarray(a)))
    np.testing.assert_allclose(lower, np.linalg.cholesky(a), rtol=1e-5, atol=1e-5)
    assert np.all(np.triu(lower, 1) == 0)
    np.testing.assert_allclose(
        solve_lower(jnp.asarray(lower), jnp.asarray(b)),
        np.linalg.solve(lower, b[..., None])[..., 0],
        rtol=1e-4,
        atol=1e-5,
    )
    np.testing.assert_allclose(
        solve_upper_transposed(jnp.asarray(lower), jnp.asarray(b)),
        np.linalg.solve(np.swapaxes(lower, -1, -2), b[..., None])[..., 0],
        rtol=1e-4,
        atol=1e-5,
    )
    np.testing.assert_allclose(
        solve_spd(jnp.asarray(a), jnp.asarray(b)),
        np.linalg.solve(a, b[..., None])[..., 0],
        rtol=1e-4,
        atol=1e-5,
    )


def test_broadcasting_one_matrix_many_right_hand_sides():
    rng = np.random.default_rng(0)
    a = _spd(rng, (), 4)
    b = rng.normal(size=(7, 4))
    lower = cholesky(jnp.asarray(a))
    np.testing.assert_allclose(
        solve_lower(lower, jnp.asarray(b)), np.linalg.solve(np.linalg.cholesky(a), b.T).T, rtol=1e-4
    )


def test_not_positive_definite_gives_nan_like_lapack():
    a = jnp.array([[1.0, 2.0], [2.0, 1.0]])
    assert np.isnan(np.asarray(cholesky(a))).any()
    assert np.isnan(np.asarray(jnp.linalg.cholesky(a))).any()


def test_gradient_of_log_determinant_matches_inverse():
    rng = np.random.default_rng(1)
    a = jnp.asarray(_spd(rng, (), 4), jnp.float32)

    def log_det(m):
        return 2 * jnp.sum(jnp.log(jnp.diagonal(cholesky(0.5 * (m + m.T)))))

    grad = jax.grad(log_det)(a)
    np.testing.assert_allclose(grad, np.linalg.inv(np.asarray(a)), rtol=1e-3, atol=1e-5)


@pytest.mark.parametrize("n", [1, 4, 6])
def test_loop_forms_match_the_unrolled_ones_and_numpy(n):
    rng = np.random.default_rng(10 + n)
    a = _spd(rng, (4, 3), n).astype(np.float32)
    b = rng.normal(size=(4, 3, n)).astype(np.float32)
    lower = np.asarray(cholesky_loop(jnp.asarray(a)))
    assert np.all(np.triu(lower, 1) == 0)
    np.testing.assert_allclose(lower, np.asarray(cholesky(jnp.asarray(a))), rtol=2e-6, atol=1e-6)
    np.testing.assert_allclose(
        lower, np.linalg.cholesky(a.astype(np.float64)), rtol=1e-5, atol=1e-5
    )
    # Broadcast batch axes: one factor per row of `b`'s leading axis, several right-hand sides.
    eye = jnp.eye(n, dtype=jnp.float32)
    got = solve_lower_loop(jnp.asarray(lower)[:, :, None], eye)
    want = solve_lower(jnp.asarray(lower)[:, :, None], eye)
    assert got.shape == want.shape == (4, 3, n, n)
    np.testing.assert_allclose(got, want, rtol=2e-6, atol=1e-6)
    np.testing.assert_allclose(
        solve_lower_loop(jnp.asarray(lower), jnp.asarray(b)),
        np.linalg.solve(lower.astype(np.float64), b[..., None])[..., 0],
        rtol=1e-4,
        atol=1e-5,
    )

    def loss(form, a):
        return jnp.sum(jnp.sin(form(a)))

    np.testing.assert_allclose(
        jax.grad(lambda a: loss(cholesky_loop, a))(jnp.asarray(a)),
        jax.grad(lambda a: loss(cholesky, a))(jnp.asarray(a)),
        rtol=1e-4,
        atol=1e-5,
    )
