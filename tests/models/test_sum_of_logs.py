"""The likelihood's log-normaliser, ``sum_of_logs``: its batching rule and its derivative."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.models.likelihood import sum_of_logs

VALUES = np.random.default_rng(0).uniform(0.2, 40.0, (5, 300, 4)).astype(np.float32)


def test_batched_and_unbatched_sums_agree_with_float64():
    """One member at a time (the YNNPACK reduction), a batch of members (the batching rule's
    elementwise additions) and a batch of batches: all within float32 rounding of the
    float64 sum."""
    expected = np.log(VALUES.astype(np.float64)).sum(-1)
    one_by_one = np.stack([jax.jit(sum_of_logs)(v) for v in VALUES])
    batched = np.asarray(jax.jit(jax.vmap(sum_of_logs))(VALUES))
    nested = np.asarray(jax.jit(jax.vmap(jax.vmap(sum_of_logs)))(VALUES.reshape(5, 3, 100, 4)))
    for got in (one_by_one, batched, nested.reshape(5, 300)):
        np.testing.assert_allclose(got, expected, rtol=2e-6, atol=2e-6)


def test_the_derivative_is_the_reciprocal_also_under_vmap():
    weights = np.linspace(-1.0, 1.0, 300, dtype=np.float32)

    def loss(values):
        return sum_of_logs(values) @ weights

    expected = weights[:, None] / VALUES
    np.testing.assert_allclose(jax.jit(jax.grad(loss))(VALUES[0]), expected[0], rtol=1e-6)
    np.testing.assert_allclose(jax.jit(jax.vmap(jax.grad(loss)))(VALUES), expected, rtol=1e-6)
    tangent = np.ones_like(VALUES[0])
    _, directional = jax.jvp(sum_of_logs, (jnp.asarray(VALUES[0]),), (jnp.asarray(tangent),))
    np.testing.assert_allclose(directional, (1.0 / VALUES[0]).sum(-1), rtol=1e-6)
