"""CMT's confirmation by the detector's own confident scores (``CMTConfig.confirm_quantile``).

Oracles: the running score histogram and its quantile against NumPy's sorted scores, and a
drawn scene of an under-confident detector (every box scores 0.855), whose components the
fixed 0.97 never confirms and the quantile rule confirms on the frame the 100th blob is
counted.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.filters.base import run
from jaxtrack.filters.cmt_tracker import CONFIRM_SCORE, CMTConfig, build_cmt
from jaxtrack.filters.score_quantile import MIN_SCORES, SCORE_BINS, confident_score, count_scores
from jaxtrack.types import Detections
from tests.filters.test_cmt import COLOURS, INFO, SMALL, scene, walkers


def numpy_threshold(scores: np.ndarray, quantile: float, confirm: float) -> float:
    """The lower edge of the bin of the ``ceil(quantile n)``-th smallest score (clipped to
    ``[0, 1]``), or ``confirm`` when lower, when enough scores were seen."""
    if len(scores) < MIN_SCORES or quantile >= 1:
        return confirm
    ordered = np.sort(np.clip(scores, 0.0, 1.0))
    k = max(1, math.ceil(quantile * len(scores)))
    index = min(int(np.floor(ordered[k - 1] * SCORE_BINS)), SCORE_BINS - 1)
    return min(confirm, index / SCORE_BINS)


@pytest.mark.parametrize("quantile", [0.0, 0.1, 0.5, 0.75, 0.9, 1.0])
def test_confident_score_is_the_quantile_of_the_scores_seen(quantile):
    rng = np.random.default_rng(7)
    counts = jnp.zeros(SCORE_BINS, jnp.float32)
    seen = []
    for frame in range(40):
        # True-ish scores near 0.8, some clutter, values outside [0, 1], padding.
        scores = np.concatenate([rng.beta(6.0, 1.5, 5), rng.uniform(-0.2, 1.2, 2)])
        mask = rng.uniform(size=scores.size) < 0.8
        blobs = Detections(
            jnp.zeros((scores.size, 4)), jnp.asarray(scores, jnp.float32), jnp.asarray(mask)
        )
        counts = count_scores(counts, blobs)
        seen.extend(np.float32(scores[mask]).tolist())
        got = float(confident_score(counts, jnp.float32(0.97), jnp.float32(quantile)))
        expected = numpy_threshold(np.asarray(seen), quantile, 0.97)
        assert got == pytest.approx(expected, abs=1e-6), (frame, len(seen))
    assert len(seen) >= MIN_SCORES  # the last frames read the quantile
    assert float(jnp.sum(counts)) == len(seen)


def test_an_under_confident_detector_confirms_once_its_scores_are_known():
    truth = walkers(60)
    scores = np.where(np.arange(4) < 2, 0.855, 0.0)[None].repeat(len(truth), axis=0)
    inputs = scene(truth, COLOURS, scores)
    shown = {}
    for quantile in (1.0, 0.75):
        filt, params = build_cmt(CMTConfig(confirm_quantile=quantile, **SMALL), INFO)
        _, info = run(filt, jax.random.PRNGKey(0), params, inputs)
        shown[quantile] = np.asarray(info.tracks.mask).sum(axis=1).tolist()
        candidates = np.asarray(info.candidates.mask).sum(axis=1)
        assert candidates[2:].tolist() == [2] * (len(truth) - 2)  # both followed throughout
    assert 0.855 < CONFIRM_SCORE
    assert shown[1.0] == [0] * len(truth)  # 0.855 never reaches 0.97: never output
    first = MIN_SCORES // 2 - 1  # two blobs a frame: the 100th is counted on frame 49
    assert shown[0.75] == [0] * first + [2] * (len(truth) - first)
