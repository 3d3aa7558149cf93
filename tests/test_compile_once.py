"""One compile per setting: the tracker, the sweep and the experiments share compiled code.

Counts XLA backend compiles (``jax.monitoring`` events) while the same setting is run again
through different callers; the first call of each path warms it up.
"""

from __future__ import annotations

import contextlib

import jax
import numpy as np
import pytest

from jaxtrack.experiments.common import QUICK_TRACKER_CONFIG, learn_split, split_halves
from jaxtrack.filters.phd_tracker import PHDConfig
from jaxtrack.filters.registry import build_tracker
from jaxtrack.io import load_sequence
from jaxtrack.pipelines.context import uniform_tracker_rows
from jaxtrack.pipelines.sweep import magnitude_grid, sweep
from jaxtrack.pipelines.tracking import track_sequences

COMPILE_EVENT = "/jax/core/compile/backend_compile_duration"
_compiles: list[str] = []
jax.monitoring.register_event_duration_secs_listener(
    lambda name, *_, **__: _compiles.append(name) if name == COMPILE_EVENT else None
)


@contextlib.contextmanager
def count_compiles():
    """Yields a one-item list holding the number of backend compiles inside the block."""
    start = len(_compiles)
    counted = [0]
    yield counted
    counted[0] = len(_compiles) - start


@pytest.fixture(scope="module")
def campus(mot15_root):
    return load_sequence(mot15_root / "TUD-Campus", frames=(1, 40))


def test_track_sequences_compiles_once_per_setting(campus):
    config = QUICK_TRACKER_CONFIG
    (first,) = track_sequences([campus], config, seed=1)
    with count_compiles() as again:
        (second,) = track_sequences([campus], PHDConfig.from_dict(config.to_dict()), seed=1)
        # Other magnitudes and post-processing: params and host code, not a new compile.
        track_sequences([campus], config.replace(clutter_rate=3.0, max_gap=0), seed=2)
        # Context learning's UM run is the same setting.
        uniform_tracker_rows(campus, seed=3, config=config)
    assert again[0] == 0
    np.testing.assert_array_equal(first.ids, second.ids)
    with count_compiles() as other:
        track_sequences([campus], config.replace(num_particles=192), seed=1)
    assert other[0] > 0  # a new static setting does compile (the counter works)


def test_sweep_compiles_once_per_setting(campus):
    filt, params = build_tracker(QUICK_TRACKER_CONFIG, campus.info)
    grid = magnitude_grid([0.5, 2.0], [0.1, 0.3])
    key = jax.random.key(0)
    sweep(filt, params, key, campus.detections, grid, chunk_size=4)
    with count_compiles() as again:
        filt_again, params_again = build_tracker(
            PHDConfig.from_dict(QUICK_TRACKER_CONFIG.to_dict()), campus.info
        )
        sweep(filt_again, params_again, key, campus.detections, grid, chunk_size=4)
    assert again[0] == 0


def test_experiment_context_learning_reuses_the_compiled_tracker(mot15_root):
    split = split_halves(mot15_root / "TUD-Campus")
    learn_split(split, QUICK_TRACKER_CONFIG, seed=0)
    with count_compiles() as again:
        learn_split(split, QUICK_TRACKER_CONFIG, seed=1)
        track_sequences([split.train], QUICK_TRACKER_CONFIG.replace(max_gap=0), seed=4)
    assert again[0] == 0
