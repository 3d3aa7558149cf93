"""OSPA and GOSPA against brute-force enumeration of assignments on tiny sets."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from jaxtrack.boxes import iou_matrix
from jaxtrack.metrics import EvalConfig, evaluate_sequence, set_distances
from jaxtrack.metrics.matching import centre_distance
from jaxtrack.metrics.ospa import set_distance_fields
from jaxtrack.metrics.preprocess import prepare_sequence
from jaxtrack.metrics.synthetic import SCENARIOS, corrupt


def brute_force_ospa(distance: np.ndarray, c: float, p: float) -> tuple[float, float, float]:
    """OSPA, localisation, cardinality by trying every injection of the smaller set."""
    n, m = distance.shape
    if n == 0 and m == 0:
        return 0.0, 0.0, 0.0
    if n > m:
        distance, n, m = distance.T, m, n
    cut = np.minimum(distance, c) ** p
    best = min(
        (
            sum(cut[i, j] for i, j in enumerate(cols))
            for cols in itertools.permutations(range(m), n)
        ),
        default=0.0,
    )
    total = ((best + c**p * (m - n)) / m) ** (1 / p)
    return total, (best / m) ** (1 / p), (c**p * (m - n) / m) ** (1 / p)


def brute_force_gospa(distance: np.ndarray, c: float, p: float) -> list[tuple[float, ...]]:
    """Every partial assignment of pairs closer than c (the assignment form of GOSPA with
    alpha 2, Rahmathullah et al. 2017), as ``(total, localisation, missed, false)`` p-th power
    sums, best first."""
    n, m = distance.shape
    options = []
    for size in range(0, min(n, m) + 1):
        for rows in itertools.combinations(range(n), size):
            for cols in itertools.permutations(range(m), size):
                d = distance[list(rows), list(cols)]
                if np.any(d >= c):
                    continue
                loc = float(np.sum(d**p))
                missed, false = c**p / 2 * (n - size), c**p / 2 * (m - size)
                options.append((loc + missed + false, loc, missed, false))
    return sorted(options)


distance_matrices = st.tuples(st.integers(0, 4), st.integers(0, 4)).flatmap(
    lambda shape: arrays(np.float64, shape, elements=st.floats(0, 3, allow_subnormal=False))
)


@settings(max_examples=200, deadline=None, derandomize=True)
@given(
    distance=distance_matrices,
    c=st.sampled_from([0.5, 1.0, 2.0]),
    p=st.sampled_from([1.0, 2.0, 3.0]),
)
def test_against_brute_force(distance, c, p):
    """Compared as p-th powers (the minimised sums): roots of near-zero sums are
    ill-conditioned, and near-ties between assignments may split the components differently."""
    values = {key: value**p for key, value in set_distances(distance, cutoff=c, order=p).items()}
    ospa, ospa_loc, ospa_card = (value**p for value in brute_force_ospa(distance, c, p))
    assert values["OSPA"] == pytest.approx(ospa, abs=1e-9)
    assert values["OSPA_localisation"] == pytest.approx(ospa_loc, abs=1e-9)
    assert values["OSPA_cardinality"] == pytest.approx(ospa_card, abs=1e-9)
    options = brute_force_gospa(distance, c, p)
    assert values["GOSPA"] == pytest.approx(options[0][0], abs=1e-9)
    # The components are those of one optimal assignment (several may tie).
    components = (values["GOSPA_localisation"], values["GOSPA_missed"], values["GOSPA_false"])
    assert any(
        np.allclose(components, option[1:], rtol=0, atol=1e-9)
        for option in options
        if option[0] <= options[0][0] + 1e-9
    )
    assert values["OSPA"] == pytest.approx(
        values["OSPA_localisation"] + values["OSPA_cardinality"], abs=1e-9
    )
    assert values["GOSPA"] == pytest.approx(
        values["GOSPA_localisation"] + values["GOSPA_missed"] + values["GOSPA_false"], abs=1e-9
    )
    assert 0 <= values["OSPA"] <= c**p + 1e-12


def test_known_values():
    # One gt, two estimates: one at distance 1, one far away.
    distance = np.array([[1.0, 10.0]])
    values = set_distances(distance, cutoff=4.0, order=2.0)
    assert values["OSPA"] == pytest.approx(np.sqrt((1 + 16) / 2))
    assert values["GOSPA"] == pytest.approx(np.sqrt(1 + 16 / 2))
    assert values["GOSPA_false"] == pytest.approx(np.sqrt(8))
    assert values["GOSPA_missed"] == 0.0
    assert set_distances(np.zeros((0, 3)), cutoff=2.0)["OSPA"] == 2.0
    assert set_distances(np.zeros((0, 0)))["GOSPA"] == 0.0


@pytest.mark.parametrize(
    ("distance", "cutoff", "order"), [("iou", 1.0, 1.0), ("centre", 40.0, 2.0)]
)
def test_sequence_equals_frame_by_frame(mot15_gt, distance, cutoff, order):
    """The batched sequence computation equals set_distances applied to every frame."""
    gt, seq_length = mot15_gt["ETH-Sunnyday"]
    result = corrupt(gt, SCENARIOS["noisy"], seed=8)
    data = prepare_sequence(gt, result, (1, seq_length))
    expected = {key: 0.0 for key in ("OSPA", "GOSPA", "GOSPA_missed", "GOSPA_false")}
    for t in range(data.num_frames):
        a = data.gt_boxes[data.gt_frame == t]
        b = data.tracker_boxes[data.tracker_frame == t]
        if distance == "iou":
            d = 1.0 - iou_matrix(a, b)
        else:
            d = centre_distance(np.repeat(a, len(b), axis=0), np.tile(b, (len(a), 1)))
            d = d.reshape(len(a), len(b))
        for key, value in set_distances(d, cutoff, order).items():
            if key in expected:
                expected[key] += value / data.num_frames
    fields = set_distance_fields(data, cutoff, order, distance)
    for key, value in expected.items():
        assert fields[key] / fields["num_frames"] == pytest.approx(value, abs=1e-9), key
    config = EvalConfig(ospa_cutoff=cutoff, ospa_order=order, ospa_distance=distance)
    summary = evaluate_sequence(gt, result, (1, seq_length), config).summary()
    assert summary["OSPA"] == pytest.approx(expected["OSPA"], abs=1e-9)
    assert summary["GOSPA"] == pytest.approx(expected["GOSPA"], abs=1e-9)
