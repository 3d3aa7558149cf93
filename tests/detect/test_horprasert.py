"""Horprasert colour model: a per-pixel loop oracle and the classes on synthetic frames."""

from __future__ import annotations

import numpy as np
import pytest

from jaxtrack.detect import horprasert as hp
from jaxtrack.errors import InputError


def _background_frames(rng, num_frames=30, shape=(24, 32)):
    """A textured colour background with per-pixel Gaussian noise (std 2 grey levels)."""
    base = rng.uniform(60, 200, size=(*shape, 3))
    noise = rng.normal(0, 2.0, size=(num_frames, *shape, 3))
    return np.clip(base + noise, 0, 255).astype(np.uint8), base


def _loop_classes(frames: np.ndarray, frame: np.ndarray, rate: float, dark: float):
    """Slow reference: every statistic and decision pixel by pixel (Horprasert eq. 3-9)."""
    n, height, width, _ = frames.shape
    colours = frames.astype(np.float64)
    mean = np.zeros((height, width, 3))
    std = np.zeros((height, width, 3))
    for i in range(height):
        for j in range(width):
            for c in range(3):
                values = colours[:, i, j, c]
                mean[i, j, c] = np.median(values)
                mad = np.median(np.abs(values - mean[i, j, c]))
                std[i, j, c] = max(hp.MAD_TO_STD * mad, hp.MIN_COLOUR_STD)

    def alpha_cd(colour, i, j):
        e, s = mean[i, j], std[i, j]
        alpha = sum(colour[c] * e[c] / s[c] ** 2 for c in range(3)) / sum(
            (e[c] / s[c]) ** 2 for c in range(3)
        )
        cd = np.sqrt(sum(((colour[c] - alpha * e[c]) / s[c]) ** 2 for c in range(3)))
        return alpha, cd

    train_alpha = np.zeros((n, height, width))
    train_cd = np.zeros((n, height, width))
    for t in range(n):
        for i in range(height):
            for j in range(width):
                train_alpha[t, i, j], train_cd[t, i, j] = alpha_cd(colours[t, i, j], i, j)
    a = np.maximum(hp.MAD_TO_STD * np.median(np.abs(train_alpha - 1), axis=0), 0.02)
    b = np.maximum(hp.MAD_TO_STD * np.median(train_cd, axis=0), 0.5)
    norm_alpha = (train_alpha - 1) / a
    tau_cd = np.quantile(train_cd / b, rate)
    tau_low, tau_high = np.quantile(norm_alpha, [(1 - rate) / 2, (1 + rate) / 2])
    classes = np.zeros((height, width), np.uint8)
    for i in range(height):
        for j in range(width):
            alpha, cd = alpha_cd(frame[i, j].astype(np.float64), i, j)
            na, ncd = (alpha - 1) / a[i, j], cd / b[i, j]
            if ncd > tau_cd:
                classes[i, j] = hp.FOREGROUND
            elif alpha < dark:
                classes[i, j] = hp.DARK_FOREGROUND
            elif tau_low < na < tau_high:
                classes[i, j] = hp.BACKGROUND
            elif na < 0:
                classes[i, j] = hp.SHADOW
            else:
                classes[i, j] = hp.HIGHLIGHT
    return classes


def test_classify_matches_per_pixel_loop_oracle():
    rng = np.random.default_rng(0)
    frames, _ = _background_frames(rng, num_frames=15, shape=(8, 10))
    test = frames[0].astype(np.float64)
    test[0:3, 0:4] *= 0.6  # shadow
    test[4:8, 0:3] = test[4:8, 0:3, ::-1]  # colour change
    test[5:8, 6:10] *= 0.1  # very dark
    test[0:2, 6:10] *= 1.3  # highlight
    test = np.clip(test, 0, 255).astype(np.uint8)
    model = hp.fit_horprasert(frames, detection_rate=0.99)
    expected = _loop_classes(frames, test, 0.99, 0.4)
    got = hp.classify(model, test)
    # float32 vs float64 may flip a pixel sitting exactly on a threshold; none here
    np.testing.assert_array_equal(got, expected)
    assert set(np.unique(expected)) >= {hp.BACKGROUND, hp.FOREGROUND, hp.SHADOW}


def test_synthetic_classes_shadow_is_not_foreground_colour_change_is():
    rng = np.random.default_rng(1)
    frames, base = _background_frames(rng)
    model = hp.fit_horprasert(frames)
    test = np.clip(base + rng.normal(0, 2.0, base.shape), 0, 255)
    shadow = (slice(2, 10), slice(2, 12))
    colour = (slice(14, 22), slice(2, 12))
    dark = (slice(2, 10), slice(18, 28))
    bright = (slice(14, 22), slice(18, 28))
    test[shadow] *= 0.6
    test[colour] = test[colour][..., [1, 2, 0]]
    test[dark] *= 0.15
    test[bright] = np.minimum(test[bright] * 1.25, 255)
    classes = hp.classify(model, test.astype(np.uint8))
    assert np.mean(classes[shadow] == hp.SHADOW) > 0.95
    assert np.mean(classes[colour] == hp.FOREGROUND) > 0.95
    assert np.mean(classes[dark] == hp.DARK_FOREGROUND) > 0.95
    assert np.mean(classes[bright] == hp.HIGHLIGHT) > 0.9  # noise grows by 1.25 too
    untouched = np.ones(classes.shape, bool)
    for region in (shadow, colour, dark, bright):
        untouched[region] = False
    assert np.mean(classes[untouched] == hp.BACKGROUND) > 0.97
    mask = hp.foreground_mask(classes)
    assert not mask[shadow].any() or mask[shadow].mean() < 0.05
    assert mask[colour].mean() > 0.95 and mask[dark].mean() > 0.95


def test_robust_statistics_ignore_a_passer_by():
    """A person in a few training frames does not enter the background mean."""
    rng = np.random.default_rng(2)
    frames, base = _background_frames(rng, num_frames=20)
    frames[:5, 5:15, 5:10] = [20, 200, 30]
    model = hp.fit_horprasert(frames)
    error = np.abs(model.mean[5:15, 5:10] - base[5:15, 5:10])
    assert error.max() < 5.0 and error.mean() < 1.5
    assert np.abs(frames.mean(axis=0)[5:15, 5:10] - base[5:15, 5:10]).mean() > 20


def test_bad_input_is_refused():
    with pytest.raises(InputError, match="at least 3"):
        hp.fit_horprasert(np.zeros((2, 4, 4, 3), np.uint8))
    model = hp.fit_horprasert(np.full((4, 4, 4, 3), 100, np.uint8))
    with pytest.raises(InputError, match="background model"):
        hp.classify(model, np.zeros((5, 4, 3), np.uint8))
