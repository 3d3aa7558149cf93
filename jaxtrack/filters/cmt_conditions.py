"""Motion conditions of CMT's contextual proposal and their probabilities (CMT eqs. 6-10).

Each local tracker (mixture component) ``m`` first draws a motion condition ``h`` from
``{normal, split, merge, exit}`` (CMT Sec. IV-B; ``enter`` concerns births, not the
particles of a living component), then a particle from the condition's proposal
(:mod:`~jaxtrack.filters.cmt_proposal`). The condition probabilities come from the spatial
context of the previous local decisions ``x_{t-1}``:

* ``d_O(m, j)``: distance between the box centres of ``m`` and another living component
  ``j``, divided by the height of ``m``;
* ``d_B(m)``: distance from the foot point ``(cx, cy + h / 2)`` of ``m`` to the nearest
  entry/exit zone (:func:`~jaxtrack.context.zones.zone_distance`), in pixels.

Distances are in units of the component's box height, so the defaults hold across image
resolutions and for near and far targets alike (the paper states them in pixels).

* eq. 7: ``p(normal) = min(min_j d_O(m, j) / d_thr, 1 - eps)``; a lone component gets
  ``1 - eps``;
* eqs. 8-10: the rest ``1 - p(normal)`` is shared between split, merge and exit in
  proportion to ``p~(split) = p~(merge) = exp(-min_j d_O(m, j))`` and ``p~(exit) =
  exp(-d_B(m) / (zone_scale h_m))`` (computed as a softmax of the log values, so far-away
  context does not underflow to 0 / 0). Without any zone ``p~(exit) = 0``; a lone
  component in a scene without zones has no context at all and gets ``p(normal) = 1``.
  Taken literally, eq. 8 gives a lone component ``p(exit) = eps`` however far it is from
  every zone (``d_B`` only sets exit's share against split and merge); the blob evidence
  below lowers it where a blob supports the target;
* eq. 6, blob evidence: ``q(h) = p(h) p(z~ | h) / sum_h' p(h') p(z~ | h')`` with ``p(z~ |
  exit) = exit_penalty`` when a foreground blob lies near the component's constant-velocity
  prediction (within ``blob_gate`` box heights of its centre) and 1 otherwise: a blob where
  the target should be speaks against its exit; and ``p(z~ | normal) = p(z~ | split) =
  group_penalty`` for a member of a *group blob* (:func:`group_members`: one blob that is
  the box of two targets together): one box over several targets speaks for a merge, whose
  particles follow the constant-velocity prediction instead of being drawn onto the group's
  box. The paper's enter bonus belongs to the births.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from jaxtrack.boxes import cxcywh_to_xywh, iou_matrix, xywh_to_cxcywh
from jaxtrack.context.zones import zone_distance
from jaxtrack.filters.births import LOG_ZERO
from jaxtrack.models.dynamics import MEASURED, POSITION, SIZE, transition_matrix
from jaxtrack.types import Detections

#: Motion conditions (CMT Sec. IV-B); a particle draws one of the first
#: :data:`NUM_PARTICLE_CONDITIONS`, ``ENTER`` marks births.
NORMAL, SPLIT, MERGE, EXIT, ENTER = range(5)
NUM_PARTICLE_CONDITIONS = 4
#: Least IoU of a blob with the bounding box of two components' predicted boxes for the
#: blob to be their group blob (:func:`group_members`).
GROUP_IOU = 0.5
#: Stands in for the estimates of dead slots (which may hold zeros): no division by a zero
#: height, so no NaN gradient through the masked rows.
UNIT_BOX_STATE = (0.0, 0.0, 0.0, 0.0, 1.0, 1.0)


class CPDParams(NamedTuple):
    """Parameters of the contextual proposal (a PyTree: vmap to sweep, grad to tune).

    Distances are in units of the box height of the component (or particle) concerned.

    Attributes:
        context_distance: ``d_thr`` of eq. 7, box heights, > 0.
        normal_floor: ``eps`` of eq. 7, in ``(0, 1)``: the least probability left to the
            other conditions.
        zone_scale: ``p~(exit) = exp(-d_B / (zone_scale h))`` (eq. 9), box heights, > 0.
        blob_gate: a blob is near a (predicted) box when its centre lies within
            ``blob_gate`` box heights of the box centre, > 0.
        blob_spread: ``(s_1, s_2, s_w, s_h)``, > 0: standard deviations of a blob's box
            around the target's (its centre and size), relative to the blob's size
            (SDV-style: ``s * (w, h, w, h)``); the spread of the Gaussian around a blob.
        defensive_weight: ``beta`` in ``[0, 1]``: the share of the blob-driven proposal
            drawn from the constant-velocity transition, so that ``q`` has the prior's tails.
        exit_penalty: ``p(z~ | exit)`` in ``(0, 1]`` when a blob is near the component's
            prediction (eq. 6).
        group_area_ratio: a blob is a *group blob* when it is the box of two living
            components' predicted boxes together, each of which covers at most this
            fraction of the pair's bounding box and of the blob (:func:`group_members`); 0
            turns group blobs off.
        group_penalty: ``p(z~ | normal) = p(z~ | split)`` in ``(0, 1]`` for a member of a
            group blob (eq. 6: one blob over several targets speaks for a merge).
    """

    context_distance: Float[Array, ""]
    normal_floor: Float[Array, ""]
    zone_scale: Float[Array, ""]
    blob_gate: Float[Array, ""]
    blob_spread: Float[Array, " 4"]
    defensive_weight: Float[Array, ""]
    exit_penalty: Float[Array, ""]
    group_area_ratio: Float[Array, ""]
    group_penalty: Float[Array, ""]


def default_cpd_params() -> CPDParams:
    """Defaults: ``d_thr`` 1.5 heights, ``eps`` 0.05 (CMT Sec. IV-B), the rest chosen here.

    Group blobs are off (``group_area_ratio`` 0): on the development scenes they did not
    pay (README, CMT section, "Group blobs"); 0.6 is the setting measured there.

    ``blob_spread`` is the toolkit's default SDV measurement noise
    (:data:`~jaxtrack.filters.phd_defaults.DEFAULT_MEASUREMENT_NOISE_STD`): the blobs are the
    detections of the box likelihood, and with the same spread the blob-driven proposal is
    that likelihood's locally optimal proposal (README, measured effective sample sizes).
    """
    return CPDParams(
        context_distance=jnp.asarray(1.5, jnp.float32),
        normal_floor=jnp.asarray(0.05, jnp.float32),
        zone_scale=jnp.asarray(1.0, jnp.float32),
        blob_gate=jnp.asarray(1.0, jnp.float32),
        blob_spread=jnp.asarray([0.15, 0.08, 0.25, 0.15], jnp.float32),
        defensive_weight=jnp.asarray(0.1, jnp.float32),
        exit_penalty=jnp.asarray(0.1, jnp.float32),
        group_area_ratio=jnp.asarray(0.0, jnp.float32),
        group_penalty=jnp.asarray(0.1, jnp.float32),
    )


def predicted_mean(states: Float[Array, "*batch 6"]) -> Float[Array, "*batch 6"]:
    """The constant-velocity prediction ``G x`` (the transition's mean, ``T = 1``)."""
    return states @ transition_matrix().T


def near_blobs(
    predictions: Float[Array, "*batch 6"], blobs: Detections, blob_gate: Float[Array, ""]
) -> Bool[Array, "*batch max_detections"]:
    """True for each real blob whose centre lies within ``blob_gate`` heights of a box's.

    Args:
        predictions: predicted states; the height of each scales its gate.
        blobs: the frame's padded foreground blobs (padded slots are never near).
        blob_gate: gate radius, box heights.

    Returns:
        ``[..., max_detections]``.
    """
    centres = xywh_to_cxcywh(blobs.boxes, jnp)[:, :2]
    gap = predictions[..., None, POSITION] - centres
    radius = blob_gate * predictions[..., SIZE[1]]
    return blobs.mask & (jnp.sum(gap * gap, axis=-1) <= (radius * radius)[..., None])


def centres_inside(
    predictions: Float[Array, "max_components 6"],
    alive: Bool[Array, " max_components"],
    blobs: Detections,
) -> Bool[Array, "max_components max_detections"]:
    """``inside[m, j]``: living component ``m``'s predicted centre lies in real blob ``j``
    (edges included)."""
    centres = predictions[:, POSITION]
    low, high = blobs.boxes[:, :2], blobs.boxes[:, :2] + blobs.boxes[:, 2:]
    inside = jnp.all((centres[:, None] >= low) & (centres[:, None] <= high), axis=-1)
    return inside & alive[:, None] & blobs.mask[None, :]


def group_members(
    predictions: Float[Array, "max_components 6"],
    alive: Bool[Array, " max_components"],
    blobs: Detections,
    group_area_ratio: Float[Array, ""],
) -> Bool[Array, "max_components max_detections"]:
    """``member[m, j]``: blob ``j`` is a group blob and component ``m`` one of its members.

    Components ``m`` and ``k`` (living, their predicted boxes ``B_m``, ``B_k``) form a group
    on blob ``j`` when the blob is the box of the pair rather than of either: its IoU with
    the pair's bounding box ``H_mk`` is at least :data:`GROUP_IOU` and above its IoU with
    either predicted box (``H_mk`` explains the blob better), each predicted box covers
    at most ``group_area_ratio`` of ``H_mk``'s area and of the blob's (the other target
    widens the pair; the blob is too large for one of them), and both predicted centres lie
    inside the blob. Targets walking together or crossing, seen by the
    detector as one box, form groups; a second component inside one target's box does not.

    Args:
        predictions: the components' constant-velocity predictions.
        alive: the living components.
        blobs: the frame's padded foreground blobs (padded slots are never groups).
        group_area_ratio: largest predicted-box-to-pair-box area ratio (0: no groups).

    Returns:
        ``[max_components, max_detections]``.
    """
    boxes = cxcywh_to_xywh(predictions[:, MEASURED], jnp)
    low, high = boxes[:, :2], boxes[:, :2] + boxes[:, 2:]
    hull_low = jnp.minimum(low[:, None], low[None, :])
    hull_high = jnp.maximum(high[:, None], high[None, :])
    hulls = jnp.concatenate([hull_low, hull_high - hull_low], axis=-1)
    overlap = iou_matrix(hulls.reshape(-1, 4), blobs.boxes, jnp).reshape(*hulls.shape[:2], -1)
    area = boxes[:, 2] * boxes[:, 3]
    hull_area = hulls[..., 2] * hulls[..., 3]
    widened = jnp.maximum(area[:, None], area[None, :]) <= group_area_ratio * hull_area
    inside = centres_inside(predictions, alive, blobs)
    pairs = alive[:, None] & alive[None, :] & ~jnp.eye(alive.shape[0], dtype=bool) & widened
    own = iou_matrix(boxes, blobs.boxes, jnp)
    better = (overlap > own[:, None, :]) & (overlap > own[None, :, :])
    blob_area = blobs.boxes[:, 2] * blobs.boxes[:, 3]
    larger = jnp.maximum(area[:, None], area[None, :])[..., None] <= group_area_ratio * blob_area
    grouped = pairs[..., None] & (overlap >= GROUP_IOU) & better & larger
    grouped = grouped & inside[:, None] & inside[None, :]
    return jnp.any(grouped, axis=1)


def sharing_blob(
    predictions: Float[Array, "max_components 6"],
    alive: Bool[Array, " max_components"],
    blobs: Detections,
) -> Bool[Array, " max_components"]:
    """True for a living component whose predicted centre lies inside a real blob that also
    holds another living component's predicted centre: one box over two targets (a merge,
    CMT Sec. IV-B), which says where the pair is but not how each of them moves.

    Args:
        predictions: the components' constant-velocity predictions.
        alive: the living components.
        blobs: the frame's padded foreground blobs (padded slots hold nothing).

    Returns:
        ``[max_components]``.
    """
    inside = centres_inside(predictions, alive, blobs).astype(jnp.float32)
    shared = (inside @ inside.T) > 0  # [m, k]: some blob holds both centres
    return jnp.any(shared & ~jnp.eye(alive.shape[0], dtype=bool), axis=1)


def object_distances(
    estimates: Float[Array, "max_components 6"], alive: Bool[Array, " max_components"]
) -> tuple[Float[Array, " max_components"], Bool[Array, " max_components"]]:
    """``min_j d_O(m, j)``: centre distance to the nearest other living component / ``h_m``.

    Args:
        estimates: the components' previous local decisions.
        alive: the living components.

    Returns:
        The distances (0 where there is no other living component) and whether there is one.
    """
    num = estimates.shape[0]
    others = alive[None, :] & ~jnp.eye(num, dtype=bool)
    gap = estimates[:, None, POSITION] - estimates[None, :, POSITION]
    squared = jnp.where(others, jnp.sum(gap * gap, axis=-1), 1.0)
    distance = jnp.where(others, jnp.sqrt(squared), jnp.inf)
    has_other = jnp.any(others, axis=1)
    nearest = jnp.where(has_other, jnp.min(distance, axis=1), 0.0)
    return nearest / estimates[:, SIZE[1]], has_other


def foot_zone_distances(
    estimates: Float[Array, "max_components 6"],
    zone_boxes: Float[Array, "num_zones 4"],
    zone_mask: Bool[Array, " num_zones"],
) -> Float[Array, " max_components"]:
    """``min d_B(m, .)``: pixels from the foot point ``(cx, cy + h / 2)`` to the nearest zone.

    Args:
        estimates: the components' previous local decisions.
        zone_boxes: padded ``(x, y, w, h)`` zone boxes.
        zone_mask: True for the real zones.

    Returns:
        The distances; 0 when there is no zone (check ``zone_mask`` first).
    """
    feet = jnp.stack(
        [estimates[:, POSITION[0]], estimates[:, POSITION[1]] + estimates[:, SIZE[1]] / 2], -1
    )
    per_zone = jax.vmap(lambda box: zone_distance(box[None], feet))(zone_boxes)
    nearest = jnp.min(jnp.where(zone_mask[:, None], per_zone, jnp.inf), axis=0)
    return jnp.where(jnp.any(zone_mask), nearest, 0.0)


def condition_probabilities(
    estimates: Float[Array, "max_components 6"],
    alive: Bool[Array, " max_components"],
    zone_boxes: Float[Array, "num_zones 4"],
    zone_mask: Bool[Array, " num_zones"],
    blobs: Detections,
    params: CPDParams,
    groups: Bool[Array, "max_components max_detections"] | None = None,
) -> Float[Array, "max_components 4"]:
    """``q(h | x_{t-1}, z~_t)`` of each component (CMT eqs. 6-10; module docstring).

    Args:
        estimates: the components' previous local decisions ``x_{t-1}`` (any values in dead
            slots).
        alive: the living components.
        zone_boxes: padded entry/exit zone boxes ``(x, y, w, h)``, pixels.
        zone_mask: True for the real zones.
        blobs: the frame's padded foreground blobs ``z~_t``.
        params: the proposal's parameters.
        groups: :func:`group_members` of the estimates' predictions, when the caller has
            them; None: computed here.

    Returns:
        ``[max_components, 4]`` probabilities of ``(NORMAL, SPLIT, MERGE, EXIT)``, rows
        summing to 1; ``(1, 0, 0, 0)`` for dead slots.
    """
    estimates = jnp.where(alive[:, None], estimates, jnp.asarray(UNIT_BOX_STATE))
    heights = estimates[:, SIZE[1]]
    d_object, has_other = object_distances(estimates, alive)
    has_zone = jnp.any(zone_mask)
    d_zone = foot_zone_distances(estimates, zone_boxes, zone_mask)
    eps = params.normal_floor
    normal = jnp.where(has_other, jnp.minimum(d_object / params.context_distance, 1 - eps), 1 - eps)
    normal = jnp.where(has_other | has_zone, normal, 1.0)
    log_pair = jnp.where(has_other, -d_object, LOG_ZERO)
    log_exit = jnp.where(has_zone, -d_zone / (params.zone_scale * heights), LOG_ZERO)
    shares = jax.nn.softmax(jnp.stack([log_pair, log_pair, log_exit], -1), axis=-1)
    prior = jnp.concatenate([normal[:, None], (1 - normal)[:, None] * shares], axis=-1)
    blob_near = jnp.any(near_blobs(predicted_mean(estimates), blobs, params.blob_gate), axis=-1)
    exit_evidence = jnp.where(blob_near, params.exit_penalty, 1.0)
    if groups is None:
        groups = group_members(predicted_mean(estimates), alive, blobs, params.group_area_ratio)
    move_evidence = jnp.where(jnp.any(groups, axis=-1), params.group_penalty, 1.0)
    # p(z~ | h) in the columns' order (NORMAL, SPLIT, MERGE, EXIT) = (0, 1, 2, 3)
    ones = jnp.ones_like(move_evidence)
    evidence = jnp.stack([move_evidence, move_evidence, ones, exit_evidence], axis=-1)
    unnormalised = prior * evidence
    posterior = unnormalised / jnp.sum(unnormalised, axis=-1, keepdims=True)
    return jnp.where(alive[:, None], posterior, jax.nn.one_hot(NORMAL, NUM_PARTICLE_CONDITIONS))
