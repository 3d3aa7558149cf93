"""The tracker tool layer: variants, padding to a common shape, one compile for many spans."""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.errors import InputError
from jaxtrack.filters.phd_tracker import (
    VARIANTS,
    Context,
    pad_to,
    track_sequences,
    tracker_params,
)
from jaxtrack.io import load_sequence


@pytest.fixture(scope="module")
def campus(mot15_root):
    return load_sequence(mot15_root / "TUD-Campus")


def _context(params):
    birth = params.birth_intensity._replace(magnitude=jnp.asarray(0.123))
    clutter = params.clutter_intensity._replace(magnitude=jnp.asarray(4.56))
    return Context(birth, clutter, {"birth": {"magnitude": 0.05}, "clutter": {"magnitude": 0.4}})


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_variants_take_the_parts_they_name(campus, variant):
    uniform = tracker_params(campus.info, {"birth_rate": 0.3, "clutter_rate": 2.0})
    context = _context(uniform)
    params = tracker_params(campus.info, {"birth_rate": 0.3, "clutter_rate": 2.0}, context, variant)
    use = VARIANTS[variant]
    expected_birth = (
        0.123 if use.learned_birth else (0.05 if use.birth_magnitude_from_context else 0.3)
    )
    expected_clutter = (
        4.56 if use.learned_clutter else (0.4 if use.clutter_magnitude_from_context else 2.0)
    )
    assert float(params.birth_intensity.magnitude) == pytest.approx(expected_birth)
    assert float(params.clutter_intensity.magnitude) == pytest.approx(expected_clutter)


def test_unknown_variant_and_wrong_image_size(campus):
    context = _context(tracker_params(campus.info))
    with pytest.raises(InputError, match="unknown variant"):
        tracker_params(campus.info, None, context, "A7")
    wide = context.clutter._replace(upper=context.clutter.upper.at[0].set(1920.0))
    with pytest.raises(InputError, match="learned on 1920x480"):
        tracker_params(campus.info, None, context._replace(clutter=wide), "GM")


def test_pad_to_adds_empty_frames_and_slots(campus):
    padded = pad_to(campus.detections, 80, campus.detections.mask.shape[1] + 3)
    frames, slots = campus.detections.mask.shape
    assert padded.mask.shape == (80, slots + 3)
    np.testing.assert_array_equal(padded.boxes[:frames, :slots], campus.detections.boxes)
    assert not padded.mask[frames:].any() and not padded.mask[:, slots:].any()
    with pytest.raises(ValueError, match="cannot pad"):
        pad_to(campus.detections, 10, slots)


def test_a_span_tracked_with_a_longer_one_gives_the_prefix_of_its_result(mot15_root):
    short = load_sequence(mot15_root / "TUD-Campus", frames=(1, 30))
    full = load_sequence(mot15_root / "TUD-Campus")
    capacity = full.detections.mask.shape[1]
    short = dataclasses.replace(short, detections=pad_to(short.detections, 30, capacity))
    config = {"num_particles": 256, "births_per_detection": 8, "output": "online"}
    rows_short, rows_full = track_sequences([short, full], config, seed=3)
    assert len(rows_short.frames) > 20
    prefix = rows_full.frames <= 30
    np.testing.assert_array_equal(rows_short.frames, rows_full.frames[prefix])
    np.testing.assert_array_equal(rows_short.ids, rows_full.ids[prefix])
    np.testing.assert_allclose(rows_short.boxes, rows_full.boxes[prefix], rtol=1e-6)
