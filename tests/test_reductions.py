"""Leading-axis reductions by pairwise halving against NumPy."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.reductions import max_leading, reduce_leading, sum_leading


@pytest.mark.parametrize("rows", [1, 2, 3, 7, 8, 18, 33, 128])
def test_sum_and_max_over_rows_match_numpy(rows):
    x = np.random.default_rng(rows).normal(size=(rows, 37, 3)).astype(np.float32)
    np.testing.assert_allclose(
        np.asarray(jax.jit(sum_leading)(x)), x.astype(np.float64).sum(0), rtol=2e-6, atol=2e-5
    )
    np.testing.assert_array_equal(np.asarray(jax.jit(max_leading)(x)), x.max(0))


def test_any_associative_operation_and_gradient():
    x = jnp.asarray(np.random.default_rng(0).normal(size=(11, 5)), jnp.float32)
    np.testing.assert_allclose(
        reduce_leading(x, jnp.logaddexp), jax.nn.logsumexp(x, axis=0), rtol=1e-6
    )
    grad = jax.grad(lambda y: jnp.sum(sum_leading(y) ** 2))(x)
    np.testing.assert_allclose(grad, 2 * np.broadcast_to(np.asarray(x).sum(0), x.shape), rtol=1e-5)


def test_no_rows_is_an_error():
    with pytest.raises(ValueError, match="at least one row"):
        sum_leading(jnp.zeros((0, 4)))
