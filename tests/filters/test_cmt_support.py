"""CMT's component support from the box likelihood alone (``CMTConfig.support``, not in the
paper): the appearance exponent must leave it alone, and the full likelihood's must not."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from jaxtrack.errors import InputError
from jaxtrack.filters.base import run
from jaxtrack.filters.cmt_tracker import CMTConfig, build_cmt
from tests.filters.test_cmt import COLOURS, INFO, SMALL, scene, walkers


def _supports(support: str, weight: float):
    inputs = scene(walkers(6), COLOURS)
    config = CMTConfig(support=support, appearance_weight=weight, **SMALL)
    filt, params = build_cmt(config, INFO)
    _, info = run(filt, jax.random.PRNGKey(3), params, inputs)
    return np.asarray(info.log_support), np.asarray(info.alive), np.asarray(info.tracks.mask)


def test_box_support_does_not_move_with_the_appearance_exponent():
    """Frame 1 is the first with components (born from frame 0's blobs): the same draws, so
    the same box likelihoods, under both exponents; the appearance differs."""
    box = {weight: _supports("box", weight) for weight in (1.0, 3.0)}
    full = {weight: _supports("likelihood", weight) for weight in (1.0, 3.0)}
    alive = box[1.0][1][1]
    assert alive.sum() == 2 and np.array_equal(full[1.0][1][1], alive)
    np.testing.assert_allclose(box[1.0][0][1][alive], box[3.0][0][1][alive], rtol=1e-6)
    gap = np.abs(full[1.0][0][1][alive] - full[3.0][0][1][alive])
    assert np.all(gap > 0.5)  # two more powers of an appearance likelihood far from 1
    # At weight 1 the box support is the full one without the appearance factor.
    assert not np.allclose(box[1.0][0][1][alive], full[1.0][0][1][alive])
    for _, _, shown in box.values():
        assert shown.sum(axis=1)[2:].tolist() == [2] * 4  # both walkers output


def test_unknown_support_is_refused():
    with pytest.raises(InputError, match="support"):
        CMTConfig(support="appearance")
