"""Blob extraction on drawn rectangles: exact boxes, areas, ellipses; mask cleaning."""

from __future__ import annotations

import numpy as np
import pytest

from jaxtrack.detect.blobs import clean_mask, crop_ellipse, extract_blobs
from jaxtrack.errors import InputError

RECTANGLES = [(3, 4, 10, 25), (30, 2, 17, 6), (60, 40, 1, 1), (20, 50, 40, 12)]  # x, y, w, h


def _drawn(shape=(80, 120), rectangles=RECTANGLES) -> np.ndarray:
    mask = np.zeros(shape, bool)
    for x, y, w, h in rectangles:
        mask[y : y + h, x : x + w] = True
    return mask


def test_drawn_rectangles_give_exact_boxes_and_areas():
    blobs = extract_blobs(_drawn())
    order = np.lexsort((blobs.boxes[:, 0], blobs.boxes[:, 1]))
    expected = sorted(RECTANGLES, key=lambda r: (r[1], r[0]))
    np.testing.assert_array_equal(blobs.boxes[order], np.array(expected, float))
    np.testing.assert_array_equal(blobs.areas[order], [w * h for _, _, w, h in expected])
    for crop, (_, _, w, h) in zip([blobs.crops[i] for i in order], expected, strict=True):
        assert crop.shape == (h, w) and crop.all()


def test_min_area_drops_small_blobs():
    blobs = extract_blobs(_drawn(), min_area=60)
    assert sorted(map(tuple, blobs.boxes.astype(int).tolist())) == sorted(
        r for r in RECTANGLES if r[2] * r[3] >= 60
    )


def test_rectangle_ellipse_moments():
    """Uniform w x h pixel block: variance (w^2 - 1) / 12 along x, axes 4 sqrt(var)."""
    x, y, w, h = 5, 7, 9, 31
    crop = np.ones((h, w), bool)
    cx, cy, major, minor, angle = crop_ellipse(crop, x, y)
    assert cx == pytest.approx(x + (w - 1) / 2)
    assert cy == pytest.approx(y + (h - 1) / 2)
    assert major == pytest.approx(4 * np.sqrt((h**2 - 1) / 12))
    assert minor == pytest.approx(4 * np.sqrt((w**2 - 1) / 12))
    assert angle == pytest.approx(90.0)
    assert crop_ellipse(np.ones((3, 12), bool))[4] == pytest.approx(0.0)


def test_diagonal_blob_angle():
    crop = np.eye(20, dtype=bool)  # rows grow with columns: 45 degrees in image axes
    assert crop_ellipse(crop)[4] == pytest.approx(45.0)


def test_clean_mask_removes_thin_line_keeps_person_and_joins_a_gap():
    mask = np.zeros((60, 80), bool)
    mask[30, :] = True  # a 1-pixel horizontal line (barrier tape)
    mask[10:25, 20:28] = True  # upper body
    mask[27:45, 20:28] = True  # legs, 2 rows below
    mask[50, 60] = True  # a speck
    cleaned = clean_mask(mask, open_size=(1, 5), close_size=(3, 11))
    blobs = extract_blobs(cleaned)
    assert len(blobs) == 1
    np.testing.assert_array_equal(blobs.boxes[0], [20, 10, 8, 35])


def test_mask_must_be_two_dimensional():
    with pytest.raises(InputError, match="height, width"):
        extract_blobs(np.zeros((4, 4, 3), bool))


def test_ellipse_matches_covariance_eigen_decomposition_on_random_blobs():
    rng = np.random.default_rng(3)
    for _ in range(5):
        crop = rng.random((23, 17)) < 0.4
        rows, cols = np.nonzero(crop)
        cov = np.cov(np.stack([cols, rows]).astype(float), bias=True)
        values, vectors = np.linalg.eigh(cov)
        cx, cy, major, minor, angle = crop_ellipse(crop, 100, 200)
        assert (cx, cy) == pytest.approx((100 + cols.mean(), 200 + rows.mean()))
        assert (major, minor) == pytest.approx(4 * np.sqrt(values[::-1]))
        expected = np.degrees(np.arctan2(vectors[1, 1], vectors[0, 1])) % 180
        assert min(abs(angle - expected), 180 - abs(angle - expected)) < 1e-6
