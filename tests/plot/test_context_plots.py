"""Context figures: heat-map values against the intensity, and non-empty PNGs."""

from __future__ import annotations

import jax
import numpy as np
import pytest
from matplotlib.image import imread

from jaxtrack.context.intensity import log_intensity, sample
from jaxtrack.context.learn import (
    BIRTH_POSITION_DIMS,
    CLUTTER_POSITION_DIMS,
    LearnedContext,
    birth_grid,
    clutter_grid,
    learn_density,
    marginal,
    uniform_volumes,
)
from jaxtrack.context.map_em import to_intensity
from jaxtrack.context.samples import EventSamples
from jaxtrack.datasets import SceneConfig
from jaxtrack.datasets.synthetic import birth_intensity, clutter_intensity
from jaxtrack.plot.context import position_map, save_context_plots

WIDTH, HEIGHT = 768, 576


@pytest.fixture(scope="module")
def truth():
    config = SceneConfig()
    return birth_intensity(config), clutter_intensity(config)


@pytest.fixture(scope="module")
def learned(truth):
    """A small context learned from draws of the true intensities (40 births, 300 clutter)."""
    uniform_birth, uniform_clutter = uniform_volumes(WIDTH, HEIGHT, 10.0)
    keys = jax.random.split(jax.random.PRNGKey(0), 4)
    births = np.asarray(sample(keys[0], truth[0], 40), np.float64)
    clutter = np.asarray(sample(keys[1], truth[1], 300), np.float64)
    birth_state, birth_snapshots = learn_density(
        birth_grid(uniform_birth, (25.0, 60.0)), births, 2, keys[2]
    )
    clutter_state, clutter_snapshots = learn_density(
        clutter_grid(uniform_clutter, (35.0, 60.0)), clutter, 2, keys[3]
    )
    return LearnedContext(
        birth=to_intensity(birth_state, 0.06),
        clutter=to_intensity(clutter_state, 1.9),
        metadata={"sequence_name": "toy", "frames": [1, 100]},
        birth_samples=EventSamples(births, np.arange(40), 100, "gt"),
        clutter_samples=EventSamples(clutter, np.arange(300), 100, "gt"),
        birth_snapshots=birth_snapshots,
        clutter_snapshots=clutter_snapshots,
    )


@pytest.mark.parametrize(("index", "dims"), [(0, BIRTH_POSITION_DIMS), (1, CLUTTER_POSITION_DIMS)])
def test_position_map_is_the_centre_marginal(truth, learned, index, dims):
    for intensity in (truth[index], learned[index]):
        step = 4.0
        values = position_map(intensity, dims, WIDTH, HEIGHT, step)
        assert values.shape == (HEIGHT // 4, WIDTH // 4)
        rows, columns = np.array([10, 60, 120]), np.array([5, 100, 180])
        points = np.stack([(columns + 0.5) * step, (rows + 0.5) * step], axis=-1)
        expected = np.asarray(log_intensity(marginal(intensity, dims), points), np.float64)
        np.testing.assert_allclose(np.log(values[rows, columns]), expected, rtol=1e-5, atol=1e-4)
    # the true events' centres lie in the image: the map sums to the magnitude
    total = position_map(truth[index], dims, WIDTH, HEIGHT, step).sum() * step**2
    assert total == pytest.approx(float(truth[index].magnitude), rel=0.02)


def test_context_plots_are_written(learned, truth, tmp_path):
    background = np.random.default_rng(0).integers(0, 255, (HEIGHT, WIDTH, 3), dtype=np.uint8)
    paths = save_context_plots(tmp_path / "with-truth", learned, WIDTH, HEIGHT, truth, background)
    assert [path.name for path in paths] == [
        "intensities.png",
        "birth_evolution.png",
        "clutter_evolution.png",
    ]
    for path in paths:  # each figure is more than a blank canvas
        assert np.unique(imread(path)[..., :3].reshape(-1, 3), axis=0).shape[0] > 20, path.name
    alone = save_context_plots(tmp_path / "alone", learned, WIDTH, HEIGHT)
    # without the truth the heat maps are one column: a narrower figure
    assert imread(alone[0]).shape[1] < imread(paths[0]).shape[1]
    # a figure is more than a blank canvas
    assert np.std(imread(paths[1])[..., :3]) > 0.05
