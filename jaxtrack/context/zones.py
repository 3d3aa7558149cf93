"""Entry/exit zones of a scene, from training trajectories or a learned birth intensity.

Fusion Sec. 2.3 (scene structure; SPEC section 3): entry/exit zones are mapped from the
starting and ending points of training trajectories, excluding those in the first and last
frames of the training span (the people already there, or still there); the points are
clustered by Euclidean distance, each cluster marking a zone, and the clusters inside the
convex hull of the others are excluded ("a person cannot enter or exit from the inner area of
the hull"). The choices the paper leaves open, made here (each a parameter):

* **Point.** A trajectory's start (end) point is the *foot point* of its first (last) box,
  the middle of its bottom edge ``(x + w / 2, y + h)``
  (:func:`~jaxtrack.context.activity.foot_points`): an entry is a place on the ground where
  people come in (a door, a path leaving the image), and the feet stay on it whatever a
  person's height, while the box centre moves by half of it (with perspective, by different
  amounts across the image). The synthetic video's scripted zones are such ground regions.
  A tracker whose state is a box centre ``(cx, cy)`` with height ``h`` tests
  ``(cx, cy + h / 2)``.
* **Span margin.** A trajectory starting in the first ``margin_frames`` frames of the span
  gives no start point, one ending in its last ``margin_frames`` frames no end point.
* **Entry and exit together.** Start and end points are clustered as one set (the paper's
  "entry/exit zone"): a zone where people both come and go is one zone; each zone records how
  many of its points are starts (entries) and ends (exits).
* **Clusters.** Average-linkage hierarchical clustering (SciPy) cut at a mean inter-cluster
  distance of ``cluster_distance`` times the image diagonal: no fixed number of clusters.
  Clusters of fewer than ``min_points`` points are noise and dropped.
* **Interior clusters.** "Each identified cluster marks an entry/exit zone. Altogether, they
  form a convex hull": the hull of the zones, i.e. of the cluster centres (per-axis medians
  of their points). A cluster is interior when its centre lies inside the convex hull of the
  *other* clusters' centres by more than ``interior_margin`` times the image diagonal. The
  hull of centres, rather than of all points, and the margin keep a zone lying on the hull's
  border (a door in a wall between two edge zones, a zone beside a cloud of exits along the
  same image edge), which the strict test on the points' hull drops. One pass: the hulls are
  those of all clusters with enough points.
* **Zone box.** A robust ``mean +- num_std std`` of the cluster's points per axis: the median
  ``+- num_std * 1.4826 MAD`` (median absolute deviation; ``1.4826 MAD`` is the standard
  deviation of a Gaussian), so that a few points of another population (exits scattered
  along the edge next to an entry zone) move the zone little; padded by ``padding`` times the
  image diagonal and clipped to the image: an axis-aligned ``(x, y, w, h)`` box (top-left
  corner).

:func:`zones_from_intensity` gives zones from a learned birth intensity (PHD-context eq.
19-21): each Gaussian component with a large enough share of the density becomes the box
``mean +- num_std std`` of its foot point.

Learning is host-side NumPy/SciPy; :func:`zone_distance` is the per-frame query (JAX,
jit- and vmap-able).
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float
from scipy.cluster.hierarchy import fcluster, linkage
from scipy.spatial import ConvexHull, QhullError

from jaxtrack.context.activity import ACTIVITY_CELL, ACTIVITY_RADIUS, activity_mask, foot_points
from jaxtrack.context.intensity import Intensity
from jaxtrack.errors import InputError

#: Frames at each end of the training span whose trajectory starts / ends are not entries /
#: exits (the people already there, or still there).
MARGIN_FRAMES = 5
#: Cut of the average-linkage clustering, as a fraction of the image diagonal.
CLUSTER_DISTANCE = 0.1
#: Fewest points of a cluster that makes a zone.
MIN_POINTS = 3
#: Depth inside the other clusters' hull from which a cluster is interior (fraction of the
#: image diagonal).
INTERIOR_MARGIN = 0.05
#: Half-size of a zone box in standard deviations of its points (or of a Gaussian component).
NUM_STD = 2.0
#: The standard deviation of a Gaussian per unit of its median absolute deviation.
MAD_TO_STD = 1.4826
#: Padding of a zone box learned from points (fraction of the image diagonal).
PADDING = 0.02
#: ``F``: the foot point ``(y1, y2 + h / 2)`` of a birth state ``(y1, vy1, y2, vy2, w, h)``.
FOOT_MAP = np.array([[1.0, 0, 0, 0, 0, 0], [0, 0, 1, 0, 0, 0.5]])
#: Smallest share of the birth density ``(1 - pi_u) w_m`` of a component that makes a zone.
MIN_SHARE = 0.05


class SceneZones(NamedTuple):
    """The scene structure a tracker uses: entry/exit zones and the activity mask.

    Attributes:
        boxes: ``[num_zones, 4]`` zone boxes ``(x, y, w, h)``, top-left corner, pixels.
        activity: ``[rows, columns]`` boolean mask of the active cells (cell ``(i, j)``
            covers pixels ``[j c, (j + 1) c) x [i c, (i + 1) c)``), or None when unknown
            (zones from a birth intensity).
        cell_size: ``c``, the side of an activity cell in pixels (None without a mask).
    """

    boxes: Float[Array, "num_zones 4"]
    activity: np.ndarray | None
    cell_size: float | None


class Endpoints(NamedTuple):
    """Start and end points of trajectories.

    Attributes:
        points: ``[num_points, 2]`` foot points ``(x, y)``.
        is_entry: ``[num_points]`` True for a start point, False for an end point.
        frames: ``[num_points]`` 1-based frame of each point.
        ids: ``[num_points]`` trajectory of each point.
    """

    points: np.ndarray
    is_entry: np.ndarray
    frames: np.ndarray
    ids: np.ndarray


class LearnedZones(NamedTuple):
    """Zones learned from trajectories, with how they were found (for figures and reports).

    Attributes:
        scene: the zones and activity mask.
        endpoints: the start and end points clustered.
        labels: ``[num_points]`` cluster of each point, ``0..num_clusters-1``.
        cluster_sizes: ``[num_clusters]`` points per cluster.
        cluster_centres: ``[num_clusters, 2]`` per-axis medians of the clusters' points.
        interior: ``[num_clusters]`` True for a cluster dropped as interior.
        zone_clusters: ``[num_zones]`` cluster of each zone (zones ordered by size, largest
            first).
        entries: ``[num_zones]`` start points of each zone.
        exits: ``[num_zones]`` end points of each zone.
    """

    scene: SceneZones
    endpoints: Endpoints
    labels: np.ndarray
    cluster_sizes: np.ndarray
    cluster_centres: np.ndarray
    interior: np.ndarray
    zone_clusters: np.ndarray
    entries: np.ndarray
    exits: np.ndarray


def trajectory_endpoints(
    frames: np.ndarray,
    ids: np.ndarray,
    boxes: np.ndarray,
    span: tuple[int, int],
    margin_frames: int = MARGIN_FRAMES,
) -> Endpoints:
    """Start and end points of the trajectories, away from the span's ends (Fusion Sec. 2.3).

    Args:
        frames: ``[num_rows]`` 1-based frame of each box (inside ``span``).
        ids: ``[num_rows]`` trajectory of each box.
        boxes: ``[num_rows, 4]`` ``(x, y, w, h)``.
        span: ``(first, last)`` training frames, 1-based inclusive.
        margin_frames: a trajectory's first box is a start point only from frame
            ``first + margin_frames`` on, its last box an end point only up to frame
            ``last - margin_frames``.

    Returns:
        The points, starts and ends of each trajectory in order of its id.

    Raises:
        ValueError: a negative margin.
    """
    if margin_frames < 0:
        raise ValueError(f"margin_frames must be >= 0, got {margin_frames}")
    frames = np.asarray(frames, np.int64).reshape(-1)
    ids = np.asarray(ids, np.int64).reshape(-1)
    feet = foot_points(boxes)
    order = np.lexsort((frames, ids))
    _, starts, counts = np.unique(ids[order], return_index=True, return_counts=True)
    first_rows = order[starts]
    last_rows = order[starts + counts - 1]
    is_start = frames[first_rows] >= span[0] + margin_frames
    is_end = frames[last_rows] <= span[1] - margin_frames
    taken = np.stack([is_start, is_end], axis=1)
    rows = np.stack([first_rows, last_rows], axis=1)[taken]
    return Endpoints(
        points=feet[rows].reshape(-1, 2),
        is_entry=np.broadcast_to([True, False], taken.shape)[taken],
        frames=frames[rows],
        ids=ids[rows],
    )


def cluster_points(points: np.ndarray, max_distance: float) -> np.ndarray:
    """Average-linkage clusters: merged while their mean pairwise distance is at most a cut.

    Args:
        points: ``[num_points, 2]``.
        max_distance: the cut, pixels.

    Returns:
        ``[num_points]`` labels ``0..num_clusters-1`` (SciPy's ``fcluster`` order).
    """
    points = np.asarray(points, np.float64).reshape(-1, 2)
    if points.shape[0] < 2:
        return np.zeros(points.shape[0], np.int64)
    tree = linkage(points, method="average")
    return fcluster(tree, max_distance, criterion="distance").astype(np.int64) - 1


def hull_depth(hull_points: np.ndarray, point: np.ndarray) -> float:
    """How deep ``point`` lies inside the convex hull of ``hull_points``.

    Args:
        hull_points: ``[num_points, 2]``.
        point: ``[2]``.

    Returns:
        The distance from ``point`` to the hull's boundary, positive inside, negative
        outside; ``-inf`` when the hull has no interior (fewer than 3 points, or collinear).
    """
    hull_points = np.asarray(hull_points, np.float64).reshape(-1, 2)
    if hull_points.shape[0] < 3:
        return -np.inf
    try:
        hull = ConvexHull(hull_points)
    except QhullError:
        return -np.inf
    # facets a.x + b <= 0 inside, with unit normals a: the depth is the smallest -(a.x + b)
    return float(np.min(-(hull.equations[:, :2] @ np.asarray(point) + hull.equations[:, 2])))


def interior_clusters(centres: np.ndarray, candidates: np.ndarray, margin: float) -> np.ndarray:
    """Candidate clusters whose centre lies deeper than ``margin`` in the others' hull.

    Args:
        centres: ``[num_clusters, 2]`` cluster centres.
        candidates: ``[num_clusters]`` the clusters taking part (the others are neither
            tested nor vertices of a hull).
        margin: depth in pixels from which a centre is interior.

    Returns:
        ``[num_clusters]`` True for the interior candidates: inside the convex hull of the
        other candidates' centres, more than ``margin`` from its boundary.
    """
    interior = np.zeros(candidates.shape[0], bool)
    for cluster in np.flatnonzero(candidates):
        others = candidates.copy()
        others[cluster] = False
        interior[cluster] = hull_depth(centres[others], centres[cluster]) > margin
    return interior


def robust_centre(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-axis median and ``1.4826 * MAD`` (median absolute deviation) of ``[n, 2]`` points."""
    median = np.median(points, axis=0)
    return median, MAD_TO_STD * np.median(np.abs(points - median), axis=0)


def zone_box(
    points: np.ndarray, width: float, height: float, num_std: float, padding: float
) -> np.ndarray:
    """``median +- num_std * 1.4826 MAD`` of the points per axis, padded, clipped to the image.

    Args:
        points: ``[num_points, 2]`` (at least one).
        width: image width, pixels.
        height: image height, pixels.
        num_std: half-size in (robust) standard deviations.
        padding: added on each side, pixels.

    Returns:
        ``[4]`` ``(x, y, w, h)``.
    """
    centre, std = robust_centre(points)
    return _clipped_box(centre, num_std * std + padding, width, height)


def learn_zones(
    frames: np.ndarray,
    ids: np.ndarray,
    boxes: np.ndarray,
    span: tuple[int, int],
    width: float,
    height: float,
    *,
    margin_frames: int = MARGIN_FRAMES,
    cluster_distance: float = CLUSTER_DISTANCE,
    min_points: int = MIN_POINTS,
    interior_margin: float = INTERIOR_MARGIN,
    num_std: float = NUM_STD,
    padding: float = PADDING,
    cell_size: int = ACTIVITY_CELL,
    activity_radius: float = ACTIVITY_RADIUS,
) -> LearnedZones:
    """Entry/exit zones and activity mask of the trajectories of a training span.

    The stages (module docstring): :func:`trajectory_endpoints`, :func:`cluster_points`,
    :func:`interior_clusters`, :func:`zone_box` and
    :func:`~jaxtrack.context.activity.activity_mask`.

    Args:
        frames: ``[num_rows]`` 1-based frame of each box (inside ``span``).
        ids: ``[num_rows]`` trajectory of each box.
        boxes: ``[num_rows, 4]`` ``(x, y, w, h)``.
        span: ``(first, last)`` training frames.
        width: image width, pixels.
        height: image height, pixels.
        margin_frames: see :func:`trajectory_endpoints`.
        cluster_distance: clustering cut, fraction of the image diagonal.
        min_points: fewest points of a zone's cluster.
        interior_margin: interior depth, fraction of the image diagonal.
        num_std: zone half-size in standard deviations.
        padding: zone padding, fraction of the image diagonal.
        cell_size: activity cell side, pixels.
        activity_radius: activity dilation radius, pixels.

    Returns:
        The zones, largest cluster first, and how they were found.

    Raises:
        InputError: no trajectory starts or ends inside the span's margins.
    """
    if len(np.asarray(frames)) == 0:
        raise InputError(f"no trajectory in frames {span[0]}:{span[1]}")
    endpoints = trajectory_endpoints(frames, ids, boxes, span, margin_frames)
    if endpoints.points.shape[0] == 0:
        raise InputError(
            f"no trajectory starts or ends in frames {span[0]}:{span[1]} more than "
            f"{margin_frames} frames from the span's ends; use a longer span"
        )
    diagonal = float(np.hypot(width, height))
    labels = cluster_points(endpoints.points, cluster_distance * diagonal)
    sizes = np.bincount(labels)
    centres = np.stack([robust_centre(endpoints.points[labels == c])[0] for c in range(sizes.size)])
    candidates = sizes >= min_points
    interior = interior_clusters(centres, candidates, interior_margin * diagonal)
    kept = np.flatnonzero(candidates & ~interior)
    kept = kept[np.argsort(-sizes[kept], kind="stable")]
    zone_boxes = [
        zone_box(endpoints.points[labels == c], width, height, num_std, padding * diagonal)
        for c in kept
    ]
    entries = np.bincount(labels[endpoints.is_entry], minlength=sizes.size)[kept]
    scene = SceneZones(
        boxes=np.asarray(zone_boxes, np.float64).reshape(-1, 4),
        activity=activity_mask(frames, ids, boxes, width, height, cell_size, activity_radius),
        cell_size=float(cell_size),
    )
    return LearnedZones(
        scene=scene,
        endpoints=endpoints,
        labels=labels,
        cluster_sizes=sizes,
        cluster_centres=centres,
        interior=interior,
        zone_clusters=kept,
        entries=entries,
        exits=sizes[kept] - entries,
    )


def zones_from_intensity(
    intensity: Intensity,
    width: float,
    height: float,
    min_share: float = MIN_SHARE,
    num_std: float = NUM_STD,
) -> tuple[np.ndarray, np.ndarray]:
    """Zone boxes from a birth intensity's Gaussian components (PHD-context eq. 19-21).

    A component ``m`` of ``p(x | b) = pi_u u(x) + (1 - pi_u) sum_m w_m N(x; mu_m, Sigma_m)``
    whose share ``(1 - pi_u) w_m`` is at least ``min_share`` becomes the box ``F mu_m +-
    num_std sqrt(diag(F Sigma_m F^T))`` of the foot point ``F x = (y1, y2 + h / 2)`` (a
    linear map of the state, so exactly Gaussian), clipped to the image.

    Args:
        intensity: a 6-D birth intensity over ``(y1, vy1, y2, vy2, w, h)``.
        width: image width, pixels.
        height: image height, pixels.
        min_share: smallest share of the density of a zone's component.
        num_std: half-size in standard deviations.

    Returns:
        ``(boxes, shares)``: ``[num_zones, 4]`` boxes ``(x, y, w, h)`` and ``[num_zones]``
        their components' shares, largest share first.
    """
    share = (1.0 - float(intensity.uniform_weight)) * np.asarray(intensity.weights, np.float64)
    chosen = np.flatnonzero(share >= min_share)
    chosen = chosen[np.argsort(-share[chosen], kind="stable")]
    means = np.asarray(intensity.means, np.float64)[chosen] @ FOOT_MAP.T
    covs = FOOT_MAP @ np.asarray(intensity.covs, np.float64)[chosen] @ FOOT_MAP.T
    stds = np.sqrt(np.diagonal(covs, axis1=1, axis2=2))
    boxes = [
        _clipped_box(mean, num_std * std, width, height)
        for mean, std in zip(means, stds, strict=True)
    ]
    return np.asarray(boxes, np.float64).reshape(-1, 4), share[chosen]


def zone_distance(
    boxes: Float[Array, "num_zones 4"], points: Float[Array, "*batch 2"]
) -> Float[Array, "*batch"]:
    """Euclidean distance from each (foot) point to the nearest zone box (0 inside one).

    CMT's ``d_B`` (object-to-entry/exit-zone distance, CMT eq. 9): for a box ``(x, y, w, h)``
    the distance of ``p`` is ``|(max(x - p1, 0, p1 - x - w), max(y - p2, 0, p2 - y - h))|``.
    Pure JAX (jit- and vmap-able).

    Args:
        boxes: ``[num_zones, 4]`` ``(x, y, w, h)``.
        points: ``[..., 2]`` foot points ``(x, y)`` (:func:`~jaxtrack.context.activity.
            foot_points`).

    Returns:
        ``[...]`` distances in pixels; ``inf`` when there is no zone.
    """
    boxes = jnp.asarray(boxes)
    points = jnp.asarray(points)[..., None, :]
    lower, upper = boxes[:, :2], boxes[:, :2] + boxes[:, 2:]
    gap = jnp.maximum(jnp.maximum(lower - points, points - upper), 0.0)
    return jnp.min(jnp.sqrt(jnp.sum(gap * gap, axis=-1)), axis=-1, initial=jnp.inf)


def _clipped_box(centre: np.ndarray, half: np.ndarray, width: float, height: float) -> np.ndarray:
    """``(x, y, w, h)`` of ``centre +- half`` clipped to ``[0, width] x [0, height]``."""
    size = np.asarray([width, height], np.float64)
    lower = np.clip(centre - half, 0.0, size)
    upper = np.clip(centre + half, 0.0, size)
    return np.concatenate([lower, upper - lower])
