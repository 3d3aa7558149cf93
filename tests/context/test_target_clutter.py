"""The detections targets generate besides their own: offsets, estimates, a scene with known
truth, the context file's record and the variants that use it."""

from __future__ import annotations

import json

import numpy as np
import pytest

from jaxtrack.context.intensity import uniform_intensity
from jaxtrack.context.io import load_context, save_context
from jaxtrack.context.samples import clutter_samples_from_gt, clutter_samples_from_tracks
from jaxtrack.context.target_clutter import (
    METADATA_KEY,
    MIN_EVENTS,
    MIN_NOISE_STD,
    chance_events,
    extra_detection_offsets,
    fit_target_clutter,
    invalid_target_clutter,
    learn_target_clutter,
    target_clutter_line,
)
from jaxtrack.datasets.scene_bank import FAMILIES, generate_family_scene
from jaxtrack.errors import FileFormatError
from jaxtrack.filters.phd_tracker import VARIANTS, Context, PHDConfig, phd_params
from jaxtrack.io import MotTable
from jaxtrack.types import SequenceInfo


def test_offsets_are_relative_to_the_object_overlapping_most():
    # frame 1: two objects; the extra box overlaps the second one most
    objects = MotTable.from_arrays(
        [1, 1, 2], [1, 2, 1], [[0, 0, 20, 40], [30, 0, 20, 40], [0, 0, 10, 20]]
    )
    det = MotTable.from_arrays(
        [1, 1, 2],
        [-1, -1, -1],
        [[34, 4, 20, 40], [0, 0, 20, 40], [0, 0, 12, 16]],
    )
    offsets = extra_detection_offsets(det, objects, np.array([True, False, True]))
    # centre (44, 24) against (40, 20) for a 20 x 40 box; centre (6, 8), size 12 x 16
    # against (5, 10), 10 x 20
    np.testing.assert_allclose(offsets, [[0.2, 0.1, 0.0, 0.0], [0.1, -0.1, 0.2, -0.2]])


def test_fit_recovers_the_rate_and_spread_of_drawn_offsets():
    rng = np.random.default_rng(0)
    spread = np.array([0.4, 0.1, 0.6, 0.2])
    offsets = rng.normal(size=(4000, 4)) * spread
    fit = fit_target_clutter(offsets, 20_000, "gt")
    assert fit.learned and fit.rate == pytest.approx(0.2)
    np.testing.assert_allclose(fit.noise_std, spread, rtol=0.05)
    assert fit.as_dict() == {
        "rate": 0.2,
        "noise_std": list(fit.noise_std),
        "events": 4000,
        "objects": 20_000,
        "source": "gt",
        "chance": 0.0,
        "learned": True,
    }
    # the spread is the root mean square: a mean offset counts in it
    shifted = fit_target_clutter(offsets + np.array([0.3, 0, 0, 0]), 20_000, "gt")
    assert shifted.noise_std[0] == pytest.approx(0.5, rel=0.05)


def test_fit_learns_nothing_from_too_few_events_and_floors_the_spread():
    few = fit_target_clutter(np.full((MIN_EVENTS - 1, 4), 0.1), 100, "tracks")
    assert not few.learned and few.rate == 0.0 and few.noise_std is None
    assert few.events == MIN_EVENTS - 1
    assert not fit_target_clutter(np.full((MIN_EVENTS, 4), 0.1), 0, "gt").learned
    flat = fit_target_clutter(np.zeros((MIN_EVENTS, 4)), 100, "gt")
    assert flat.learned and flat.noise_std == (MIN_NOISE_STD,) * 4
    # the scene clutter expected among the events does not count towards the rate, and the
    # excess must stand 3 standard deviations (Poisson) above it: 30 - 9 = 21 >= 3 * 3, while
    # 40 - 26 = 14 < 3 * 5.1 is chance scatter
    some = fit_target_clutter(np.full((30, 4), 0.1), 100, "gt", chance=9.0)
    assert some.rate == pytest.approx(0.21) and some.chance == 9.0
    assert not fit_target_clutter(np.full((30, 4), 0.1), 100, "gt", chance=20.5).learned
    assert not fit_target_clutter(np.full((40, 4), 0.1), 100, "gt", chance=26.0).learned
    assert fit_target_clutter(np.full((40, 4), 0.1), 100, "gt", chance=24.0).learned
    assert chance_events(90, 0.9) == pytest.approx(10.0)


@pytest.mark.parametrize("seed", [0, 1])
def test_the_rate_is_the_simulated_detectors_share_of_badly_placed_boxes(seed):
    """The ``misplaced`` family's detector places a detected person's box badly with
    probability ``m`` and adds a second badly placed box with probability ``e``: per person and
    frame it gives ``(m + e) pD`` boxes that are not the person's well-placed one. Learned
    from the ground truth of frames 1-300, the rate is that within 10 % (0.186 vs 0.187 and
    0.184 vs 0.178 on seeds 0 and 1; boxes placed badly at IoU >= 0.5 count as the person's,
    and ones overlapping no person at 0.2 as clutter, which roughly cancel). A scene whose
    detector places every box well learns only the clutter that lands on people by chance."""
    scene = generate_family_scene("misplaced", seed)
    config = FAMILIES["misplaced"](seed)
    det = scene.det_table.select(scene.det_table.frames <= 300)
    gt = scene.gt_table.select(scene.gt_table.frames <= 300)
    clutter = clutter_samples_from_gt(det, gt, (1, 300))
    extra = clutter.left_out
    fit = learn_target_clutter(det, gt, extra, len(gt), "gt")
    expected = (
        config.misplaced_detection_prob + config.extra_detection_prob
    ) * config.detection_prob
    assert fit.rate == pytest.approx(expected, rel=0.1)
    # the spread is wider than the likelihood's (0.15, 0.08, 0.25, 0.15) in every dimension
    assert np.all(np.array(fit.noise_std) > [0.3, 0.1, 0.4, 0.2])

    # the scene's clutter that lands on people by chance is counted back into the clutter
    # magnitude (its coverage): on misplaced it is a few percent of the extra boxes
    chance = chance_events(clutter.count, clutter.coverage)
    with_chance = learn_target_clutter(det, gt, extra, len(gt), "gt", chance)
    assert 0 < chance < 0.1 * fit.events
    assert with_chance.rate == pytest.approx((fit.events - chance) / len(gt))

    # a detector that places every box well: what lands on people is the scene's clutter
    steady = generate_family_scene("flicker", seed)
    det = steady.det_table.select(steady.det_table.frames <= 300)
    gt = steady.gt_table.select(steady.gt_table.frames <= 300)
    clutter = clutter_samples_from_gt(det, gt, (1, 300))
    chance = chance_events(clutter.count, clutter.coverage)
    by_chance = learn_target_clutter(det, gt, clutter.left_out, len(gt), "gt", chance)
    assert 0 < by_chance.events < chance + MIN_EVENTS
    assert not by_chance.learned and by_chance.rate == 0.0


def test_the_detections_left_out_beside_tracks_are_unassociated_boxes_on_a_track():
    rows = MotTable.from_arrays([1], [7], [[0, 0, 10, 20]])
    det = MotTable.from_arrays(
        [1, 1, 1], [-1, -1, -1], [[0, 0, 10, 20], [4, 0, 10, 20], [100, 100, 10, 20]]
    )
    # IoU 1 (associated), 0.43 (extra), 0 (clutter)
    events = clutter_samples_from_tracks(det, rows, (1, 1))
    np.testing.assert_array_equal(events.left_out, [False, True, False])
    assert events.object_overlaps == 1 and events.count == 1


RECORD = fit_target_clutter(
    np.random.default_rng(1).normal(size=(50, 4)) * 0.3, 400, "gt"
).as_dict()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"rate": -0.1}, "rate must be a number in (0, 100]"),
        ({"rate": "a lot"}, "rate must be a number"),
        ({"noise_std": [0.1, 0.2]}, "noise_std must be a list of 4 numbers"),
        ({"noise_std": [0.1, 0.2, 0.0, 0.3]}, "noise_std values must lie in (0, 100]"),
        ({"noise_std": [0.1, 0.2, float("nan"), 0.3]}, "noise_std values must lie in (0, 100]"),
    ],
)
def test_a_context_file_with_a_bad_record_is_refused_naming_it(tmp_path, change, message):
    path = tmp_path / "context.npz"
    birth = uniform_intensity(0.1, [0.0] * 6, [1.0] * 6)
    clutter = uniform_intensity(1.0, [0.0] * 4, [1.0] * 4)
    save_context(path, birth, clutter, {METADATA_KEY: RECORD})
    assert load_context(path)[2][METADATA_KEY] == RECORD
    assert invalid_target_clutter(RECORD) is None
    bad = {**RECORD, **change}
    assert message in invalid_target_clutter(bad)
    save_context(path, birth, clutter, {METADATA_KEY: bad})
    with pytest.raises(FileFormatError, match=f"{path.name}.*target_clutter"):
        load_context(path)
    # a record that learned nothing is valid whatever else it holds
    assert invalid_target_clutter({"learned": False, "rate": 0.0}) is None
    assert "JSON object" in invalid_target_clutter([1, 2])


def test_variants_with_learned_clutter_get_the_target_clutter():
    info = SequenceInfo("s", 100, 768, 576, 10.0)
    birth = uniform_intensity(0.1, [0.0, -5, 0, -5, 1, 1], [768.0, 5, 576, 5, 300, 500])
    clutter = uniform_intensity(1.0, [0.0, 0, 1, 1], [768.0, 576, 300, 500])
    context = Context(birth, clutter, {METADATA_KEY: RECORD})
    for variant, use in VARIANTS.items():
        params = phd_params(PHDConfig(), info, context, variant)
        rate = float(params.target_clutter.rate)
        if use.learned_clutter:
            assert rate == pytest.approx(RECORD["rate"])
            np.testing.assert_allclose(
                params.target_clutter.noise_std, RECORD["noise_std"], rtol=1e-6
            )
        else:
            assert rate == 0.0, variant
    # an older context (no record) and no context: the paper's model
    older = Context(birth, clutter, {})
    assert float(phd_params(PHDConfig(), info, older, "GM").target_clutter.rate) == 0.0
    assert float(phd_params(PHDConfig(), info).target_clutter.rate) == 0.0


def test_the_learn_context_line_says_what_was_learned():
    line = target_clutter_line(RECORD)
    assert line.startswith(
        "target clutter from gt: 50 detections beside 400 object boxes, 0.0 of them expected "
        "from the scene's clutter (0.125"
    )
    assert "no significant excess" in target_clutter_line(
        fit_target_clutter(np.zeros((3, 4)), 9, "gt").as_dict()
    )
    assert "older context" in target_clutter_line(None)
    json.dumps(RECORD)  # a metadata record is plain JSON
