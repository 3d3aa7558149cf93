"""``split_capacity``: frames that fit in half the slots run on that half (``phd_step``).

Oracles: the float64 NumPy reference of the full step (``tests.filters.phd_reference``), the
full step itself (same outputs, padded slots included, up to rounding), and the births'
draws for all slots."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.filters.base import run
from jaxtrack.filters.births import draw_births
from jaxtrack.filters.phd import phd_filter
from jaxtrack.filters.phd_tracker import PHDConfig, phd_filter_of
from jaxtrack.types import PAD_BOX, Detections
from tests.filters.phd_reference import reference_of_state
from tests.filters.phd_scenes import walking_scene
from tests.filters.test_phd import TARGETS, _params, _state_with_targets, _to_float64

#: Eight slots: three real detections (two targets and a clutter box) in the first four.
BOXES = np.array(
    [[183.0, 106.0, 39.0, 92.0], [386.0, 266.0, 31.0, 69.0], [50.0, 60.0, 35.0, 80.0]]
    + [list(PAD_BOX)] * 5
)
SCORES = np.array([0.97, 0.8, 0.6, 0, 0, 0, 0, 0])
MASK = np.array([True, True, True, False, False, False, False, False])


def _frame(boxes, scores, mask) -> Detections:
    return Detections(boxes=jnp.asarray(boxes), scores=jnp.asarray(scores), mask=jnp.asarray(mask))


@functools.cache
def _step(split: bool, last_real: int = 2, extraction: str = "partition"):
    """One float64 step of the full or split filter from test_phd's state on an 8-slot frame
    whose last real detection is in slot ``last_real``; its outputs and the NumPy reference
    of the full step."""
    boxes, scores, mask = BOXES.copy(), SCORES.copy(), MASK.copy()
    if last_real != 2:  # move the clutter box to slot ``last_real``
        swap = [2, last_real]
        boxes[swap], scores[swap], mask[swap] = (
            boxes[swap[::-1]],
            scores[swap[::-1]],
            mask[swap[::-1]],
        )
    with jax.enable_x64(True):
        filt = phd_filter(
            32,
            births_per_detection=4,
            split_capacity=split,
            extraction=extraction,
            max_clusters=4,
            em_iterations=2,
        )
        params = _to_float64(_params(survival_prob=jnp.asarray(0.97)))
        state = _to_float64(_state_with_targets(filt, jax.random.key(0), TARGETS, 32))
        frame = _to_float64(_frame(boxes, scores, mask))
        new_state, info = jax.jit(filt.step)(jax.random.key(7), state, params, frame)
        reference = reference_of_state(jax.random.key(7), state, params, boxes, scores, mask, 4)
    return new_state, info, reference


def test_births_drawn_for_all_slots_keep_the_first_slots_draws():
    key = jax.random.key(3)
    measurements = jnp.asarray([[100.0, 50.0, 30.0, 60.0]] * 8)
    mask = jnp.arange(8) < 3
    args = (4, jnp.zeros(2), jnp.ones(2), jnp.asarray([0.1, 0.1, 0.1, 0.1]))
    full = draw_births(key, measurements, mask, *args)
    half = draw_births(key, measurements[:4], mask[:4], *args, draw_slots=8)
    np.testing.assert_array_equal(half.states, full.states[:16])
    np.testing.assert_array_equal(half.real, full.real[:16])
    with pytest.raises(ValueError, match="draw_slots"):
        draw_births(key, measurements, mask, *args, draw_slots=4)


@pytest.mark.parametrize("last_real", [2, 5], ids=["fits-in-half", "needs-all-slots"])
def test_split_step_matches_the_numpy_reference_of_the_full_step(last_real):
    new_state, info, reference = _step(True, last_real)
    np.testing.assert_allclose(info.log_likelihood, reference["log_likelihood"], rtol=1e-9)
    np.testing.assert_allclose(new_state.mass, reference["mass"], rtol=1e-9)
    np.testing.assert_allclose(new_state.particles, reference["resampled"], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(
        info.estimates.masses[np.asarray(reference["valid"])], reference["shares"], rtol=1e-9
    )
    assert info.estimates.mask.shape == (8,) and info.tracks.mask.shape == (8,)


@pytest.mark.parametrize("extraction", ["partition", "gmm"])
def test_split_step_gives_the_full_step_s_outputs_padded_slots_included(extraction):
    """Partition: one estimate per slot, padded back; GMM: cluster slots, whatever the
    frame's detection slots."""
    split_state, split_info, _ = _step(True, extraction=extraction)
    full_state, full_info, _ = _step(False, extraction=extraction)
    for split, full in zip(
        jax.tree.leaves((split_state, split_info)),
        jax.tree.leaves((full_state, full_info)),
        strict=True,
    ):
        assert split.shape == full.shape and split.dtype == full.dtype
        np.testing.assert_allclose(split, full, rtol=1e-9, atol=1e-9)


def test_split_run_tracks_like_the_full_run_and_keeps_gradients():
    """A float64 run of a walking scene (two targets in 8 slots): the same tracks and the
    same log-likelihood gradient in the clutter magnitude as the full run; under a vmap over
    magnitudes with shared detections, the single run's value."""
    detections, _ = walking_scene(20, [(100, 100), (400, 200)], [(3, 0), (-2, 1)], capacity=8)
    with jax.enable_x64(True):
        params = _to_float64(_params())
        frames = _to_float64(jax.tree.map(jnp.asarray, detections))
        magnitude = params.clutter_intensity.magnitude
        outputs = {}
        for split in (False, True):
            filt = phd_filter(128, births_per_detection=8, split_capacity=split)

            def loss(magnitude, filt=filt):
                clutter = params.clutter_intensity._replace(magnitude=magnitude)
                changed = params._replace(clutter_intensity=clutter)
                _, info = run(filt, jax.random.key(1), changed, frames)
                return jnp.sum(info.log_likelihood), info.tracks

            gradient = jax.jit(jax.value_and_grad(loss, has_aux=True))
            outputs[split] = gradient(magnitude)
        batched = jax.jit(jax.vmap(lambda m: loss(m)[0]))(jnp.stack([magnitude, 2 * magnitude]))
    (value, tracks), grad = outputs[False]
    (split_value, split_tracks), split_grad = outputs[True]
    np.testing.assert_allclose(batched[0], split_value, rtol=1e-9)
    np.testing.assert_allclose(split_value, value, rtol=1e-9)
    np.testing.assert_allclose(split_grad, grad, rtol=1e-7)
    assert np.isfinite(float(split_grad)) and float(split_grad) != 0
    np.testing.assert_array_equal(split_tracks.ids, tracks.ids)
    np.testing.assert_allclose(split_tracks.boxes, tracks.boxes, atol=1e-6)
    assert np.asarray(tracks.mask).sum() > 25  # both targets tracked most of the run


def test_the_configuration_selects_the_split_step():
    assert PHDConfig().frame_capacity == "full"
    full = phd_filter_of(PHDConfig())
    split = phd_filter_of(PHDConfig().replace(frame_capacity="split"))
    assert full.step.keywords["split_capacity"] is False
    assert split.step.keywords["split_capacity"] is True
