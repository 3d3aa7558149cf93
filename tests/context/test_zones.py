"""Entry/exit zones: each stage on hand-built cases, a synthetic scene with known zones, and
the JAX zone distance against a loop."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.context.intensity import Intensity
from jaxtrack.context.zones import (
    MAD_TO_STD,
    cluster_points,
    hull_depth,
    interior_clusters,
    learn_zones,
    trajectory_endpoints,
    zone_box,
    zone_distance,
    zones_from_intensity,
)
from jaxtrack.datasets.scene_config import SceneConfig
from jaxtrack.datasets.synthetic import generate_scene
from jaxtrack.errors import InputError
from tests.context.zone_scenes import (
    CROSSING_FRAMES,
    CROSSING_SCENE,
    CROSSING_ZONES,
    zone_feet,
)

WIDTH, HEIGHT = 768, 576


def boxes_at(feet, size=(20.0, 40.0)) -> np.ndarray:
    """``(x, y, w, h)`` boxes with the given foot points (middles of their bottom edges)."""
    feet = np.asarray(feet, float).reshape(-1, 2)
    corner = feet - [size[0] / 2, size[1]]
    return np.c_[corner, np.broadcast_to(size, feet.shape)]


def box_centres(boxes) -> np.ndarray:
    boxes = np.asarray(boxes)
    return boxes[:, :2] + boxes[:, 2:] / 2


def test_endpoints_skip_the_span_margins_and_take_foot_points():
    # id 1: frames 1-10 (there from the start); id 2: 4-20; id 3: 8-30 (still there at the
    # end); id 4: one box at frame 12. Rows shuffled.
    rows = [(f, 1, f, 0) for f in range(1, 11)]
    rows += [(f, 2, 100 + f, 50) for f in range(4, 21)]
    rows += [(f, 3, 200, 100 + f) for f in range(8, 31)]
    rows += [(12, 4, 300, 300)]
    rows = np.asarray(rows, float)[np.random.default_rng(0).permutation(len(rows))]
    ends = trajectory_endpoints(rows[:, 0], rows[:, 1], boxes_at(rows[:, 2:]), (1, 30), 3)
    got = sorted(zip(ends.ids.tolist(), ends.is_entry.tolist(), ends.frames.tolist(), strict=True))
    assert got == [
        (1, False, 10),
        (2, False, 20),
        (2, True, 4),
        (3, True, 8),
        (4, False, 12),
        (4, True, 12),
    ]
    expected = {
        (2, True): (104, 50),
        (2, False): (120, 50),
        (1, False): (10, 0),
        (3, True): (200, 108),
    }
    for identity, entry, point in zip(ends.ids, ends.is_entry, ends.points, strict=True):
        if (identity, entry) in expected:
            np.testing.assert_allclose(point, expected[(identity, entry)])
    everything = trajectory_endpoints(rows[:, 0], rows[:, 1], boxes_at(rows[:, 2:]), (1, 30), 0)
    assert everything.points.shape == (8, 2) and everything.is_entry.sum() == 4


def test_clusters_follow_the_cut():
    rng = np.random.default_rng(1)
    blobs = [(50, 300), (700, 300), (400, 40)]
    points = np.concatenate([rng.normal(centre, 8.0, (6, 2)) for centre in blobs])
    labels = cluster_points(points, 96.0)
    assert np.unique(labels).size == 3
    for k in range(3):  # each blob is one cluster
        assert np.unique(labels[6 * k : 6 * k + 6]).size == 1
    assert np.unique(cluster_points(points, 2000.0)).size == 1
    assert cluster_points(points[:1], 96.0).tolist() == [0]
    assert cluster_points(np.zeros((0, 2)), 96.0).shape == (0,)


def test_hull_depth_on_a_square():
    square = [(0, 0), (10, 0), (10, 10), (0, 10), (5, 5)]
    assert hull_depth(square, (5, 5)) == pytest.approx(5)
    assert hull_depth(square, (1, 4)) == pytest.approx(1)
    assert hull_depth(square, (-2, 5)) == pytest.approx(-2)
    assert hull_depth([(0, 0), (5, 5), (10, 10)], (5, 5)) == -np.inf  # collinear
    assert hull_depth([(0, 0), (5, 5)], (1, 1)) == -np.inf


def test_interior_cluster_needs_the_margin_and_candidates():
    centres = np.array([(20, 288), (748, 288), (384, 20), (384, 556), (384, 300)], float)
    candidates = np.ones(5, bool)
    assert interior_clusters(centres, candidates, 48.0).tolist() == [0, 0, 0, 0, 1]
    # 206 px inside the others' hull: not interior under a larger margin
    assert not interior_clusters(centres, candidates, 210.0).any()
    # without the top cluster the others' hull is a triangle with the centre 12 px inside
    no_top = candidates.copy()
    no_top[2] = False
    assert interior_clusters(centres, no_top, 10.0).tolist() == [0, 0, 0, 0, 1]
    assert not interior_clusters(centres, no_top, 48.0).any()


def test_zone_box_is_median_plus_minus_robust_std_clipped():
    points = np.array([(10.0, 100.0), (20.0, 110.0), (30.0, 120.0), (25.0, 500.0)])
    x, y, w, h = zone_box(points, WIDTH, HEIGHT, num_std=2.0, padding=25.0)
    # x: median 22.5, MAD 5 -> half 2 * 5 * 1.4826 + 25; y: median 115, MAD 10 (the outlier
    # at 500 moves it little)
    half_x, half_y = 2 * 5 * MAD_TO_STD + 25, 2 * 10 * MAD_TO_STD + 25
    assert (x, w) == pytest.approx((0.0, 22.5 + half_x))  # clipped at the left border
    assert (y, h) == pytest.approx((115 - half_y, 2 * half_y))


def test_interior_endpoints_are_not_a_zone():
    # 5 people from each image edge walk to the middle and vanish there (say behind a
    # kiosk): the middle cluster lies deep inside the hull of the edge clusters.
    rng = np.random.default_rng(2)
    edges = [(15, 288), (753, 288), (384, 15), (384, 561)]
    frames, ids, centres = [], [], []
    for k, edge in enumerate(np.repeat(edges, 5, axis=0)):
        start = edge + rng.normal(0, 5, 2)
        end = np.array([384, 288]) + rng.normal(0, 8, 2)
        for step, t in enumerate(np.linspace(0, 1, 20)):
            frames.append(10 + 3 * k + step)
            ids.append(k)
            centres.append(start + t * (end - start))
    boxes = boxes_at(centres)
    learned = learn_zones(np.array(frames), np.array(ids), boxes, (1, 200), WIDTH, HEIGHT)
    centres = box_centres(learned.scene.boxes)
    assert len(centres) == 4 and learned.interior.sum() == 1
    medians = learned.cluster_centres[learned.zone_clusters]
    for edge in edges:  # box centres move when a box is clipped at the image border
        assert np.min(np.linalg.norm(medians - edge, axis=1)) < 10
        assert np.min(np.linalg.norm(centres - edge, axis=1)) < 20
    assert learned.entries.tolist() == [5, 5, 5, 5] and learned.exits.tolist() == [0, 0, 0, 0]


@pytest.mark.parametrize("seed", [0, 1])
def test_zones_of_a_synthetic_scene_with_known_zones(seed):
    gt = generate_scene(seed, CROSSING_SCENE).gt_table
    learned = learn_zones(gt.frames, gt.ids, gt.boxes, (1, CROSSING_FRAMES), WIDTH, HEIGHT)
    centres = box_centres(learned.scene.boxes)
    for zone, feet in zip(CROSSING_ZONES, zone_feet(CROSSING_ZONES, CROSSING_SCENE), strict=True):
        distance = np.linalg.norm(centres - feet, axis=1)
        nearest = int(np.argmin(distance))
        assert distance[nearest] <= 20.0, zone.name
        assert learned.entries[nearest] > 0 and learned.exits[nearest] > 0, zone.name
    middle = (np.abs(centres[:, 0] - WIDTH / 2) < 0.3 * WIDTH) & (
        np.abs(centres[:, 1] - HEIGHT / 2) < 0.3 * HEIGHT
    )
    assert not middle.any(), centres[middle]
    boxes = learned.scene.boxes
    assert np.all(boxes[:, :2] >= 0) and np.all(boxes[:, :2] + boxes[:, 2:] <= [WIDTH, HEIGHT])


def test_no_start_or_end_inside_the_margins_is_an_error():
    rows = np.array([(f, 1, 100.0, 100.0) for f in range(1, 11)])
    with pytest.raises(InputError, match="no trajectory starts or ends"):
        learn_zones(rows[:, 0], rows[:, 1], boxes_at(rows[:, 2:]), (1, 10), WIDTH, HEIGHT)
    with pytest.raises(InputError, match="no trajectory in frames 1:10"):
        learn_zones(np.zeros(0), np.zeros(0), np.zeros((0, 4)), (1, 10), WIDTH, HEIGHT)


def test_zones_from_the_true_birth_intensity_sit_on_the_true_zones():
    config = SceneConfig(num_frames=50)
    scene = generate_scene(0, config)
    boxes, shares = zones_from_intensity(scene.birth_intensity, WIDTH, HEIGHT)
    zones = config.zones
    weights = np.array([zone.weight for zone in zones])
    np.testing.assert_allclose(np.sort(shares), np.sort(weights / weights.sum()), rtol=1e-6)
    assert np.all(np.diff(shares) <= 0)  # largest first
    # the truth's Gaussians are the zones: their mean feet exact, 2-std boxes
    for zone, feet in zip(zones, zone_feet(zones, config), strict=True):
        k = int(np.argmin(np.linalg.norm(box_centres(boxes) - feet, axis=1)))
        np.testing.assert_allclose(box_centres(boxes)[k], feet, atol=1e-3)
        assert boxes[k, 2] == pytest.approx(4 * zone.position_std[0], rel=1e-4)


def test_zones_from_intensity_weigh_by_the_gaussian_share_and_clip():
    intensity = Intensity(
        magnitude=jnp.asarray(0.1),
        uniform_weight=jnp.asarray(0.5),
        lower=jnp.zeros(6),
        upper=jnp.ones(6),
        weights=jnp.asarray([0.7, 0.25, 0.05]),
        means=jnp.asarray(
            [[10.0, 0, 300, 0, 30, 80], [400, 0, 200, 0, 30, 80], [500, 0, 50, 0, 30, 80]]
        ),
        covs=jnp.broadcast_to(jnp.diag(jnp.asarray([100.0, 1, 400, 1, 1, 1])), (3, 6, 6)),
    )
    boxes, shares = zones_from_intensity(intensity, WIDTH, HEIGHT, min_share=0.1)
    np.testing.assert_allclose(shares, [0.35, 0.125])  # the third has 0.025 < 0.1
    # feet y2 + h / 2: means 300 + 40 and 200 + 40, std sqrt(400 + 1 / 4)
    half = 2 * np.sqrt(400.25)
    expected = [[0, 340 - half, 30, 2 * half], [380, 240 - half, 40, 2 * half]]
    np.testing.assert_allclose(boxes, expected, atol=1e-4)


def loop_distance(boxes, point) -> float:
    best = np.inf
    for x, y, w, h in boxes:
        dx = max(x - point[0], 0.0, point[0] - (x + w))
        dy = max(y - point[1], 0.0, point[1] - (y + h))
        best = min(best, float(np.hypot(dx, dy)))
    return best


def test_zone_distance_matches_a_loop_under_jit_and_vmap():
    rng = np.random.default_rng(3)
    boxes = np.c_[rng.uniform(0, 600, (5, 2)), rng.uniform(10, 150, (5, 2))].astype(np.float32)
    points = rng.uniform(-50, 800, (40, 2)).astype(np.float32)
    expected = np.array([loop_distance(boxes, p) for p in points])
    np.testing.assert_allclose(zone_distance(boxes, points), expected, rtol=1e-5, atol=1e-3)
    jitted = jax.jit(zone_distance)(boxes, points)
    np.testing.assert_allclose(jitted, zone_distance(boxes, points), rtol=1e-6)
    mapped = jax.vmap(zone_distance, in_axes=(None, 0))(boxes, points)
    np.testing.assert_allclose(mapped, expected, rtol=1e-5, atol=1e-3)
    assert float(zone_distance(boxes, boxes[0, :2] + 1)) == 0.0  # inside a zone
    assert np.all(np.isinf(zone_distance(np.zeros((0, 4)), points)))
