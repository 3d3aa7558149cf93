"""Detection scores in the Hierarchical low level: confirmation by a strong detection and the
score log-odds in the association cost (``confirm_score``, ``score_weight``)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.association.labelling import score_log_odds
from jaxtrack.filters.base import run
from jaxtrack.filters.hier_low import init_low, low_step
from jaxtrack.filters.hier_low_defaults import default_low_params
from jaxtrack.filters.hier_low_model import (
    innovation_covariance,
    low_predict,
    mahalanobis_square_distances,
    track_scale,
)
from jaxtrack.filters.hierarchical import SCORE_CLIP
from jaxtrack.filters.hierarchical_tracker import (
    CONFIRM_SCORE,
    HierarchicalConfig,
    build_hierarchical,
)
from jaxtrack.pipelines.tracking import output_rows
from tests.filters.test_cmt import INFO, SIZE, frame_inputs

ROWS = 4
STEP = jax.jit(
    lambda s, p, z, v, strong, odds: low_step(s, p, z, v, strong, odds, measurement="box")
)


def _padded(z, valid, strong=None, odds=None):
    rows = np.zeros((ROWS, 4), np.float32)
    rows[: len(z)] = z
    mask = np.arange(ROWS) < len(z)
    strong_row = np.zeros(ROWS, bool)
    strong_row[: len(z)] = True if strong is None else strong
    odds_row = np.zeros(ROWS, np.float32)
    odds_row[: len(z)] = 0.0 if odds is None else odds
    return (
        jnp.asarray(rows),
        jnp.asarray(mask & np.pad(np.asarray(valid, bool), (0, ROWS - len(z)))),
        jnp.asarray(strong_row),
        jnp.asarray(odds_row),
    )


def _walk(num_frames):
    k = np.arange(num_frames)[:, None]
    return np.hstack([100 + 2 * k, 200 + k, np.full_like(k, 40), np.full_like(k, 100)]).astype(
        np.float32
    )


@pytest.mark.parametrize(
    ("strong_frames", "expected"), [(None, [4]), ([2], [4]), ([9], [9]), ([], [])]
)
def test_a_track_is_confirmed_only_once_it_has_held_a_strong_measurement(strong_frames, expected):
    """One target measured exactly on every frame: the paper's rule confirms it on its 4th
    update (frame 4); with strong measurements only on ``strong_frames`` it is confirmed on
    the first frame that both rules allow, and never without one."""
    params = default_low_params("box", confirm_updates=4)
    state, confirmed = init_low(4, "box"), []
    for k, box in enumerate(_walk(15)):
        strong = None if strong_frames is None else [k in strong_frames]
        state, info = STEP(state, params, *_padded(box[None], [True], strong))
        confirmed.append(bool(info.newly_confirmed[0]))
    assert np.flatnonzero(confirmed).tolist() == expected
    assert bool(state.confirmed[0]) == bool(expected)


def test_log_odds_decide_between_two_gated_measurements_at_the_likelihood_balance():
    """A settled track and two measurements in its gate: the cost is ``MSD - 2 log-odds``
    (plus the track's own term), so the farther one is taken exactly when its log-odds
    exceed the nearer one's by more than half the MSD difference (computed here from the
    model's own predict and innovation covariance)."""
    params = default_low_params("box")
    state = init_low(4, "box")
    for box in np.repeat(np.array([[100.0, 200.0, 40.0, 100.0]], np.float32), 12, axis=0):
        state, _ = STEP(state, params, *_padded(box[None], [True]))
    z = np.array([[101.0, 200.0, 40.0, 100.0], [104.0, 200.0, 40.0, 100.0]], np.float32)
    scale = track_scale(state.mean[0], "box")
    mean, cov = low_predict(state.mean[0], state.cov[0], params.process_std, scale, "box")
    s_cov, _ = innovation_covariance(cov, params.measurement_std, scale, "box")
    msd = np.asarray(mahalanobis_square_distances(mean, s_cov, jnp.asarray(z), "box"), float)
    assert msd[1] <= float(params.gate) and msd[0] < msd[1]
    balance = (msd[1] - msd[0]) / 2
    for extra, taker in ((0.0, 0), (balance * 0.9, 0), (balance * 1.1, 1)):
        _, info = STEP(state, params, *_padded(z, [True, True], odds=[0.5, 0.5 + extra]))
        assert int(info.assignment[taker]) == 0, (extra, info.assignment)
        assert int(info.assignment[1 - taker]) != 0


def test_score_log_odds_clip_and_sign():
    odds = np.asarray(score_log_odds(jnp.array([0.0, 0.5, 0.8, 1.0]), SCORE_CLIP))
    np.testing.assert_allclose(odds, [-np.log(999), 0.0, np.log(4), np.log(999)], rtol=1e-4)


def _scene(num_frames, target_scores, clutter_score):
    """A walking target scored ``target_scores[t]`` and a static false detection scored
    ``clutter_score`` on every frame."""
    frames = [np.full((SIZE[1], SIZE[0], 3), 128, np.uint8)] * num_frames
    boxes = [
        [(20.0 + 1.5 * t, 20.0, 16.0, 36.0), (110.0, 70.0, 16.0, 36.0)] for t in range(num_frames)
    ]
    scores = np.zeros((num_frames, 4))
    scores[:, 0] = target_scores
    scores[:, 1] = clutter_score
    return frame_inputs(frames, boxes, scores=scores)


@pytest.mark.parametrize("variant", ["managed", "full"])
def test_a_persistent_weak_false_detection_is_not_output_but_the_target_is_whole(variant):
    """The false detection (score 0.6, every frame) is a track under the paper's rule and
    none with the default ``confirm_score``; the target, strong only on frame 12, is output
    on every frame from its first (the offline output keeps its tentative rows)."""
    num_frames = 30
    target_scores = np.where(np.arange(num_frames) == 12, 0.99, 0.8)
    inputs = _scene(num_frames, target_scores, 0.6)
    background = np.full((SIZE[1], SIZE[0], 3), 128, np.uint8)
    results = {}
    for name, settings in {"paper": {"confirm_score": 0.0}, "default": {}}.items():
        config = HierarchicalConfig(variant=variant, max_tracks=8, max_trackers=8, **settings)
        filt, params = build_hierarchical(config, INFO, background)
        _, info = jax.jit(lambda k, p, i, f=filt: run(f, k, p, i))(
            jax.random.PRNGKey(0), params, inputs
        )
        results[name] = output_rows(jax.device_get(info), config, 1)
    assert CONFIRM_SCORE == HierarchicalConfig().confirm_score == 0.97
    for name, rows in results.items():
        clutter = np.abs(rows.boxes[:, 1] - 70.0) < 4
        target = np.abs(rows.boxes[:, 1] - 20.0) < 4
        assert clutter.any() == (name == "paper"), name
        assert np.unique(rows.ids[target]).size == 1, name
        assert sorted(rows.frames[target].tolist()) == list(range(1, num_frames + 1)), name


@pytest.mark.parametrize("variant", ["managed", "full"])
def test_a_detector_whose_scores_never_reach_confirm_score_confirms_by_its_own_quantile(variant):
    """Target detections scoring 0.8 and a false one scoring 0.6, every frame: no detection
    reaches ``confirm_score`` 0.97, so with ``confirm_quantile`` 1 (off) nothing is output.
    By default (0.75) the bar is the 75th percentile of the scores seen so far once 100 are
    counted (frame 50, two a frame): 0.8, so the target is confirmed and output whole (its
    tentative rows kept) and the false detection is still not."""
    num_frames = 70
    inputs = _scene(num_frames, np.full(num_frames, 0.8), 0.6)
    background = np.full((SIZE[1], SIZE[0], 3), 128, np.uint8)
    assert HierarchicalConfig().confirm_quantile == 0.75
    for quantile, expected in ((1.0, []), (0.75, list(range(1, num_frames + 1)))):
        config = HierarchicalConfig(
            variant=variant, max_tracks=8, max_trackers=8, confirm_quantile=quantile
        )
        filt, params = build_hierarchical(config, INFO, background)
        _, info = jax.jit(lambda k, p, i, f=filt: run(f, k, p, i))(
            jax.random.PRNGKey(0), params, inputs
        )
        rows = output_rows(jax.device_get(info), config, 1)
        target = np.abs(rows.boxes[:, 1] - 20.0) < 4
        assert not (np.abs(rows.boxes[:, 1] - 70.0) < 4).any(), quantile
        assert sorted(rows.frames[target].tolist()) == expected, quantile
        assert np.unique(rows.ids[target]).size == len(expected[:1]), quantile
        confirmed = np.asarray(info.low.newly_confirmed).any(axis=1)
        assert np.flatnonzero(confirmed).tolist() == ([49] if expected else []), quantile
