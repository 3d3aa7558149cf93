"""Chunked runs at per-chunk detection capacities (``run(..., fit_capacity=True)``)."""

from __future__ import annotations

import dataclasses

import jax
import numpy as np
import pytest

from jaxtrack.filters.base import (
    CROWDED_FACTOR,
    MIN_CAPACITY,
    Chunk,
    capacity_for,
    fit_detections,
    plan_chunks,
    run,
)
from jaxtrack.filters.phd import phd_filter
from jaxtrack.filters.phd_defaults import default_phd_params
from jaxtrack.filters.phd_tracker import PHDConfig
from jaxtrack.io import load_sequence
from jaxtrack.io.motchallenge import pad_detections
from jaxtrack.pipelines.tracking import track_sequences
from jaxtrack.types import MotTable

CONFIG = PHDConfig(num_particles=256, births_per_detection=8, output="online")


def test_capacity_is_a_power_of_two_at_least_the_minimum():
    assert [capacity_for(n) for n in (0, 1, 16, 17, 100, 512, 513)] == [
        MIN_CAPACITY,
        MIN_CAPACITY,
        16,
        32,
        128,
        512,
        1024,
    ]


def test_plan_isolates_crowded_frames_and_covers_every_frame_once():
    counts = np.full(300, 5)
    counts[[10, 11, 200]] = 500
    counts[150] = 40  # 40 <= 4 * 16: regular, raises the regular capacity to 64
    chunks = plan_chunks(counts, chunk_frames=128)
    assert chunks == [
        Chunk(0, 10, 64),
        Chunk(10, 12, 512, crowded=True),
        Chunk(12, 140, 64),
        Chunk(140, 200, 64),
        Chunk(200, 201, 512, crowded=True),
        Chunk(201, 300, 64),
    ]
    covered = np.concatenate([np.arange(c.start, c.stop) for c in chunks])
    np.testing.assert_array_equal(covered, np.arange(300))
    assert all(counts[c.start : c.stop].max() <= c.capacity for c in chunks)
    # The threshold is relative to the median frame, so a uniformly dense scene has none.
    assert not any(c.crowded for c in plan_chunks(np.full(50, 300), 16))
    assert CROWDED_FACTOR * capacity_for(5) == 64


@pytest.fixture(scope="module")
def campus(mot15_root):
    return load_sequence(mot15_root / "TUD-Campus", frames=(1, 40))


def _crowded(seq, frame: int, count: int):
    """``seq`` with ``count`` extra detections (spread over the image) on ``frame``."""
    rng = np.random.default_rng(0)
    boxes = np.column_stack(
        [rng.uniform(0, 600, count), rng.uniform(0, 400, count), np.full((count, 2), 40.0)]
    )
    det = seq.det_table
    table = MotTable.from_arrays(
        np.concatenate([det.frames, np.full(count, frame)]),
        np.concatenate([det.ids, np.full(count, -1)]),
        np.concatenate([det.boxes, boxes]),
        np.concatenate([det.confs, np.full(count, 0.5)]),
    )
    return dataclasses.replace(
        seq,
        det_table=table,
        detections=pad_detections(table, seq.first_frame, seq.num_frames),
    )


def _same_rows(a, b):
    np.testing.assert_array_equal(a.frames, b.frames)
    np.testing.assert_array_equal(a.ids, b.ids)
    np.testing.assert_array_equal(a.boxes, b.boxes)


def test_a_sequence_gives_the_same_result_alone_and_in_company(mot15_root, campus):
    pets = load_sequence(mot15_root / "PETS09-S2L1", frames=(1, 60))
    crowded = _crowded(campus, 20, 200)
    (alone,) = track_sequences([campus], CONFIG, seed=4)
    together = track_sequences([crowded, pets, campus], CONFIG, seed=4)
    _same_rows(alone, together[2])
    (pets_alone,) = track_sequences([pets], CONFIG, seed=4)
    _same_rows(pets_alone, together[1])
    # More empty slots in the input do not change the result either.
    wide = dataclasses.replace(
        campus, detections=pad_detections(campus.det_table, campus.first_frame, 40, 100)
    )
    _same_rows(alone, track_sequences([wide], CONFIG, seed=4)[0])


def test_a_crowded_frame_leaves_the_frames_before_it_unchanged(campus):
    crowded = _crowded(campus, 25, 300)
    counts = crowded.detections.mask.sum(axis=1)
    assert [c.capacity for c in plan_chunks(counts, 128)] == [16, 512, 16]
    (plain,) = track_sequences([campus], CONFIG, seed=1)
    (with_crowd,) = track_sequences([crowded], CONFIG, seed=1)
    before = plain.frames < 25
    assert before.sum() > 20
    _same_rows(plain.select(before), with_crowd.select(with_crowd.frames < 25))


def test_fit_capacity_run_equals_an_unchunked_run_on_fitted_detections(campus):
    filt = phd_filter(128, births_per_detection=4, max_tracks=16)
    params = default_phd_params(640.0, 480.0, 25.0)
    key = jax.random.PRNGKey(7)
    fitted = fit_detections(campus.detections)
    assert fitted.mask.shape == (40, 16) and fitted.mask.sum() == campus.detections.mask.sum()
    _, expected = jax.jit(lambda k, d: run(filt, k, params, d))(key, fitted)
    _, chunked = run(filt, key, params, campus.detections, chunk_frames=16, fit_capacity=True)
    jax.tree.map(
        lambda a, b: np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-5), chunked, expected
    )
    with pytest.raises(ValueError, match="fit_capacity needs chunk_frames"):
        run(filt, key, params, campus.detections, fit_capacity=True)


def test_tracking_is_refused_up_front_when_memory_is_short(campus, monkeypatch):
    from jaxtrack import resources
    from jaxtrack.pipelines.tracking import check_tracking_memory
    from jaxtrack.resources import ResourceError

    check_tracking_memory([campus], CONFIG)  # this machine has the few MB it needs
    monkeypatch.setattr(resources, "available_memory_bytes", lambda: 10**4)
    with pytest.raises(ResourceError, match=r"tracking TUD-Campus .* num_particles"):
        track_sequences([campus], CONFIG, seed=0)


def test_detections_that_give_no_tracks_warn(campus):
    from jaxtrack.errors import InputWarning

    one = campus.det_table.select(np.arange(1))
    lone = dataclasses.replace(
        campus, det_table=one, detections=pad_detections(one, campus.first_frame, 40)
    )
    with pytest.warns(InputWarning, match=r"TUD-Campus: 1 detections in frames 1..40 gave no"):
        (rows,) = track_sequences([lone], CONFIG, seed=0)
    assert len(rows) == 0


def test_a_score_threshold_that_drops_most_detections_warns(campus):
    import warnings

    from jaxtrack.errors import InputWarning
    from jaxtrack.filters.kalman_tracker import KalmanConfig

    # TUD-Campus's detector scores are mostly above the default preset's 0.9: quiet.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        track_sequences([campus], KalmanConfig(), seed=0)
    # The same boxes with scores on another scale (0.5-0.85): every one ignored, said so.
    table = campus.det_table
    count = len(table)
    rescaled = dataclasses.replace(table, confs=0.5 + 0.35 * (table.confs - table.confs.min()))
    low = dataclasses.replace(
        campus,
        det_table=rescaled,
        detections=pad_detections(rescaled, campus.first_frame, campus.num_frames),
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        (dropped,) = track_sequences([low], KalmanConfig(), seed=0)
    said = [str(w.message) for w in caught if issubclass(w.category, InputWarning)]
    assert any(f"TUD-Campus: {count} of {count} detections (100 %) score below" in m for m in said)
    assert any("gave no tracks" in m for m in said)  # and its consequence, also said
    assert len(dropped) == 0  # what the warning is about: nothing tracked
    # The 'sort' preset has no threshold: no warning, and it tracks them.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        (kept,) = track_sequences([low], KalmanConfig(preset="sort"), seed=0)
    assert len(kept) > 100
