"""The low level's noise estimated from detections (jaxtrack.filters.hier_low_noise).

Oracles: detections drawn from the low level's own model with known noise (the estimate must
find it, and the gate calibration must stay at 1 on Gaussian data), a Monte Carlo of the
model's second differences (the process coefficients), Student-t measurement noise (heavy
tails: the calibration must widen the gate until it holds its share), and hand-made links.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from jaxtrack.filters.hier_low_defaults import DEFAULT_NOISE, low_params, steady_state
from jaxtrack.filters.hier_low_noise import (
    estimate_box_noise,
    gate_calibration,
    link_chains,
    process_coefficients,
    second_differences,
)
from jaxtrack.filters.hierarchical_tracker import (
    HierarchicalConfig,
    HierarchicalContext,
    build_hierarchical,
    low_noise,
)
from jaxtrack.types import Detections
from tests.filters.test_cmt import INFO, SIZE

HEIGHT = 100.0
#: Unit-scale truth of the drawn scenes: acceleration, size step, measurement noise.
ACCELERATION = 0.012
SIZE_STEP = 0.015
MEASUREMENT = np.array([0.03, 0.04, 0.03, 0.05])


def drawn_detections(seed, num_frames=30, num_targets=150, noise="gauss", measurement=MEASUREMENT):
    """Targets far apart (one per row of the image) following the low level's model: centre
    at constant velocity with white acceleration, size a random walk, measurement noise
    relative to the true height (``"gauss"`` or Student t with 3 dof scaled to the same
    standard deviation)."""
    rng = np.random.default_rng(seed)
    boxes = np.zeros((num_frames, num_targets, 4))
    for j in range(num_targets):
        cx, cy, vx, vy = 200.0, 150.0 + 400.0 * j, 0.0, 0.0
        w, h = 0.4 * HEIGHT, HEIGHT
        for t in range(num_frames):
            ax, ay = rng.normal(0.0, ACCELERATION * h, 2)
            cx, vx = cx + vx + ax / 2, vx + ax
            cy, vy = cy + vy + ay / 2, vy + ay
            w, h = w + rng.normal(0.0, SIZE_STEP * h), h + rng.normal(0.0, SIZE_STEP * h)
            if noise == "gauss":
                e = rng.normal(0.0, 1.0, 4)
            else:
                e = rng.standard_t(3, 4) / np.sqrt(3.0)
            z = np.array([cx, cy, w, h]) + e * measurement * h
            boxes[t, j] = (z[0] - z[2] / 2, z[1] - z[3] / 2, z[2], z[3])
    return boxes, np.ones((num_frames, num_targets), bool)


def test_process_coefficients_match_a_monte_carlo_of_the_model():
    """``Var d_k`` per unit process variance, from simulated noise-free tracks."""
    rng = np.random.default_rng(0)
    n, frames = 20000, 8
    a = rng.normal(size=(n, frames))
    x, v = np.zeros(n), np.zeros(n)
    xs = []
    for t in range(frames):
        x, v = x + v + a[:, t] / 2, v + a[:, t]
        xs.append(x)
    walk = np.cumsum(rng.normal(size=(n, frames)), axis=1)
    xs = np.stack(xs, 1)
    for k in (1, 2, 3):
        t = 3
        centre = np.var(xs[:, t + k] - 2 * xs[:, t] + xs[:, t - k])
        size = np.var(walk[:, t + k] - 2 * walk[:, t] + walk[:, t - k])
        expected = process_coefficients(k)
        assert centre == pytest.approx(expected[0], rel=0.05)
        assert size == pytest.approx(expected[2], rel=0.05)


def test_the_estimate_finds_the_noise_of_drawn_gaussian_detections():
    boxes, mask = drawn_detections(1)
    noise = estimate_box_noise(boxes, mask, DEFAULT_NOISE["box"])
    assert min(noise.samples) > 1500
    # Gaussian data: the calibration leaves the fit as it is (within sampling noise).
    assert noise.calibration == pytest.approx(1.0, abs=0.08)
    np.testing.assert_allclose(noise.measurement_std, MEASUREMENT, rtol=0.15)
    np.testing.assert_allclose(noise.process_std[:2], ACCELERATION, rtol=0.3)
    # The size's step is small beside its measurement noise (2k q^2 against 6 r^2): weakly
    # identified, so only its order of magnitude is checked.
    np.testing.assert_allclose(noise.process_std[2:], SIZE_STEP, rtol=0.7)
    # A new track: its position and size at least measured, its velocity at least the prior,
    # everything at least 1.5x the steady state (so the low level accepts the noise).
    initial = np.asarray(noise.initial_std)
    assert np.all(initial[[0, 2, 4, 5]] >= np.asarray(noise.measurement_std) - 1e-12)
    assert min(initial[1], initial[3]) >= DEFAULT_NOISE["box"][2][1]
    settled, _ = steady_state("box", noise.process_std, noise.measurement_std)
    assert np.all(initial >= 1.5 * np.sqrt(np.diag(settled)) - 1e-12)
    low_params("box", *noise[:3])  # raises when |S_k| would not fall while updating


def test_heavy_tails_widen_the_gate_until_it_holds_its_share():
    boxes, mask = drawn_detections(2, noise="student")
    noise = estimate_box_noise(boxes, mask, DEFAULT_NOISE["box"])
    assert noise.calibration > 1.2
    # After the calibration, the lag-1 differences inside the 99 % gate are 99 % of them.
    diffs, _ = second_differences(boxes, mask)
    variance = 6 * np.square(noise.measurement_std) + process_coefficients(1) * np.square(
        noise.process_std
    )
    inside = np.mean(np.sum(diffs[1] ** 2 / variance, axis=1) <= chi2.ppf(0.99, 4))
    assert inside == pytest.approx(0.99, abs=0.004)


def test_gate_calibration_is_the_quantile_ratio_and_never_shrinks():
    rng = np.random.default_rng(3)
    x = rng.normal(0.0, 2.0, (200000, 4))
    assert gate_calibration(x, np.full(4, 4.0)) == pytest.approx(1.0, abs=0.02)
    assert gate_calibration(x, np.full(4, 1.0)) == pytest.approx(2.0, rel=0.02)
    assert gate_calibration(x, np.full(4, 16.0)) == 1.0


def test_links_are_mutual_best_matches_above_the_iou():
    boxes = np.array(
        [
            [[0, 0, 10, 10], [50, 0, 10, 10], [0, 0, 0, 0]],
            [[1, 0, 10, 10], [100, 0, 10, 10], [2, 0, 10, 10]],
        ],
        float,
    )
    mask = np.array([[True, True, False], [True, True, True]])
    nxt = link_chains(boxes, mask)
    # detection 0 -> 0 (IoU 0.82 beats 0.67 of slot 2); the box at x=50 has no partner.
    np.testing.assert_array_equal(nxt, [[0, -1, -1], [-1, -1, -1]])


def test_too_few_detections_keep_the_defaults():
    boxes, mask = drawn_detections(4, num_frames=12, num_targets=3)
    noise = estimate_box_noise(boxes, mask, DEFAULT_NOISE["box"])
    assert noise.samples == (0, 0, 0) and noise.calibration == 1.0
    assert (noise.process_std, noise.measurement_std, noise.initial_std) == DEFAULT_NOISE["box"]


def _detections(boxes, mask, scores=None):
    scores = np.ones(mask.shape) if scores is None else scores
    return Detections(boxes.astype(np.float32), scores.astype(np.float32), mask)


def test_the_tracker_uses_the_estimate_unless_told_otherwise():
    boxes, mask = drawn_detections(5, num_frames=120, num_targets=1)
    detections = _detections(boxes, mask)
    background = np.full((SIZE[1], SIZE[0], 3), 128, np.uint8)

    def context(config):  # what the pipelines give the tracker
        return HierarchicalContext(background, low_noise(config, detections)[0])

    estimated = HierarchicalConfig(variant="managed")
    noise, line = low_noise(estimated, detections)
    assert "estimated from" in line
    expected = estimate_box_noise(detections.boxes, mask, DEFAULT_NOISE["box"])
    assert noise == expected[:3]
    _, params = build_hierarchical(estimated, INFO, context(estimated))
    np.testing.assert_allclose(params.low.measurement_std, expected.measurement_std, rtol=1e-6)
    apriori, ellipse = estimated.replace(noise="default"), estimated.replace(measurement="ellipse")
    for config, ctx in (
        (apriori, context(apriori)),
        (estimated, background),  # a background image alone: no noise given, the prior
        (ellipse, context(ellipse)),
    ):
        _, params = build_hierarchical(config, INFO, ctx)
        default = DEFAULT_NOISE[config.measurement][1]
        np.testing.assert_allclose(params.low.measurement_std, default, rtol=1e-6)
    assert "a priori" in low_noise(estimated.replace(noise="default"), detections)[1]


def test_the_score_threshold_drops_detections_before_the_estimate():
    boxes, mask = drawn_detections(6, num_frames=120, num_targets=1)
    scores = np.ones(mask.shape)
    scores[::2] = 0.2  # every other frame below the threshold: no chains at all
    config = HierarchicalConfig(variant="managed", min_score=0.5)
    _, line = low_noise(config, _detections(boxes, mask, scores))
    assert "too few linked detections" in line
    _, line = low_noise(config.replace(min_score=0.0), _detections(boxes, mask, scores))
    assert "estimated from" in line


def test_auto_keeps_the_prior_on_the_toolkits_blobs():
    boxes, mask = drawn_detections(7)
    detections = _detections(boxes, mask)
    auto = HierarchicalConfig(variant="managed")
    assert auto.noise == "auto"
    noise, line = low_noise(auto, detections, blobs=True)
    assert noise == DEFAULT_NOISE["box"] and "blobs" in line
    assert "estimated from" in low_noise(auto.replace(noise="estimated"), detections, True)[1]
    background = np.full((SIZE[1], SIZE[0], 3), 128, np.uint8)
    _, params = build_hierarchical(auto, INFO, HierarchicalContext(background, noise))
    np.testing.assert_allclose(params.low.measurement_std, DEFAULT_NOISE["box"][1], rtol=1e-6)
