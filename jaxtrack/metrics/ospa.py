"""Set distances between the gt boxes and the tracker boxes of each frame: OSPA and GOSPA.

For a frame with gt set ``X`` (``n`` boxes), tracker set ``Y`` (``m`` boxes), base distance
``d`` (``1 - IoU`` or the distance between box centres), cut-off ``c > 0`` and order
``p >= 1``, write ``d_c = min(d, c)`` and let an optimal assignment pair ``min(n, m)`` boxes
minimising ``sum d_c^p``; ``S`` is the sum of ``d^p`` over its pairs with ``d < c`` and ``k``
their number (pairs at the cut-off count as unassigned, which costs the same).

* **OSPA** (Schuhmacher, Vo & Vo 2008), ``N = max(n, m)``:
  ``OSPA = ((S + c^p (N - k)) / N)^(1/p)``, with localisation
  ``((S + c^p (min(n, m) - k)) / N)^(1/p)`` and cardinality ``(c^p (N - min(n, m)) / N)^(1/p)``
  components, ``OSPA^p = loc^p + card^p``; 0 when both sets are empty.
* **GOSPA** with ``alpha = 2`` (Rahmathullah, Garcia-Fernandez & Svensson 2017):
  ``GOSPA = (S + c^p / 2 (n + m - 2k))^(1/p)``, with localisation ``S^(1/p)``, missed
  ``(c^p / 2 (n - k))^(1/p)`` and false ``(c^p / 2 (m - k))^(1/p)`` components,
  ``GOSPA^p = loc^p + missed^p + false^p``.

Sequence scores average the per-frame values over every frame of the evaluated span
(frames where both sets are empty count with distance 0).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment

from jaxtrack.metrics.matching import assign_frames, box_similarity, centre_distance
from jaxtrack.metrics.preprocess import SequenceData

#: Base distances between boxes.
DISTANCES = ("iou", "centre")
#: Per-frame values, averaged over frames for a sequence.
SCORES = (
    "OSPA",
    "OSPA_localisation",
    "OSPA_cardinality",
    "GOSPA",
    "GOSPA_localisation",
    "GOSPA_missed",
    "GOSPA_false",
)


def check_parameters(cutoff: float, order: float, distance: str = "iou") -> None:
    """Raises ValueError unless ``cutoff > 0``, ``order >= 1`` and a known distance."""
    if not (np.isfinite(cutoff) and cutoff > 0):
        raise ValueError(f"OSPA cut-off c must be positive, got {cutoff}")
    if not (np.isfinite(order) and order >= 1):
        raise ValueError(f"OSPA order p must be >= 1, got {order}")
    if distance not in DISTANCES:
        raise ValueError(f"OSPA distance must be one of {DISTANCES}, got {distance!r}")


def set_distances(distance: np.ndarray, cutoff: float = 1.0, order: float = 1.0) -> dict:
    """OSPA and GOSPA (alpha = 2) of one frame, with their components.

    Args:
        distance: ``[n, m]`` base distances between the ``n`` gt and ``m`` tracker elements.
        cutoff: ``c > 0``.
        order: ``p >= 1``.

    Returns:
        The values named in ``SCORES``, as floats.
    """
    check_parameters(cutoff, order)
    distance = np.asarray(distance, dtype=float)
    n, m = distance.shape
    cost = np.minimum(distance, cutoff) ** order
    rows, cols = linear_sum_assignment(cost)
    inside = distance[rows, cols] < cutoff
    assigned_cost = np.sum(cost[rows, cols][inside])
    values = _frame_values(
        np.array([assigned_cost]),
        np.array([inside.sum()]),
        np.array([n]),
        np.array([m]),
        cutoff,
        order,
    )
    return {key: float(value[0]) for key, value in values.items()}


def set_distance_frames(
    data: SequenceData,
    cutoff: float = 1.0,
    order: float = 1.0,
    distance: str = "iou",
) -> dict:
    """OSPA/GOSPA of every frame of a sequence (e.g. to plot them over time).

    Frames whose pairs closer than the cut-off share no box are assigned without solving;
    the others are solved with the Hungarian algorithm.

    Args:
        data: the scored boxes.
        cutoff: ``c > 0``, in units of the distance (1 is the natural choice for ``1 - IoU``;
            pixels for centre distance).
        order: ``p >= 1``.
        distance: ``"iou"`` for ``1 - IoU`` or ``"centre"`` for the centre distance.

    Returns:
        ``{score: [num_frames] values}`` for ``SCORES``; index ``t`` is frame
        ``data.first_frame + t``.
    """
    check_parameters(cutoff, order, distance)
    pairs = data.pairs
    gt_boxes = data.gt_boxes[pairs.gt_row]
    tracker_boxes = data.tracker_boxes[pairs.tracker_row]
    if distance == "iou":
        base = 1.0 - box_similarity(gt_boxes, tracker_boxes)
    else:
        base = centre_distance(gt_boxes, tracker_boxes)
    cost = np.minimum(base, cutoff) ** order
    inside = base < cutoff
    assigned = assign_frames(pairs, cutoff**order - cost, inside, data.num_rows)
    assigned_cost = np.bincount(
        pairs.frame[assigned], weights=cost[assigned], minlength=data.num_frames
    )
    assigned_count = np.bincount(pairs.frame[assigned], minlength=data.num_frames)
    return _frame_values(
        assigned_cost, assigned_count, pairs.num_gt, pairs.num_tracker, cutoff, order
    )


def set_distance_fields(
    data: SequenceData,
    cutoff: float = 1.0,
    order: float = 1.0,
    distance: str = "iou",
) -> dict:
    """Per-frame OSPA/GOSPA of a sequence summed over frames (see
    :func:`set_distance_frames`), with ``num_frames``: the additive fields."""
    values = set_distance_frames(data, cutoff, order, distance)
    fields = {key: float(np.sum(value)) for key, value in values.items()}
    fields["num_frames"] = data.num_frames
    return fields


def set_distance_scores(fields: dict) -> dict:
    """Frame averages of the summed per-frame values."""
    return {key: fields[key] / max(1, fields["num_frames"]) for key in SCORES}


def _frame_values(assigned_cost, assigned_count, num_gt, num_tracker, cutoff, order) -> dict:
    """Per-frame OSPA/GOSPA terms from the optimal assignment (see the module docstring)."""
    penalty = cutoff**order
    larger = np.maximum(num_gt, num_tracker)
    smaller = np.minimum(num_gt, num_tracker)
    safe_larger = np.maximum(larger, 1)
    unassigned_in_smaller = smaller - assigned_count
    root = 1.0 / order
    return {
        "OSPA": ((assigned_cost + penalty * (larger - assigned_count)) / safe_larger) ** root,
        "OSPA_localisation": ((assigned_cost + penalty * unassigned_in_smaller) / safe_larger)
        ** root,
        "OSPA_cardinality": (penalty * (larger - smaller) / safe_larger) ** root,
        "GOSPA": (assigned_cost + penalty / 2 * (num_gt + num_tracker - 2 * assigned_count))
        ** root,
        "GOSPA_localisation": assigned_cost**root,
        "GOSPA_missed": (penalty / 2 * (num_gt - assigned_count)) ** root,
        "GOSPA_false": (penalty / 2 * (num_tracker - assigned_count)) ** root,
    }
