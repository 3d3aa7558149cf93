"""Fusion's target profile: signatures, occlusion status and re-identification (Fusion Sec. 2).

Every function works on a fixed table of ``S`` target slots (boxes ``[S, 4]`` as
``(x, y, w, h)``, an ``alive`` mask) and is jit-able; static sizes (patch shape, quantisation
step, ``min_rows``) are bound with ``functools.partial`` before ``jax.jit``.

* :func:`signatures`: each box's profile, the HSV histograms of its upper and lower parts
  split at the row maximising their Bhattacharyya distance (Fusion eq. 1);
* :func:`signature_distance`: the distance of two signatures;
* :func:`overlap_ratio` and :func:`occlusion_status`: occlusion groups from the box overlap
  ``Q`` (Fusion eq. 2) and, in each group, the occluder and the occluded targets;
* :func:`update_signatures` / :func:`start_signatures`: each target's running signature model
  (:mod:`jaxtrack.appearance.model`), frozen while the target is occluded;
* :func:`reidentify`: a newly initiated target against the occluded targets near it (Fusion
  Sec. 3.1, "validation process for each newly identified target").

The paper's signature also holds MSCR regions and is taken after a segmentation of the target
([12] of the paper); here it is the two HSV histograms of the whole box only.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int, UInt8

from jaxtrack.appearance.features import profile_histograms
from jaxtrack.appearance.model import AppearanceModel, init_model, update_model
from jaxtrack.appearance.similarity import bhattacharyya_distance
from jaxtrack.boxes import iou_matrix
from jaxtrack.errors import InputError


class Signature(NamedTuple):
    """The profile of a box (Fusion Sec. 2.1), one per slot when batched.

    Attributes:
        histograms: normalised HSV ``[upper, lower]`` histograms (all zero: no sample of the
            box lies inside the frame).
        row: the split row ``Y`` (first patch row of the lower part).
    """

    histograms: Float[Array, "*slots 2 num_bins"]
    row: Int[Array, "*slots"]


def signatures(
    frame: UInt8[Array, "height width 3"],
    boxes: Float[Array, "slots 4"],
    patch_shape: tuple[int, int],
    step: float,
    min_rows: int,
) -> Signature:
    """The signature of every box: Fusion eq. 1, ``Y = argmax_y d_Bh(h(I_u(y)), h(I_l(y)))``.

    :func:`~jaxtrack.appearance.features.profile_histograms` (nearest-pixel samples) vmapped
    over the boxes.

    Args:
        frame: RGB frame, uint8.
        boxes: ``(x, y, w, h)`` boxes, pixels (padded slots give meaningless signatures).
        patch_shape: ``(ph, pw)`` samples per box, static.
        step: quantisation step of H, S and V, static.
        min_rows: fewest patch rows in a part, static.
    """
    split = jax.vmap(profile_histograms, in_axes=(None, 0, None, None, None))(
        frame, boxes, patch_shape, step, min_rows
    )
    return Signature(split.histograms, split.row)


def signature_distance(
    a: Float[Array, "*shape 2 num_bins"], b: Float[Array, "*shape 2 num_bins"]
) -> Float[Array, "*shape"]:
    """``D(a, b) = (d_Bh(a_u, b_u) + d_Bh(a_l, b_l)) / 2``, in ``[0, 1]``.

    The mean Bhattacharyya distance of the upper parts and of the lower parts (the paper
    compares signatures without saying how; the parts weigh alike whatever their sizes). A
    missing part (all-zero histogram) is at distance 1.

    Args:
        a: ``[upper, lower]`` histograms (a signature's, or a model's mean ones).
        b: the same for the other signature; broadcasts against ``a``.
    """
    return jnp.mean(bhattacharyya_distance(a, b), axis=-1)


def overlap_ratio(boxes: Float[Array, "slots 4"]) -> Float[Array, "slots slots"]:
    """Fusion eq. 2 for every pair: ``Q(bb_l, bb_m) = 2 |bb_l ∩ bb_m| / |bb_l ∪ bb_m|``.

    As written, ``Q`` is twice the intersection over union: 0 for disjoint boxes, 2 for
    equal ones, so the paper's threshold ``Q > 0.3`` means ``IoU > 0.15`` (the paper calls it
    "an intersection of 30% of the total bb area"). Empty boxes overlap nothing.
    """
    return 2.0 * iou_matrix(boxes, boxes, xp=jnp)


class OcclusionStatus(NamedTuple):
    """Each slot's occlusion state (Fusion Sec. 2.2).

    Attributes:
        related: the target overlaps another (``Q > threshold``): it is in an occlusion group.
        occluded: related and not its group's occluder; its models stop updating.
        occluder: slot of the occluder of the target's group (itself for the occluder), -1
            for an independent target or a dead slot.
    """

    related: Bool[Array, " slots"]
    occluded: Bool[Array, " slots"]
    occluder: Int[Array, " slots"]


def occlusion_status(
    boxes: Float[Array, "slots 4"],
    alive: Bool[Array, " slots"],
    stored: Float[Array, "slots 2 num_bins"],
    observed: Float[Array, "slots 2 num_bins"],
    threshold: float | Float[Array, ""] = 0.3,
) -> OcclusionStatus:
    """Occlusion groups and their occluders (Fusion Sec. 2.2, eq. 2).

    Two alive targets are linked when ``Q > threshold`` (:func:`overlap_ratio`); an
    occlusion group is a connected component of the links (A overlapping B overlapping C is
    one group). In a group, the occluder is the target whose observed signature (extracted at
    its current box) is closest to its own stored one, ``argmin_i D(stored_i, observed_i)``
    (:func:`signature_distance`; ties go to the lowest slot): the visible target looks like
    itself, the hidden ones look like the occluder. The others are occluded.

    Args:
        boxes: the targets' current boxes.
        alive: which slots hold a target.
        stored: each target's stored signature (its model's mean histograms).
        observed: each target's signature in the current frame.
        threshold: ``Q`` above which two targets are occlusion-related (0.3 in the paper).

    Raises:
        InputError: the tables disagree on the number of slots.
    """
    num_slots = _check_slots(boxes, alive, stored, observed)
    linked = (overlap_ratio(boxes) > threshold) & alive[:, None] & alive[None, :]
    linked = linked & ~jnp.eye(num_slots, dtype=bool)
    related = jnp.any(linked, axis=1)
    groups = _connected(linked)
    own_distance = signature_distance(stored, observed)
    in_group_distance = jnp.where(groups, own_distance[None, :], jnp.inf)
    occluder = jnp.where(related, jnp.argmin(in_group_distance, axis=1), -1)
    occluded = related & (occluder != jnp.arange(num_slots))
    return OcclusionStatus(related, occluded, occluder.astype(jnp.int32))


def _connected(linked: Bool[Array, "slots slots"]) -> Bool[Array, "slots slots"]:
    """Reflexive transitive closure of a symmetric relation by repeated squaring.

    After ``k`` squarings of ``I + linked``, slots up to ``2^k`` links apart are connected;
    ``ceil(log2 S)`` squarings reach every path (at most ``S - 1`` links).
    """
    num_slots = linked.shape[0]
    reach = (linked | jnp.eye(num_slots, dtype=bool)).astype(jnp.float32)
    for _ in range(max(num_slots - 1, 1).bit_length()):
        reach = (reach @ reach > 0).astype(jnp.float32)
    return reach > 0


def update_signatures(
    models: AppearanceModel,
    observed: Float[Array, "slots 2 num_bins"],
    occluded: Bool[Array, " slots"],
    learning_rate: float | Float[Array, ""],
) -> AppearanceModel:
    """Each target's running signature, ``m <- m + max(1 / n, lambda) (p - m)``, per part.

    :func:`~jaxtrack.appearance.model.update_model` vmapped over the slots: an occluded
    target's model is frozen (Fusion Sec. 2.2), an all-zero observation (box outside the
    frame) changes nothing. Dead slots should be passed as occluded.

    Args:
        models: the slots' models (``histogram`` ``[S, 2, num_bins]``).
        observed: the slots' signature histograms in the current frame.
        occluded: which models are frozen.
        learning_rate: ``lambda`` (0.15 on CAVIAR, 0.35 on PETS 2009 in the paper).
    """
    return jax.vmap(update_model, in_axes=(0, 0, 0, None))(
        models, observed, occluded, learning_rate
    )


def start_signatures(
    models: AppearanceModel,
    observed: Float[Array, "slots 2 num_bins"],
    born: Bool[Array, " slots"],
) -> AppearanceModel:
    """The models with each newly born slot's replaced by a model of its first signature.

    :func:`~jaxtrack.appearance.model.init_model` (``m = p``, ``n = 1``, no distance
    statistics yet) where ``born``, the old model elsewhere.

    Args:
        models: the slots' models.
        observed: the slots' signature histograms in the current frame.
        born: which slots hold a target initiated in this frame.
    """
    fresh = init_model(observed)
    return jax.tree.map(
        lambda new, old: jnp.where(born.reshape(born.shape + (1,) * (new.ndim - 1)), new, old),
        fresh,
        models,
    )


def reidentify(
    new_signature: Float[Array, "2 num_bins"],
    new_box: Float[Array, " 4"],
    occluded: Bool[Array, " slots"],
    boxes: Float[Array, "slots 4"],
    stored: Float[Array, "slots 2 num_bins"],
    radius: float | Float[Array, ""],
    gate: float | Float[Array, ""],
) -> Int[Array, ""]:
    """The occluded target a newly initiated one is, or -1 (Fusion Sec. 3.1).

    Candidates are the occluded targets whose box centre lies within ``radius * h`` of the
    new box's centre (``h`` the new box's height) and whose stored signature is within
    ``gate`` of the new one, ``D(stored_i, new) <= gate`` (:func:`signature_distance`); the
    new target takes the identity of the closest candidate in signature (ties: lowest slot).
    ``jax.vmap`` over ``new_signature`` and ``new_box`` checks several new targets at once
    (two of them may pick the same slot; the caller settles that).

    Args:
        new_signature: the new target's ``[upper, lower]`` histograms.
        new_box: the new target's box.
        occluded: which slots hold occluded targets (:func:`occlusion_status`).
        boxes: the slots' boxes.
        stored: the slots' stored signatures.
        radius: the vicinity, in new-box heights.
        gate: largest signature distance of a match, in ``[0, 1]``.

    Returns:
        The matched slot, or -1.

    Raises:
        InputError: the tables disagree on the number of slots.
    """
    _check_slots(boxes, occluded, stored, stored)
    offset = _centre(boxes) - _centre(new_box)[None, :]
    near = jnp.sum(offset**2, axis=-1) <= (radius * new_box[3]) ** 2
    distance = signature_distance(stored, new_signature[None])
    candidate = occluded & near & (distance <= gate)
    best = jnp.argmin(jnp.where(candidate, distance, jnp.inf))
    return jnp.where(jnp.any(candidate), best, -1).astype(jnp.int32)


def _centre(boxes: Float[Array, "*shape 4"]) -> Float[Array, "*shape 2"]:
    return boxes[..., :2] + boxes[..., 2:] / 2


def _check_slots(boxes, mask, stored, observed) -> int:
    """The number of slots ``S``, after checking that every table has it."""
    num_slots = boxes.shape[0]
    if boxes.shape != (num_slots, 4):
        raise InputError(f"boxes must be [slots, 4], got {boxes.shape}")
    shapes = {"mask": mask.shape[:1], "stored": stored.shape[:1], "observed": observed.shape[:1]}
    wrong = {name: shape for name, shape in shapes.items() if shape != (num_slots,)}
    if wrong or mask.ndim != 1 or stored.shape != observed.shape:
        raise InputError(
            f"slot tables disagree: {num_slots} boxes, mask {mask.shape}, "
            f"stored {stored.shape}, observed {observed.shape}"
        )
    return num_slots
