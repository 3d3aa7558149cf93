"""The tracker tool layer: variants, the tracking capacity, one compile for many spans."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.errors import InputError
from jaxtrack.filters.base import fit_detections, run
from jaxtrack.filters.phd import phd_filter
from jaxtrack.filters.phd_tracker import VARIANTS, Context, PHDConfig, phd_params
from jaxtrack.io import SequenceInfo, load_sequence
from jaxtrack.io.motchallenge import pad_detections
from jaxtrack.pipelines.tracking import track_sequences
from tests.filters.phd_scenes import walking_scene


@pytest.fixture(scope="module")
def campus(mot15_root):
    return load_sequence(mot15_root / "TUD-Campus")


def _context(params):
    birth = params.birth_intensity._replace(magnitude=jnp.asarray(0.123))
    clutter = params.clutter_intensity._replace(magnitude=jnp.asarray(4.56))
    return Context(birth, clutter, {"birth": {"magnitude": 0.05}, "clutter": {"magnitude": 0.4}})


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_variants_take_the_parts_they_name(campus, variant):
    uniform = phd_params(PHDConfig(birth_rate=0.3, clutter_rate=2.0), campus.info)
    context = _context(uniform)
    params = phd_params(PHDConfig(birth_rate=0.3, clutter_rate=2.0), campus.info, context, variant)
    use = VARIANTS[variant]
    expected_birth = (
        0.123 if use.learned_birth else (0.05 if use.birth_magnitude_from_context else 0.3)
    )
    expected_clutter = (
        4.56 if use.learned_clutter else (0.4 if use.clutter_magnitude_from_context else 2.0)
    )
    assert float(params.birth_intensity.magnitude) == pytest.approx(expected_birth)
    assert float(params.clutter_intensity.magnitude) == pytest.approx(expected_clutter)


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_the_first_frame_intensity_goes_with_the_learned_births(campus, variant):
    uniform = phd_params(PHDConfig(initial_rate=0.7), campus.info)
    initial = uniform.birth_intensity._replace(magnitude=jnp.asarray(5.5))
    context = _context(uniform)._replace(initial=initial)
    params = phd_params(PHDConfig(initial_rate=0.7), campus.info, context, variant)
    if VARIANTS[variant].learned_birth:
        assert params.initial_intensity is initial
    else:
        assert float(params.initial_intensity.magnitude) == pytest.approx(0.7)
        assert float(params.initial_intensity.uniform_weight) == 1.0
    # a context without one (learned before it existed): uniform with initial_rate
    older = phd_params(PHDConfig(initial_rate=0.7), campus.info, _context(uniform), variant)
    assert float(older.initial_intensity.magnitude) == pytest.approx(0.7)


def test_unknown_variant_and_wrong_image_size(campus):
    context = _context(phd_params(PHDConfig(), campus.info))
    with pytest.raises(InputError, match="unknown variant"):
        phd_params(PHDConfig(), campus.info, context, "A7")
    wide = context.clutter._replace(upper=context.clutter.upper.at[0].set(1920.0))
    with pytest.raises(InputError, match="learned on 1920x480"):
        phd_params(PHDConfig(), campus.info, context._replace(clutter=wide), "GM")


def test_fit_detections_pads_and_cuts_to_the_tracking_capacity(campus):
    frames, slots = campus.detections.mask.shape
    fitted = fit_detections(campus.detections)
    assert slots < 16 and fitted.mask.shape == (frames, 16)
    np.testing.assert_array_equal(fitted.boxes[:, :slots], campus.detections.boxes)
    assert not fitted.mask[:, slots:].any()
    wide = pad_detections(campus.det_table, campus.first_frame, frames, 40)
    np.testing.assert_array_equal(fit_detections(wide).mask, fitted.mask)


def test_a_span_tracked_with_a_longer_one_gives_the_prefix_of_its_result(mot15_root):
    short = load_sequence(mot15_root / "TUD-Campus", frames=(1, 30))
    full = load_sequence(mot15_root / "TUD-Campus")
    config = PHDConfig(num_particles=256, births_per_detection=8, output="online")
    rows_short, rows_full = track_sequences([short, full], config, seed=3)
    assert len(rows_short.frames) > 20
    prefix = rows_full.frames <= 30
    np.testing.assert_array_equal(rows_short.frames, rows_full.frames[prefix])
    np.testing.assert_array_equal(rows_short.ids, rows_full.ids[prefix])
    np.testing.assert_allclose(rows_short.boxes, rows_full.boxes[prefix], rtol=1e-6)


def test_first_frame_births_use_the_initial_intensity():
    """A learned birth intensity far from both targets: the target in view on the first frame
    is still picked up (uniform initial intensity), the one appearing later is not born."""
    detections, truth = walking_scene(
        10,
        starts=[(100.0, 100.0), (400.0, 200.0)],
        velocities=[(2.0, 0.0), (-2.0, 0.0)],
        missed={t: {1} for t in range(4)},
        capacity=4,
    )
    info = SequenceInfo(name="walk", im_width=640, im_height=480, frame_rate=25.0, seq_length=10)
    uniform = phd_params(PHDConfig(), info)
    far_birth = uniform.birth_intensity._replace(
        uniform_weight=jnp.asarray(1e-3),
        weights=jnp.ones(1),
        means=jnp.array([[600.0, 0.0, 450.0, 0.0, 40.0, 100.0]]),
        covs=jnp.diag(jnp.array([10.0, 1.0, 10.0, 1.0, 5.0, 10.0]) ** 2)[None],
    )
    context = Context(far_birth, uniform.clutter_intensity, {})
    params = phd_params(PHDConfig(), info, context, "A1")
    filt = phd_filter(512, births_per_detection=16)
    _, out = run(filt, jax.random.PRNGKey(0), params, detections)
    centres = truth[:, :, 0] + 20.0  # true centre x of each target

    def found_near(out, target, frames):
        x = np.asarray(out.estimates.states[frames, :, 0])
        mask = np.asarray(out.estimates.mask[frames])
        return (mask & (np.abs(x - centres[frames, target, None]) < 10)).any(axis=-1)

    assert found_near(out, 0, slice(1, 10)).all()  # in view at the start: found
    assert not found_near(out, 1, slice(4, 10)).any()  # appears later, far from births
    # Without the uniform initial intensity, the first frame's births carry pi_u = 1e-3 of it.
    _, out_far = run(
        filt, jax.random.PRNGKey(0), params._replace(initial_intensity=far_birth), detections
    )
    assert float(out.mass[0]) > 100 * float(out_far.mass[0]) and float(out.mass[0]) > 0.1
