"""Fusion of a pool of trackers' responses for one target (Fusion Sec. 4; SPEC section 3).

For a target followed by ``M`` pool members with responses ``R_i`` (boxes ``(x, y, w, h)`` or
response maps: any array, the fusion is linear in them), some of them missing this frame
(``valid`` mask, fixed shape ``M``):

* **Confidence** (eq. 3-4, :func:`speed_similarity`, :func:`confidence`):
  ``S_i = (Sim_sp + Sim_app) / 2`` with ``Sim_sp = min(v_mean, v_k) / max(v_mean, v_k)``,
  ``v_mean`` the mean speed over the last ``N`` frames (the valid ones) and ``v_k`` the
  speed of this frame's response; ``Sim_sp = 1`` when both speeds are 0 (a standing
  person is consistent) and when there is no history yet. ``Sim_app`` in ``[0, 1]`` is the
  response's appearance similarity to the target's signature (e.g. a Bhattacharyya
  coefficient, :mod:`jaxtrack.appearance.similarity`).
* **Accordance** (eq. 5, :func:`accordance`): ``A_ij = (Sim_dist + Sim_ovrl + Sim_app) / 3``
  with ``Sim_ovrl`` the IoU of the two boxes and ``Sim_dist = exp(-d_ij / h_ij)``, ``d_ij``
  the distance of the box centres and ``h_ij`` the mean of the two box heights (the paper
  names the Euclidean distance as a similarity; dividing by the height makes it scale-free
  across the image's depth and maps it into ``(0, 1]`` like the other two cues).
* **Dynamic fusion** (eq. 6, :func:`fusion_weights`): over the unordered pairs ``i < j`` of
  valid members, ``R = sum_ij (A_ij / A_sum) (S_i R_i + S_j R_j) / (S_i + S_j)``, ``A_sum``
  the sum of the ``A_ij`` of the pairs taken. This is ``R = sum_k c_k R_k`` with member
  weights ``c_k = sum_{j != k} (A_kj / A_sum) S_k / (S_k + S_j)`` (summing to 1), so boxes
  and maps share one :func:`fuse`. A pair with ``S_i + S_j = 0`` has no intermediate
  result and is left out of the sum and of ``A_sum``; a member with ``S_i = 0`` thus gets
  weight 0. When no pair is left (a pool of one, or all confidences 0) the weights are
  equal over the valid members: a pool of one is that member alone.
* **Naive fusion** (Sec. 5.1 ablation, :func:`naive_weights`): the mean of the valid
  members' responses.

Pure JAX: every function works on one target and is vmapped over targets.
"""

from __future__ import annotations

import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from jaxtrack.boxes import iou_matrix, xywh_to_cxcywh


def speed_similarity(
    past_speeds: Float[Array, " num_past"],
    past_valid: Bool[Array, " num_past"],
    speed: Float[Array, ""],
) -> Float[Array, ""]:
    """``Sim_sp = min(v_mean, v_k) / max(v_mean, v_k)`` (Fusion eq. 3).

    Args:
        past_speeds: ``[N]`` speeds (pixels per frame) of the target's last ``N`` frames.
        past_valid: ``[N]`` which of them exist (a young target has fewer).
        speed: ``v_k``, the speed this frame's response implies.

    Returns:
        ``Sim_sp`` in ``[0, 1]``; 1 without history or when both speeds are 0.
    """
    count = jnp.sum(past_valid)
    mean = jnp.sum(jnp.where(past_valid, past_speeds, 0.0)) / jnp.maximum(count, 1)
    low, high = jnp.minimum(mean, speed), jnp.maximum(mean, speed)
    ratio = jnp.where(high > 0, low / jnp.where(high > 0, high, 1.0), 1.0)
    return jnp.where(count > 0, ratio, 1.0)


def confidence(
    speed_sim: Float[Array, "*members"], appearance_sim: Float[Array, "*members"]
) -> Float[Array, "*members"]:
    """``S_i = (Sim_sp + Sim_app) / 2`` (Fusion eq. 4), in ``[0, 1]`` for cues in ``[0, 1]``."""
    return (speed_sim + appearance_sim) / 2.0


def accordance(
    boxes: Float[Array, "num_members 4"],
    appearance_sim: Float[Array, "num_members num_members"],
) -> Float[Array, "num_members num_members"]:
    """``A_ij = (exp(-d_ij / h_ij) + IoU_ij + Sim_app_ij) / 3`` (Fusion eq. 5, module doc).

    Args:
        boxes: ``[M, 4]`` the members' boxes ``(x, y, w, h)`` (positive heights).
        appearance_sim: ``[M, M]`` appearance similarity of the members' responses, in
            ``[0, 1]`` (symmetric).

    Returns:
        ``[M, M]`` symmetric accordances in ``[0, 1]``.
    """
    centres = xywh_to_cxcywh(boxes, jnp)
    offset = centres[:, None, :2] - centres[None, :, :2]
    distance = jnp.sqrt(jnp.sum(offset * offset, axis=-1))
    height = (boxes[:, None, 3] + boxes[None, :, 3]) / 2.0
    distance_sim = jnp.exp(-distance / height)
    return (distance_sim + iou_matrix(boxes, boxes, jnp) + appearance_sim) / 3.0


def fusion_weights(
    confidences: Float[Array, " num_members"],
    accordances: Float[Array, "num_members num_members"],
    valid: Bool[Array, " num_members"],
) -> Float[Array, " num_members"]:
    """Member weights ``c_k`` of the dynamic fusion (Fusion eq. 6, module doc).

    Args:
        confidences: ``[M]`` ``S_i >= 0``.
        accordances: ``[M, M]`` ``A_ij >= 0`` (only ``i < j`` is read).
        valid: ``[M]`` members with a response this frame (at least one).

    Returns:
        ``[M]`` weights summing to 1, 0 for invalid members.
    """
    num_members = confidences.shape[0]
    upper = jnp.triu(jnp.ones((num_members, num_members), bool), k=1)
    pair_total = confidences[:, None] + confidences[None, :]
    taken = upper & valid[:, None] & valid[None, :] & (pair_total > 0)
    pair_weight = jnp.where(taken, accordances, 0.0)
    pair_sum = jnp.sum(pair_weight)
    safe_total = jnp.where(taken, pair_total, 1.0)
    # pair (i, j), i < j, gives R_i the weight A_ij S_i / (S_i + S_j) and R_j A_ij S_j / (...)
    to_first = pair_weight * confidences[:, None] / safe_total
    to_second = pair_weight * confidences[None, :] / safe_total
    member = jnp.sum(to_first, axis=1) + jnp.sum(to_second, axis=0)
    dynamic = member / jnp.where(pair_sum > 0, pair_sum, 1.0)
    return jnp.where(pair_sum > 0, dynamic, naive_weights(valid))


def naive_weights(valid: Bool[Array, " num_members"]) -> Float[Array, " num_members"]:
    """Equal weights over the valid members (the naive mean fusion, Fusion Sec. 5.1)."""
    return valid / jnp.maximum(jnp.sum(valid), 1)


def fuse(
    weights: Float[Array, " num_members"], responses: Float[Array, " num_members *response"]
) -> Float[Array, " *response"]:
    """``R = sum_k c_k R_k``: a fused box (``[M, 4]`` responses) or map (``[M, H, W]``).

    Invalid members must have weight 0; their responses may hold any finite value.
    """
    return jnp.tensordot(weights, responses, axes=1)
