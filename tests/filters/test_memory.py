"""Memory of the compiled trackers: linear in the detection capacity, and the estimators.

Only compiled (``memory_analysis()``), never run: the sizes here would allocate up to tens
of MB.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.filters.base import run
from jaxtrack.filters.births import log_mixture_density
from jaxtrack.filters.kalman_tracker import KalmanConfig
from jaxtrack.filters.phd_tracker import PHDConfig
from jaxtrack.filters.registry import TRACKERS, build_tracker
from jaxtrack.types import Detections, SequenceInfo

INFO = SequenceInfo("memory", 100, 640, 480, 25.0)
FRAMES = 8


@functools.cache
def _analysis(config, capacity: int):
    """``memory_analysis()`` of the jitted run over ``FRAMES`` frames of ``capacity`` slots."""
    filt, params = build_tracker(config, INFO)
    detections = Detections(
        jax.ShapeDtypeStruct((FRAMES, capacity, 4), jnp.float32),
        jax.ShapeDtypeStruct((FRAMES, capacity), jnp.float32),
        jax.ShapeDtypeStruct((FRAMES, capacity), jnp.bool_),
    )
    compiled = jax.jit(functools.partial(run, filt)).lower(jax.random.key(0), params, detections)
    return compiled.compile().memory_analysis()


def test_phd_temporaries_grow_linearly_with_the_detection_capacity():
    """Births are ``births_per_detection x capacity`` particles: a ``[births, detections]``
    array (the births' proposal density) or ``[blocks, detections]`` stacks (the update) would
    make the temporaries grow 16-fold from 512 to 2048 slots; blocked, about 4-fold."""
    small, large = (_analysis(PHDConfig(), c).temp_size_in_bytes for c in (512, 2048))
    assert large < 5 * small
    assert large < 20 * 2**20  # 578 MB before the births and the update were blocked


@pytest.mark.parametrize(
    ("config", "capacity"),
    [
        (PHDConfig(), 16),
        (PHDConfig(), 512),
        (PHDConfig(), 2048),
        (PHDConfig(extraction="gmm"), 64),
        (KalmanConfig(), 16),
        (KalmanConfig(preset="sort"), 1024),
    ],
)
def test_the_memory_estimate_is_within_a_factor_two_of_the_compiled_run(config, capacity):
    analysis = _analysis(config, capacity)
    compiled = (
        analysis.temp_size_in_bytes
        + analysis.argument_size_in_bytes
        + analysis.output_size_in_bytes
    )
    estimate = TRACKERS[config.tracker].memory(config, capacity, FRAMES)
    assert compiled / 2 <= estimate.chunk_bytes <= 2 * compiled
    filt, params = build_tracker(config, INFO)
    one_frame = jax.tree.map(lambda x: x[:1], _detections(capacity))
    _, info = jax.eval_shape(functools.partial(run, filt), jax.random.key(0), params, one_frame)
    assert estimate.frame_output_bytes == pytest.approx(
        sum(leaf.size * leaf.dtype.itemsize for leaf in jax.tree.leaves(info)), abs=4
    )
    assert estimate.run_bytes(1000) == estimate.chunk_bytes + 2000 * estimate.frame_output_bytes


def _detections(capacity: int) -> Detections:
    return Detections(
        jnp.ones((FRAMES, capacity, 4)),
        jnp.zeros((FRAMES, capacity)),
        jnp.zeros((FRAMES, capacity), bool),
    )


def test_blocked_mixture_density_equals_the_single_block_and_its_gradient():
    """Blocks of 7 points (the last one padded) give each point the same sum, and the same
    gradient w.r.t. the noise (``jax.checkpoint`` recomputes the blocks)."""
    key_points, key_measurements = jax.random.split(jax.random.key(5))
    measurements = jnp.concatenate(
        [
            jax.random.uniform(key_measurements, (6, 2), maxval=400.0),
            jnp.full((6, 2), 40.0),
        ],
        axis=1,
    )
    points = jnp.repeat(measurements, 5, axis=0) + jax.random.normal(key_points, (30, 4))
    mask = jnp.arange(6) < 4

    def density(scale, block_size):
        std = scale * measurements[:, 2:][:, [0, 1, 0, 1]]
        return log_mixture_density(points, measurements, std, mask, block_size)

    blocked = jax.jit(density, static_argnums=1)(0.1, 7)
    np.testing.assert_allclose(blocked, jax.jit(density, static_argnums=1)(0.1, None), rtol=1e-6)
    assert blocked.shape == (30,) and bool(jnp.all(jnp.isfinite(blocked)))

    def total(scale, block_size):
        return jnp.sum(density(scale, block_size))

    np.testing.assert_allclose(jax.grad(total)(0.1, 7), jax.grad(total)(0.1, None), rtol=1e-5)
