"""Track confirmation rules of the PHD tracker (``PHDConfig.confirmation``)."""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pytest

from jaxtrack.association.labelling import is_learned
from jaxtrack.context.scores import identity_calibration, learn_score_calibration
from jaxtrack.errors import InputError
from jaxtrack.experiments.common import evaluate_rows
from jaxtrack.filters.phd import phd_filter
from jaxtrack.filters.phd_tracker import PHDConfig, phd_params, with_score_calibration
from jaxtrack.io import load_sequence
from jaxtrack.io.motchallenge import pad_detections
from jaxtrack.pipelines.tracking import track_sequences
from jaxtrack.types import MotTable

CONFIG = PHDConfig(num_particles=256, births_per_detection=8, output="online")


@pytest.fixture(scope="module")
def campus(mot15_root):
    return load_sequence(mot15_root / "TUD-Campus", frames=(1, 40))


@pytest.fixture(scope="module")
def campus_at_08(campus):
    """TUD-Campus frames 1-40 with every detection scored 0.8: no detection reaches the
    0.97 that confirms a track under the score rule."""
    seq = campus
    det = seq.det_table
    table = MotTable.from_arrays(det.frames, det.ids, det.boxes, np.full(len(det.frames), 0.8))
    return dataclasses.replace(
        seq, det_table=table, detections=pad_detections(table, seq.first_frame, seq.num_frames)
    )


def test_evidence_tracks_targets_whose_detections_never_reach_the_confirm_score(
    campus, campus_at_08
):
    with pytest.warns(UserWarning, match="gave no tracks"):
        (by_score,) = track_sequences([campus_at_08], CONFIG, seed=0)
    evidence_config = dataclasses.replace(CONFIG, confirmation="evidence")
    (by_evidence,) = track_sequences([campus_at_08], evidence_config, seed=0)
    assert len(by_score.frames) == 0
    # Reference: the score rule on the real scores (median 0.99), same particles and seed
    # (MOTA 0.50 measured; the evidence rule on the 0.8 scores 0.40).
    (reference,) = track_sequences([campus], CONFIG, seed=0)
    reference_mota = evaluate_rows(campus, reference).summary()["MOTA"]
    summary = evaluate_rows(campus_at_08, by_evidence).summary()
    assert summary["MOTA"] > max(0.3, reference_mota - 0.15), (summary, reference_mota)
    # Online output: a track is output from its third held estimate on (3 logit(0.8) >=
    # logit(0.97) > 2 logit(0.8)), so no identity appears on the first two frames.
    assert by_evidence.frames.min() >= 3


def test_confirmation_setting_round_trips_and_is_checked():
    config = PHDConfig(confirmation="evidence")
    assert PHDConfig.from_dict(json.loads(json.dumps(config.to_dict()))) == config
    with pytest.raises(InputError, match="confirmation"):
        PHDConfig(confirmation="votes")
    with pytest.raises(ValueError, match="confirmation"):
        phd_filter(64, confirmation="votes")


def test_auto_is_the_score_rule_without_a_calibration(campus):
    """Without a learned calibration ``"auto"`` (the default) gives the score rule's
    output, row for row."""
    assert PHDConfig().confirmation == "auto"
    score_config = dataclasses.replace(CONFIG, confirmation="score")
    auto_config = dataclasses.replace(CONFIG, confirmation="auto")
    (by_score,) = track_sequences([campus], score_config, seed=0)
    (by_auto,) = track_sequences([campus], auto_config, seed=0)
    assert len(by_score.frames) > 0
    assert_rows_equal(by_auto, by_score)


def test_auto_is_the_evidence_rule_with_a_learned_calibration(campus_at_08):
    """With a learned calibration in the parameters ``"auto"`` gives the evidence rule's
    output, row for row; a sweep mixing a calibrated and an uncalibrated parameter set
    confirms each by its own rule."""
    calibration, summary = learn_score_calibration(
        np.linspace(0.5, 0.99, 200), np.arange(200) % 4 != 0
    )
    assert summary["learned"]
    assert bool(is_learned(calibration)) and not bool(is_learned(identity_calibration()))
    info = campus_at_08.info
    calibrated = with_score_calibration(phd_params(CONFIG, info), calibration)
    plain = phd_params(CONFIG, info)
    runs = {}
    for rule in ("auto", "score", "evidence"):
        config = dataclasses.replace(CONFIG, confirmation=rule)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # the score rule gives no tracks
            runs[rule] = track_sequences(
                [campus_at_08] * 2, config, seed=0, params=[calibrated, plain]
            )
    # Calibrated, p(target | 0.8) = 0.75 here: a track is output from its fourth held
    # estimate on (3 logit 0.75 = 3.30 < logit 0.97 = 3.48 <= 4 logit 0.75, where the raw
    # scores confirm on the third); the score rule confirms nothing at 0.8.
    assert len(runs["score"][0].frames) == 0 and len(runs["evidence"][0].frames) > 0
    assert runs["evidence"][0].frames.min() >= 4
    assert_rows_equal(runs["auto"][0], runs["evidence"][0])
    assert_rows_equal(runs["auto"][1], runs["score"][1])
    assert len(runs["auto"][1].frames) == 0


def assert_rows_equal(a: MotTable, b: MotTable) -> None:
    np.testing.assert_array_equal(a.frames, b.frames)
    np.testing.assert_array_equal(a.ids, b.ids)
    np.testing.assert_array_equal(a.boxes, b.boxes)
