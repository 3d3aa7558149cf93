"""Motion models: tracklet cutting, per-cell fitting, GP algebra against NumPy/SciPy."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from jaxtrack.context.motion_models import (
    Tracklets,
    condition_cells,
    cut_tracklets,
    fit_motion_models,
    log_marginal_likelihood,
    tracklet_cells,
    tracklet_inputs,
)
from jaxtrack.errors import InputError
from jaxtrack.types import MotTable


def table(frames, ids, feet):
    """Boxes 10 x 20 whose foot points are ``feet``."""
    feet = np.asarray(feet, float)
    boxes = np.c_[feet[:, 0] - 5, feet[:, 1] - 20, np.full((len(feet), 2), [10.0, 20.0])]
    return MotTable.from_arrays(frames, ids, boxes)


def reference_tracklets(frames, ids, feet, length):
    """Loop: each id's runs of consecutive frames, cut into windows of ``length + 1``."""
    windows = []
    for identity in sorted(set(ids)):
        rows = sorted(
            (f, tuple(p)) for f, i, p in zip(frames, ids, feet, strict=True) if i == identity
        )
        runs = [[rows[0]]]
        for previous, row in itertools.pairwise(rows):
            if row[0] == previous[0] + 1:
                runs[-1].append(row)
            else:
                runs.append([row])
        for run in runs:
            for start in range(0, len(run) - length, length + 1):
                windows.append([p for _, p in run[start : start + length + 1]])
    return np.array(windows, float).reshape(-1, length + 1, 2)


def test_cut_tracklets_matches_a_loop_with_gaps_and_unsorted_rows():
    rng = np.random.default_rng(0)
    frames = np.r_[1:10, 11:19, 3:13]  # id 1 has a gap between 9 and 11
    ids = np.r_[np.full(17, 1), np.full(10, 2)]
    feet = rng.uniform(0, 100, (frames.size, 2))
    order = rng.permutation(frames.size)
    cut = cut_tracklets(table(frames[order], ids[order], feet[order]), length=3)
    expected = reference_tracklets(frames, ids, feet, 3)
    assert cut.points.shape == (expected.shape[0], 3, 2) == (2 + 2 + 2, 3, 2)
    np.testing.assert_allclose(cut.points, expected[:, :3])
    np.testing.assert_allclose(cut.next_points, expected[:, 3])


def test_cut_tracklets_rejects_a_repeated_id_in_a_frame_and_a_short_length():
    bad = table([1, 2, 2], [1, 1, 1], [[0, 0], [1, 0], [2, 0]])
    with pytest.raises(InputError, match="table: id 1 has two boxes in frame 2"):
        cut_tracklets(bad)
    with pytest.raises(InputError, match="length must be >= 2"):
        cut_tracklets(bad, length=1)


def test_tracklet_inputs_and_cells():
    points = np.array([[[0.0, 0], [1, 2], [3, 3]]])
    np.testing.assert_allclose(tracklet_inputs(points), [[1, 2, 2, 1]])
    cells = tracklet_cells(np.array([[5.0, 5], [25, 5], [5, 25], [-3, 99]]), 10.0, np.array([3, 2]))
    np.testing.assert_array_equal(cells, [0, 1, 4, 4])  # (row 2, column 0) after clipping


def rbf(a, b, scale, amplitude):
    return amplitude * np.exp(-((a[:, None] - b[None]) ** 2).sum(-1) / (2 * scale**2))


def test_condition_and_likelihood_match_numpy_and_scipy_with_padding():
    rng = np.random.default_rng(1)
    inputs = rng.normal(size=(3, 6, 4))
    residuals = rng.normal(size=(3, 6, 2))
    mask = np.array([[1, 1, 1, 1, 0, 0], [1] * 6, [0] * 6], bool)
    scale, amplitude, noise = 1.3, 0.7, 0.2
    cholesky, alpha = condition_cells(inputs, residuals, mask, scale, amplitude, noise)
    total = 0.0
    for cell in range(3):
        real = mask[cell]
        gram = rbf(inputs[cell, real], inputs[cell, real], scale, amplitude) + noise * np.eye(
            real.sum()
        )
        np.testing.assert_allclose(
            alpha[cell, real], np.linalg.solve(gram, residuals[cell, real]), rtol=1e-4, atol=1e-5
        )
        np.testing.assert_allclose(alpha[cell, ~real], 0.0)
        np.testing.assert_allclose(
            np.asarray(cholesky[cell, ~real])[:, ~real], np.eye((~real).sum())
        )
        for axis in range(2) if real.any() else ():
            total += multivariate_normal(np.zeros(real.sum()), gram).logpdf(
                residuals[cell, real, axis]
            )
    likelihood = log_marginal_likelihood(residuals, mask, cholesky, alpha)
    np.testing.assert_allclose(float(likelihood), total, rtol=1e-5)


def moving_tracklets(num, start, velocity, rng):
    """``num`` tracklets of 5 points moving at ``velocity`` from near ``start``."""
    steps = np.arange(6)[None, :, None] * np.asarray(velocity)
    points = np.asarray(start) + rng.normal(0, 1, (num, 1, 2)) + steps
    return points


def test_fit_flags_fallback_cells_caps_size_and_drops_still_tracklets():
    rng = np.random.default_rng(2)
    busy = moving_tracklets(100, [20, 20], [1.0, 0.5], rng)  # cell 0: 100 tracklets
    sparse = moving_tracklets(3, [70, 20], [1.0, 0.0], rng)  # cell 1: too few
    still = moving_tracklets(50, [20, 70], [0.1, 0.0], rng)  # cell 2: not informative
    windows = np.concatenate([busy, sparse, still])
    tracklets = Tracklets(windows[:, :5], windows[:, 5])
    models = fit_motion_models(
        tracklets, 100, 100, cell_size=50, min_displacement=2.0, min_tracklets=5, max_points=16
    )
    np.testing.assert_array_equal(models.fitted, [True, False, False, False])
    np.testing.assert_array_equal(models.grid, [2, 2])
    assert models.inputs.shape == (4, 16, 8) and int(models.mask[0].sum()) == 16
    kept = np.asarray(models.inputs[0])
    expected = tracklet_inputs(busy[np.linspace(0, 99, 16).astype(int), :5])
    np.testing.assert_allclose(kept, expected, rtol=1e-5)
    np.testing.assert_allclose(np.asarray(models.alpha[1:]), 0.0)


def test_fit_chooses_the_grid_point_of_largest_likelihood():
    rng = np.random.default_rng(3)
    windows = moving_tracklets(40, [20, 20], [1.0, 0.5], rng)
    windows[:, 5] += rng.normal(0, 0.5, (40, 2))
    tracklets = Tracklets(windows[:, :5], windows[:, 5])
    fractions = (0.2, 0.5, 0.8)
    chosen = fit_motion_models(tracklets, 100, 100, cell_size=50, noise_fractions=fractions)
    variance = float(chosen.amplitude + chosen.noise)
    best = float(log_marginal_likelihood_of(chosen, tracklets))
    for fraction in fractions:
        fixed = fit_motion_models(tracklets, 100, 100, cell_size=50, noise_fractions=(fraction,))
        np.testing.assert_allclose(float(fixed.amplitude + fixed.noise), variance, rtol=1e-5)
        assert float(log_marginal_likelihood_of(fixed, tracklets)) <= best + 1e-3


def log_marginal_likelihood_of(models, tracklets):
    points = np.asarray(tracklets.points)
    residuals = (
        np.asarray(tracklets.next_points) - points[:, -1] - (points[:, -1] - points[:, 0]) / 4
    )
    padded = np.zeros(models.alpha.shape)
    padded[0, : len(points)] = residuals[: models.alpha.shape[1]]
    return log_marginal_likelihood(padded, models.mask, models.cholesky, models.alpha)


@pytest.mark.parametrize(
    ("option", "value"),
    [
        ("cell_size", 0.0),
        ("max_points", 0),
        ("noise_fractions", (0.5, 1.0)),
        ("length_scale_factors", ()),
    ],
)
def test_fit_rejects_bad_options(option, value):
    tracklets = Tracklets(np.zeros((0, 5, 2)), np.zeros((0, 2)))
    with pytest.raises(InputError, match=option):
        fit_motion_models(tracklets, 100, 100, **{option: value})
