"""Perspective prior: recovered from noisy boxes with outliers; group blobs are split."""

from __future__ import annotations

import numpy as np
import pytest

from jaxtrack.detect.perspective import (
    PerspectivePrior,
    fit_perspective,
    person_box,
    split_blob,
)
from jaxtrack.errors import InputError


def test_fit_recovers_line_despite_groups_and_fragments():
    rng = np.random.default_rng(0)
    foot = rng.uniform(100, 500, 300)
    height = 10 + 0.25 * foot + rng.normal(0, 2, 300)
    width = 0.35 * height
    boxes = np.stack([rng.uniform(0, 600, 300), foot - height, width, height], axis=1)
    groups = boxes[:40].copy()
    groups[:, 2] *= 2.5  # wide: not person-shaped, not fitted
    fragments = boxes[40:80].copy()
    fragments[:, 3] *= 0.5  # half people, person-shaped (w/h 0.7 -> excluded) ...
    fragments[:, 2] *= 0.5  # ... made person-shaped: outliers of the line
    prior = fit_perspective(np.concatenate([boxes, groups, fragments]))
    assert prior.slope == pytest.approx(0.25, abs=0.01)
    assert prior.intercept == pytest.approx(10, abs=3)
    assert prior.aspect == pytest.approx(0.35, abs=0.01)


def test_fit_needs_person_shaped_boxes():
    with pytest.raises(InputError, match="perspective prior"):
        fit_perspective(np.array([[0, 0, 50, 10]] * 20, float))


def _two_people(gap_rows=0):
    """Two 10x30 people side by side, touching through a 2-pixel-wide bridge."""
    crop = np.zeros((30, 22), bool)
    crop[:, 0:10] = True
    crop[:, 12:22] = True
    crop[14:16, 10:12] = True
    return crop


def test_wide_blob_splits_into_people_with_exact_boxes():
    prior = PerspectivePrior(intercept=0.0, slope=30 / 130, aspect=1 / 3)  # h 30 at row 130
    box = np.array([50, 100, 22, 30], float)
    parts = split_blob(box, _two_people(), prior)
    parts = parts[np.argsort(parts[:, 0])]
    assert len(parts) == 2
    np.testing.assert_array_equal(parts[0], [50, 100, 10, 30])
    assert parts[1][0] in (60, 61, 62) and parts[1][2] == 72 - parts[1][0]
    single = split_blob(np.array([50, 100, 10, 30.0]), np.ones((30, 10), bool), prior)
    np.testing.assert_array_equal(single, [[50, 100, 10, 30]])


def test_tall_blob_splits_vertically():
    prior = PerspectivePrior(intercept=0.0, slope=30 / 160, aspect=1 / 3)
    crop = np.zeros((60, 10), bool)
    crop[0:29, 1:9] = True  # the person behind, higher up
    crop[29:31, 4:6] = True
    crop[31:60, 0:10] = True
    parts = split_blob(np.array([0, 100, 10, 60], float), crop, prior)
    assert len(parts) == 2
    parts = parts[np.argsort(parts[:, 1])]
    assert parts[0][1] == 100 and parts[1][1] + parts[1][3] == 160
    assert 26 <= parts[0][3] <= 32 and 26 <= parts[1][3] <= 32


def test_person_box_widens_thin_boxes_about_their_centre():
    boxes = np.array([[10, 0, 4, 40], [0, 0, 30, 40]], float)
    out = person_box(boxes, 0.5)
    np.testing.assert_allclose(out[0], [2, 0, 20, 40])
    np.testing.assert_allclose(out[1], boxes[1])
