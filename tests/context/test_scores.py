"""The detector's score calibration (:mod:`jaxtrack.context.scores`) and where it is used."""

from __future__ import annotations

import functools
import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.association.labelling import confirm_by_evidence, init_labels, label_step
from jaxtrack.context.io import load_context, save_context
from jaxtrack.context.scores import (
    FLOOR,
    MIN_DETECTIONS,
    ScoreCalibration,
    calibration_from_metadata,
    identity_calibration,
    invalid_calibration,
    knot_scores,
    learn_score_calibration,
)
from jaxtrack.errors import FileFormatError
from jaxtrack.filters.phd_defaults import default_phd_params
from jaxtrack.filters.phd_tracker import Context, PHDConfig, phd_params
from jaxtrack.types import SequenceInfo
from tests.association.test_labelling import PARAMS, _estimates


def _pool_adjacent_violators(values, weights):
    """A slow reference of the weighted isotonic (non-decreasing) least-squares fit."""
    blocks = [[float(v), float(w), 1] for v, w in zip(values, weights, strict=True)]
    merged = True
    while merged:
        merged = False
        for i in range(len(blocks) - 1):
            if blocks[i][0] > blocks[i + 1][0]:
                (v1, w1, n1), (v2, w2, n2) = blocks[i], blocks[i + 1]
                blocks[i : i + 2] = [[(v1 * w1 + v2 * w2) / (w1 + w2), w1 + w2, n1 + n2]]
                merged = True
                break
    return np.concatenate([[v] * n for v, _, n in blocks])


def test_learned_calibration_is_the_isotonic_fit_at_the_knots():
    rng = np.random.default_rng(0)
    scores = np.round(rng.uniform(0.3, 1.0, 400), 2)  # ties on purpose
    is_target = rng.uniform(size=400) < scores**3
    calibration, summary = learn_score_calibration(scores, is_target)
    unique = np.unique(scores)
    shares = np.array([is_target[scores == u].mean() for u in unique])
    counts = np.array([(scores == u).sum() for u in unique])
    fitted = _pool_adjacent_violators(shares, counts)
    knots = knot_scores()
    expected = np.clip(np.interp(knots, unique, fitted), FLOOR, 1 - FLOOR)
    np.testing.assert_allclose(calibration.scores, knots)
    np.testing.assert_allclose(calibration.probabilities, expected, atol=1e-6)
    assert np.all(np.diff(calibration.probabilities) >= 0)
    assert summary["learned"] and summary["detections"] == 400
    assert summary["target_share"] == pytest.approx(is_target.mean())


def test_learned_calibration_recovers_a_known_curve():
    """p(target | s) = s^3 over many detections: within 0.05 of the truth on [0.3, 0.95]."""
    rng = np.random.default_rng(1)
    scores = rng.uniform(0.2, 1.0, 40_000)
    calibration, _ = learn_score_calibration(scores, rng.uniform(size=scores.size) < scores**3)
    probe = np.linspace(0.3, 0.95, 14)
    learned = np.interp(probe, calibration.scores, calibration.probabilities)
    np.testing.assert_allclose(learned, probe**3, atol=0.05)


def test_nothing_is_learned_from_too_few_or_one_sided_labels():
    scores = np.linspace(0.5, 1.0, MIN_DETECTIONS)
    assert learn_score_calibration(scores[:-1], scores[:-1] > 0.7)[0] is None
    assert learn_score_calibration(scores, np.ones(scores.size, bool))[0] is None
    assert learn_score_calibration(scores, scores > 0.7)[0] is not None
    with pytest.raises(ValueError, match="labels"):
        learn_score_calibration(scores, scores[:3] > 0)


def test_identity_reads_scores_as_probabilities():
    calibration = identity_calibration()
    probe = np.array([0.01, 0.5, 0.8, 0.97])
    np.testing.assert_allclose(
        np.interp(probe, calibration.scores, calibration.probabilities), probe, atol=1e-6
    )


def test_evidence_rule_reads_scores_through_the_calibration():
    """A calibration that maps every score to 0.9: logit(0.9) = 2.20 per frame, so a track
    is confirmed on its second estimate whatever its scores (2 x 2.20 >= logit(0.97))."""
    knots = knot_scores()
    flat = ScoreCalibration(jnp.asarray(knots), jnp.full(knots.shape, 0.9))
    params = PARAMS._replace(confirm_score=jnp.asarray(0.97), score_calibration=flat)
    step = jax.jit(functools.partial(label_step, confirmation=confirm_by_evidence))
    state = init_labels(4)
    confirmed = []
    for t, score in enumerate([0.3, 0.99, 0.3]):
        estimates = _estimates([(100 + 2 * t, 200, 40, 100)], scores=[score, 0, 0, 0])
        state, labels = step(state, params, estimates)
        confirmed.append(bool(labels.confirmed[0]))
    assert 2 * math.log(9) >= math.log(0.97 / 0.03) > math.log(9)
    assert confirmed == [False, True, True]


def _info():
    return SequenceInfo(name="S", seq_length=100, im_width=640, im_height=480, frame_rate=25.0)


def test_context_calibration_reaches_every_variant_and_round_trips(tmp_path):
    params = default_phd_params(640.0, 480.0, 25.0)
    knots = knot_scores()
    calibration = ScoreCalibration(knots, np.clip(knots**2, FLOOR, 1 - FLOOR))
    record = {"scores": knots.tolist(), "probabilities": calibration.probabilities.tolist()}
    metadata = {"score_calibration": {"learned": True, "source": "gt", **record}}
    path = tmp_path / "c.npz"
    save_context(path, params.birth_intensity, params.clutter_intensity, metadata)
    context = Context(*load_context(path))
    loaded = calibration_from_metadata(context.metadata)
    np.testing.assert_allclose(loaded.probabilities, calibration.probabilities)
    for variant in ("UM", "GM", "A3"):
        labelling = phd_params(PHDConfig(), _info(), context, variant).labelling
        np.testing.assert_allclose(
            labelling.score_calibration.probabilities, calibration.probabilities, atol=1e-6
        )
    plain = phd_params(PHDConfig(), _info()).labelling.score_calibration
    np.testing.assert_allclose(plain.probabilities, knots)
    no_calibration = Context(context.birth, context.clutter, {"score_calibration": {}})
    assert calibration_from_metadata(no_calibration.metadata) is None


@pytest.mark.parametrize(
    ("record", "message"),
    [
        ([0.5], "JSON object"),
        ({"scores": [0.2, 0.5]}, "numeric"),
        ({"scores": [0.2, 0.5], "probabilities": [0.1]}, "one length"),
        ({"scores": [0.5, 0.2], "probabilities": [0.1, 0.2]}, "increase"),
        ({"scores": [0.2, 0.5], "probabilities": [0.3, 0.2]}, "non-decreasing"),
        ({"scores": [0.2, 0.5], "probabilities": [0.3, 1.2]}, "non-decreasing"),
        ({"scores": [0.2, "NaN"], "probabilities": [0.3, 0.4]}, "numeric|finite"),
    ],
)
def test_invalid_calibration_metadata_is_refused_on_loading(tmp_path, record, message):
    params = default_phd_params(640.0, 480.0, 25.0)
    path = tmp_path / "c.npz"
    save_context(path, params.birth_intensity, params.clutter_intensity)
    with np.load(path) as data:
        arrays = {name: data[name] for name in data.files}
    arrays["metadata_json"] = np.asarray(
        json.dumps({"format_version": 1, "score_calibration": record})
    )
    with path.open("wb") as file:
        np.savez(file, **arrays)
    assert invalid_calibration(record) is not None
    with pytest.raises(FileFormatError, match=message):
        load_context(path)
