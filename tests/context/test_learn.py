"""Context learning on the synthetic default scene: the learned intensities match the truth.

One 400-frame scene (seed 5) is learned once from ground-truth events (about 25 births and
750 clutter detections; ~15 s on 2 CPU cores); a tracker-based run is in
``tests/test_cli_learn_context.py``.
"""

from __future__ import annotations

import dataclasses
import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.boxes import iou_matrix
from jaxtrack.context.intensity import Intensity, log_density, log_intensity, sample
from jaxtrack.context.learn import (
    BIRTH_EPOCHS,
    CLUTTER_EPOCHS,
    SNAPSHOT_FRACTIONS,
    marginal,
    uniform_volumes,
)
from jaxtrack.context.samples import matched_detections
from jaxtrack.datasets import SceneConfig, generate_scene
from jaxtrack.datasets.synthetic import write_scene
from jaxtrack.errors import InputError
from jaxtrack.io import load_sequence
from jaxtrack.pipelines.context import learn_context

FRAMES = 400


@pytest.fixture(scope="module")
def scene():
    return generate_scene(5, dataclasses.replace(SceneConfig(), num_frames=FRAMES))


@pytest.fixture(scope="module")
def scene_dir(scene, tmp_path_factory):
    return write_scene(scene, tmp_path_factory.mktemp("learn") / "SYN-5")


@pytest.fixture(scope="module")
def learned(scene_dir):
    return learn_context(scene_dir, (1, FRAMES), birth_from="gt", clutter_from="gt")


@pytest.fixture(scope="module")
def paper(scene_dir):
    """The paper's recursion alone (no held-out selection of settings and shares)."""
    return learn_context(scene_dir, (1, FRAMES), birth_from="gt", clutter_from="gt", heldout=False)


def _centre_map(intensity: Intensity, dims, step=2.0):
    """Centre-marginal intensity on a grid over the default 768x576 image."""
    columns = np.arange(0.0, 768.0, step)
    rows = np.arange(0.0, 576.0, step)
    points = np.stack(np.meshgrid(columns, rows), axis=-1)
    values = np.exp(np.asarray(log_intensity(marginal(intensity, dims), points), np.float64))
    return columns, rows, values


def _local_maxima(values):
    """Boolean map of points above all eight neighbours."""
    padded = np.pad(values, 1, constant_values=-np.inf)
    centre = padded[1:-1, 1:-1]
    peak = np.ones_like(values, bool)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                shifted = padded[
                    1 + di : padded.shape[0] - 1 + di, 1 + dj : padded.shape[1] - 1 + dj
                ]
                peak &= centre > shifted
    return peak


def test_clutter_density_peaks_at_every_clutter_source(learned):
    columns, rows, values = _centre_map(learned.clutter, (0, 1))
    uniform_level = float(learned.clutter.magnitude) / (768 * 576)
    peaks = _local_maxima(values) & (values > 20 * uniform_level)
    peak_rows, peak_columns = np.nonzero(peaks)
    for source in SceneConfig().clutter_sources:
        distance = np.hypot(
            columns[peak_columns] - source.centre[0], rows[peak_rows] - source.centre[1]
        )
        assert distance.size and distance.min() < 20.0, source.name


def _in_zone_share(intensity):
    draws = np.asarray(sample(jax.random.PRNGKey(0), intensity, 20000), np.float64)
    in_zone = np.zeros(draws.shape[0], bool)
    for zone in SceneConfig().zones:
        # a zone: its birth positions' 3-sigma ellipse, widened by 20 px
        semi_axes = 3 * np.asarray(zone.position_std) + 20.0
        offset = (draws[:, [0, 2]] - np.asarray(zone.centre)) / semi_axes
        in_zone |= np.sum(offset**2, axis=1) <= 1.0
    return in_zone.mean()


def test_birth_density_puts_most_mass_in_the_entry_zones(learned, paper):
    # the paper's recursion: nearly all its mass; with the held-out check, ~25 births leave
    # a fall-back share (uniform + background) for births where none was seen
    assert _in_zone_share(paper.birth) > 0.8
    held = learned.metadata["birth"]["heldout"]
    fallback = held["uniform_weight"] + held["background_weight"]
    assert 0.0 < fallback < 0.35
    assert _in_zone_share(learned.birth) > 0.6
    assert held["heldout_gain"] > 3.0  # far better than uniform on unseen births
    # the zones cover a few percent of the image: a uniform density would fail this test
    uniform = np.asarray(
        sample(jax.random.PRNGKey(1), uniform_volumes(768, 576, 10.0)[0], 20000), np.float64
    )
    assert (
        np.mean(
            np.any(
                [
                    np.sum(
                        ((uniform[:, [0, 2]] - z.centre) / (3 * np.asarray(z.position_std) + 20))
                        ** 2,
                        1,
                    )
                    <= 1
                    for z in SceneConfig().zones
                ],
                axis=0,
            )
        )
        < 0.2
    )


def test_birth_events_are_the_true_births(scene, learned):
    births = learned.birth_samples
    truth = (scene.birth_frames >= 6) & (scene.birth_frames < FRAMES)
    assert births.count == int(np.sum(truth))
    np.testing.assert_array_equal(births.frames, scene.birth_frames[truth])
    # same frame order; positions and sizes exact up to rounding
    true_states = scene.birth_states[truth]
    np.testing.assert_allclose(
        births.values[:, [0, 2, 4, 5]], true_states[:, [0, 2, 4, 5]], atol=0.01
    )
    # speeds: the SDV motion noise changes them by ~0.1 px/frame per frame over the 5 boxes
    speed_error = np.abs(births.values[:, [1, 3]] - true_states[:, [1, 3]])
    assert speed_error.max() < 0.6 and np.median(speed_error) < 0.1
    assert learned.metadata["birth"]["magnitude"] == pytest.approx(births.count / (FRAMES - 5))


def test_clutter_events_are_the_false_detections(scene, learned):
    clutter = learned.clutter_samples
    true_clutter = scene.det_table.select(scene.is_clutter)
    true_set = {tuple(np.round(row, 3)) for row in np.c_[true_clutter.frames, true_clutter.boxes]}
    centres = clutter.values
    boxes = np.c_[centres[:, :2] - centres[:, 2:] / 2, centres[:, 2:]]
    found = [tuple(np.round(row, 3)) in true_set for row in np.c_[clutter.frames, boxes]]
    precision = np.mean(found)
    recall = np.sum(found) / len(true_set)
    # the simulated detector places its boxes of people well: every event is true clutter;
    # the true clutter missed is exactly the clutter that happens to overlap a person by
    # IoU >= 0.2 (left out as a person's badly placed detection)
    assert precision == 1.0 and recall > 0.95
    on_people = 0
    for frame, box in zip(true_clutter.frames, true_clutter.boxes, strict=True):
        people = scene.gt_table.boxes[scene.gt_table.frames == frame]
        on_people += bool(len(people)) and iou_matrix(box[None], people).max() >= 0.2
    assert on_people == len(true_set) - np.sum(found) == clutter.object_overlaps > 0
    assert learned.metadata["clutter"]["object_overlaps"] == on_people
    # the magnitude counts the clutter left out on people back: the coverage is 1 - the chance
    # that a clutter box lands on a person; the truth here: 786 false detections in 400 frames
    meta = learned.metadata["clutter"]
    assert meta["coverage"] == clutter.coverage < 1
    assert meta["magnitude"] == pytest.approx(clutter.count / (clutter.coverage * FRAMES))
    true_rate = len(true_set) / FRAMES
    assert abs(meta["magnitude"] - true_rate) < 0.02 * true_rate
    assert abs(meta["magnitude"] - true_rate) < abs(clutter.count / FRAMES - true_rate) / 3


@pytest.mark.parametrize("kind", ["birth", "clutter"])
def test_intensities_integrate_to_their_magnitudes_over_the_volume(learned, kind):
    intensity = getattr(learned, kind)
    key_choice, key_uniform, key_density = jax.random.split(jax.random.PRNGKey(2), 3)
    # importance sampling from q = (uniform + density) / 2: the ratio intensity / q <= 2 lambda
    num = 50_000
    uniform = jax.random.uniform(
        key_uniform, (num, intensity.dim), minval=intensity.lower, maxval=intensity.upper
    )
    points = jnp.where(
        jax.random.bernoulli(key_choice, 0.5, (num, 1)),
        uniform,
        sample(key_density, intensity, num),
    )
    log_volume = jnp.sum(jnp.log(intensity.upper - intensity.lower))
    log_q = jnp.logaddexp(-log_volume, log_density(intensity, points)) + jnp.log(0.5)
    inside = jnp.all((points >= intensity.lower) & (points <= intensity.upper), axis=-1)
    ratio = jnp.where(inside, jnp.exp(log_intensity(intensity, points) - log_q), 0.0)
    estimate = float(jnp.mean(ratio))
    # the measured events per frame, not the stored magnitude lambda / P(V)
    assert estimate == pytest.approx(learned.metadata[kind]["magnitude"], rel=0.02)


def test_volumes_are_the_trackers_uniform_volumes(learned):
    uniform_birth, uniform_clutter = uniform_volumes(768, 576, 10.0)
    for learned_intensity, uniform in (
        (learned.birth, uniform_birth),
        (learned.clutter, uniform_clutter),
    ):
        np.testing.assert_allclose(learned_intensity.lower, uniform.lower)
        np.testing.assert_allclose(learned_intensity.upper, uniform.upper)
    # birth velocities span 0.4 H / fps pixels per frame
    assert float(learned.birth.upper[1]) == pytest.approx(0.4 * 576 / 10.0)


def test_grids_are_pruned_and_snapshots_record_the_evolution(paper):
    learned = paper
    for snapshots, epochs, grid_size in (
        (learned.birth_snapshots, BIRTH_EPOCHS, 120),
        (learned.clutter_snapshots, CLUTTER_EPOCHS, 224),
    ):
        assert len(snapshots) == len(SNAPSHOT_FRACTIONS) + 1
        counts = [snapshot.num_samples for snapshot in snapshots]
        assert counts == sorted(counts) and counts[0] == 0
        assert [snapshot.samples.shape[0] for snapshot in snapshots] == counts
        assert int(np.sum(snapshots[0].state.alive)) == grid_size
        assert float(snapshots[0].state.uniform_weight) == 1.0
        assert snapshots[-1].epochs == epochs
        assert int(np.sum(snapshots[-1].state.alive)) < grid_size / 10
    meta = learned.metadata
    assert meta["birth"]["epochs"] == BIRTH_EPOCHS and meta["clutter"]["epochs"] == CLUTTER_EPOCHS
    assert meta["birth"]["source"] == "gt" and meta["frames"] == [1, FRAMES]
    for kind in ("birth", "clutter"):
        assert 0.9 < meta[kind]["volume_mass"] <= 1.0
        assert meta[kind]["heldout"] is None


def test_heldout_check_selects_a_candidate_and_records_it(learned):
    for kind, grid_size, background_size in (("birth", 120, 30), ("clutter", 224, 56)):
        meta = learned.metadata[kind]
        held = meta["heldout"]
        assert held["num_folds"] == 4 and len(held["candidate_scores"]) == 3
        assert held["candidate_scores"][held["candidate"]] == max(held["candidate_scores"])
        assert held["heldout_loglik"] > held["heldout_loglik_uniform"]
        assert meta["uniform_weight"] == pytest.approx(held["uniform_weight"])
        assert 0 < meta["components_alive"] <= grid_size + background_size


def test_marginal_matches_numerical_integration():
    intensity = Intensity(
        magnitude=jnp.asarray(2.0),
        uniform_weight=jnp.asarray(0.3),
        lower=jnp.array([0.0, -5.0, 0.0]),
        upper=jnp.array([10.0, 5.0, 8.0]),
        weights=jnp.array([0.7, 0.3]),
        means=jnp.array([[3.0, 1.0, 4.0], [7.0, -1.0, 2.0]]),
        covs=jnp.array(
            [[[1.0, 0.5, 0.2], [0.5, 2.0, 0.3], [0.2, 0.3, 1.5]], np.diag([0.5, 1.0, 0.8])]
        ),
    )
    axis = np.linspace(-15.0, 15.0, 3001)
    query = np.array([[3.5, 4.0], [6.0, 2.5], [1.0, 7.0]])
    full = np.stack(
        [np.stack([np.full_like(axis, q[0]), axis, np.full_like(axis, q[1])], -1) for q in query]
    )
    dense = np.exp(np.asarray(log_intensity(intensity, jnp.asarray(full)), np.float64))
    # the uniform term is 1/V everywhere: integrate it over the volume only
    uniform_part = float(intensity.magnitude * intensity.uniform_weight) / 800.0
    inside = (axis >= -5) & (axis <= 5)
    gaussian_part = dense - uniform_part
    integral = np.trapezoid(gaussian_part, axis, axis=1) + uniform_part * np.sum(inside) * (
        axis[1] - axis[0]
    )
    expected = np.exp(np.asarray(log_intensity(marginal(intensity, (0, 2)), jnp.asarray(query))))
    np.testing.assert_allclose(integral, expected, rtol=2e-3)


def test_errors_for_bad_input(scene_dir, tmp_path):
    with pytest.raises(InputError, match="birth source"):
        learn_context(scene_dir, (1, 100), birth_from="nowhere")
    with pytest.raises(InputError, match="frame span"):
        learn_context(scene_dir, (1, FRAMES + 1), birth_from="gt")
    with pytest.raises(InputError, match="warm-up"):
        learn_context(scene_dir, (1, 5), birth_from="gt")
    with pytest.raises(InputError, match="no birth events"):
        learn_context(scene_dir, (1, 8), birth_from="gt")
    sequence = load_sequence(scene_dir, frames=(1, 50))
    with pytest.raises(InputError, match="loaded sequence"):
        learn_context(sequence, (1, 50), birth_from="gt")
    no_gt = dataclasses.replace(sequence, gt_table=None, ground_truth=None)
    with pytest.raises(InputError, match="no ground truth"):
        learn_context(no_gt, birth_from="tracks", clutter_from="gt")


def test_score_calibration_is_the_target_share_of_the_scores(scene_dir, learned):
    """The learned p(target | s) against the share of gt-matched detections in score bins
    (an independent binned estimate; bins of at least 200 detections)."""
    record = learned.metadata["score_calibration"]
    assert record["learned"] and record["source"] == "gt"
    sequence = load_sequence(scene_dir, frames=(1, FRAMES))
    targets = matched_detections(sequence.det_table, sequence.gt_table, (1, FRAMES))
    scores = sequence.det_table.confs
    assert record["detections"] == scores.size
    edges = np.quantile(scores, np.linspace(0, 1, 9))
    checked = 0
    for low, high in itertools.pairwise(edges):
        inside = (scores >= low) & (scores < high)
        if inside.sum() < 200:
            continue
        learned_share = np.interp(scores[inside], record["scores"], record["probabilities"]).mean()
        assert learned_share == pytest.approx(targets[inside].mean(), abs=0.05), (low, high)
        checked += 1
    assert checked >= 5
