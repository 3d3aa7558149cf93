"""State extraction: GMM clustering of the particles and the measurement-driven partition."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.filters.extraction import gmm_clusters, measurement_partition

CENTRES = np.array(
    [
        [100.0, 2.0, 100.0, 0.0, 40.0, 90.0],
        [300.0, -1.0, 120.0, 1.0, 30.0, 80.0],
        [200.0, 0.0, 400.0, 0.0, 50.0, 110.0],
    ]
)


def _blobs(masses, per_blob=300, seed=0):
    rng = np.random.default_rng(seed)
    particles = np.concatenate(
        [c + rng.normal(0, [3, 0.3, 3, 0.3, 1, 2], (per_blob, 6)) for c in CENTRES]
    )
    weights = np.repeat(np.asarray(masses) / per_blob, per_blob)
    return jnp.asarray(particles, jnp.float32), jnp.log(jnp.asarray(weights, jnp.float32))


def test_gmm_keeps_the_clusters_with_mass_above_one_half():
    particles, log_weights = _blobs([1.0, 1.1, 0.3])
    scores = jnp.concatenate([jnp.full(300, 0.9), jnp.full(300, 0.6), jnp.full(300, 0.2)])
    for seed in range(5):
        estimates = gmm_clusters(
            jax.random.key(seed), particles, log_weights, scores, 8, 10, jnp.asarray(0.5)
        )
        kept = np.asarray(estimates.mask)
        assert kept.sum() == 2, seed
        states = np.asarray(estimates.states)[kept]
        order = np.argsort(states[:, 0])
        np.testing.assert_allclose(states[order], CENTRES[:2], atol=0.5)
        np.testing.assert_allclose(np.asarray(estimates.masses)[kept][order], [1.0, 1.1], atol=0.02)
        np.testing.assert_allclose(np.asarray(estimates.scores)[kept][order], [0.9, 0.6], atol=0.01)


def test_gmm_with_no_mass_gives_no_estimate():
    particles, _ = _blobs([1.0, 1.0, 1.0])
    estimates = gmm_clusters(
        jax.random.key(0), particles, jnp.full(900, -1e30), jnp.zeros(900), 8, 5, jnp.asarray(0.5)
    )
    assert not np.any(estimates.mask)
    assert np.all(np.isfinite(estimates.states))


def test_measurement_partition_keeps_the_parts_heavier_than_the_threshold():
    """The parts' masses and mean states come from the update (``tests/filters/test_stages.py``
    checks them against a NumPy oracle); the partition keeps real detections above 0.5."""
    log_masses = jnp.log(jnp.array([0.9, 0.3, 0.7, 1e-30]))
    states = jnp.arange(24.0).reshape(4, 6)
    estimates = measurement_partition(
        log_masses,
        states,
        jnp.array([0.9, 0.6, 0.8, 0.0]),
        jnp.array([True, True, True, False]),
        jnp.asarray(0.5),
    )
    np.testing.assert_allclose(estimates.masses, [0.9, 0.3, 0.7, 0.0], rtol=1e-6, atol=1e-20)
    np.testing.assert_array_equal(estimates.states, states)
    np.testing.assert_array_equal(estimates.mask, [True, False, True, False])


def test_gmm_jit_equals_eager():
    particles, log_weights = _blobs([1.0, 0.8, 0.3], per_blob=20)
    args = (jax.random.key(0), particles, log_weights, jnp.ones(60), 3, 2, jnp.asarray(0.5))
    jitted = jax.jit(gmm_clusters, static_argnums=(4, 5))(*args)
    with jax.disable_jit():
        eager = gmm_clusters(*args)
    jax.tree.map(lambda a, b: np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-4), jitted, eager)
