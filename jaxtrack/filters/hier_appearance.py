"""High-level appearance of the Hierarchical tracker (Hierarchical Sec. 5.2-5.3; SPEC section 4).

Each high-level tracker slot keeps, for Collins' 49 linear-RGB features (64 bins each):

* the feature ranking (Sec. 5.2): the variance ratio (eq. 3) of the log-likelihood ratio
  (eq. 2) of this frame's target histogram ``p^i`` (eq. 1) against the background histogram
  ``q^i`` of the same box on the background model's mean image;
* the pool (Sec. 5.3): the ``M`` best features of the frame and the ``N`` best long-run ones
  (:func:`~jaxtrack.appearance.variance_ratio.select_features`);
* the mean histograms ``m^i_t`` (eq. 4) and the mean and variance of the Bhattacharyya
  distance ``d^i_t = d(m^i_(t-1), p^i_t)`` (eq. 5-6)
  (:func:`~jaxtrack.appearance.model.update_model`).

Departure from the paper: the paper keeps mean histograms for the pooled features only
("for each M feature"); here all 49 are updated at every update, so a feature entering the
pool brings the mean of the whole track (``n^i`` counts every update of the slot, not the
updates while pooled). Association (:mod:`jaxtrack.filters.hier_reassociation`) uses the
pooled features only. It costs 49 histograms per slot instead of ``M + N`` and keeps one
vmapped update with fixed shapes.

Every function is pure JAX over a fixed number of slots ``S`` (jit-able, vmap-able over
parameter sets); the pool sizes ``M`` and ``N`` are static keyword arguments.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int, UInt8

from jaxtrack.appearance.colour import LINEAR_COMBINATION_WEIGHTS
from jaxtrack.appearance.features import linear_combination_histograms
from jaxtrack.appearance.model import AppearanceModel, init_model, update_model
from jaxtrack.appearance.similarity import bhattacharyya_distance
from jaxtrack.appearance.variance_ratio import (
    FeaturePool,
    init_pool,
    select_features,
    variance_ratio,
)
from jaxtrack.control import largest_member
from jaxtrack.errors import InputError

#: Collins' linear RGB features (49).
NUM_FEATURES = len(LINEAR_COMBINATION_WEIGHTS)

#: Histogram bins per feature (Sec. 5.2: 64 bins, the histograms' default quantisation step 4).
NUM_BINS = 64

#: ``(ph, pw)`` samples per box. ``benchmarks/hier_appearance.py`` on PETS09-S2L1: the 49
#: histograms of ground-truth people (frames 1, 201, 401) lie at a median mean Bhattacharyya
#: distance 0.12 from full-resolution ones (16 x 8: 0.19; 32 x 16: 0.08), against 0.47 between
#: two people; 10 boxes on a 768 x 576 frame and on the background image take 1.4 ms (16 x 8:
#: 0.6 ms; 32 x 16: 2.5 ms; 32 boxes: 4.6 ms) on 2 shared CPU cores, inside the 3 ms budget of
#: a 25 frames/s tracker.
PATCH_SHAPE = (24, 12)

#: Smallest bucket of :func:`live_box_histograms`; the buckets double from it up to the
#: number of slots.
SMALLEST_BUCKET = 8


class AppearanceParams(NamedTuple):
    """Tunable parameters of the high-level appearance (a PyTree of float32 scalars).

    Attributes:
        delta: floor ``epsilon`` of the histogram values in eq. 2. The paper takes the
            smallest histogram value; :func:`default_params` sets the smallest nonzero value
            a box histogram can hold, one sample's weight ``1 / (ph pw)``.
        gate_sigmas: ``k`` of the gate ``d <= mu + k max(sigma, sigma_min)`` (Sec. 5.4).
        min_std: ``sigma_min``, floor of the gate's standard deviation (``sigma`` is 0 while
            the statistics rest on one distance).
        min_updates: updates a feature's model needs before it is gated on.
        rate_floor: ``beta`` of :func:`~jaxtrack.appearance.model.update_model`; 0 is the
            paper's cumulative mean (eq. 4).
    """

    delta: Float[Array, ""]
    gate_sigmas: Float[Array, ""]
    min_std: Float[Array, ""]
    min_updates: Float[Array, ""]
    rate_floor: Float[Array, ""]


def default_params(patch_shape: tuple[int, int] = PATCH_SHAPE) -> AppearanceParams:
    """Defaults: ``epsilon = 1 / (ph pw)``, ``k = 3``, ``sigma_min = 0.05``, 3 updates, beta 0.

    Not tuned yet (the tracker tunes on synthetic video seeds 0-2 only).
    """
    samples = patch_shape[0] * patch_shape[1]
    return AppearanceParams(*(jnp.float32(v) for v in (1.0 / samples, 3.0, 0.05, 3.0, 0.0)))


class AppearanceTable(NamedTuple):
    """The appearance of ``S`` high-level tracker slots.

    Attributes:
        models: mean histograms and distance statistics of all 49 features, leaves
            ``[S, 49, ...]`` (``count`` 0: no histogram yet).
        pool: how often each feature was among a slot's ``M`` best, ``[S, 49]``.
        features: the pooled feature indices, ``[S, M + N]``: the ``M`` current best by
            decreasing variance ratio, then the ``N`` long-run ones (-1 before the first
            update). Hierarchical Fig. 4b plots them over time.
        last_distance: ``d^i_t = d(m^i_(t-1), p^i_t)`` of each feature at the slot's last
            update with a previous model, ``[S, 49]`` (Fig. 4c); 0 before.
    """

    models: AppearanceModel
    pool: FeaturePool
    features: Int[Array, "num_slots pool_size"]
    last_distance: Float[Array, "num_slots 49"]


def box_histograms(
    image: UInt8[Array, "height width 3"],
    boxes: Float[Array, "num_boxes 4"],
    patch_shape: tuple[int, int] = PATCH_SHAPE,
) -> Float[Array, "num_boxes 49 64"]:
    """The 49 normalised feature histograms ``p^i`` of each box (Hierarchical eq. 1).

    Called on the frame it gives the target histograms; on the background model's mean image
    (uint8) the background histograms ``q^i`` of the same boxes (eq. 2). A box wholly outside
    the image has all-zero histograms (no observation).

    Args:
        image: RGB image, uint8.
        boxes: ``(x, y, w, h)`` of each box, pixels.
        patch_shape: ``(ph, pw)`` samples per box, static.
    """
    histograms = functools.partial(linear_combination_histograms, patch_shape=patch_shape)
    return jax.vmap(histograms, in_axes=(None, 0))(image, boxes)


def bucket_sizes(num_slots: int) -> tuple[int, ...]:
    """The static sizes :func:`live_box_histograms` compacts ``num_slots`` slots into:
    :data:`SMALLEST_BUCKET`, doubling, below ``num_slots``, then ``num_slots`` itself."""
    sizes = []
    size = SMALLEST_BUCKET
    while size < num_slots:
        sizes.append(size)
        size *= 2
    return (*sizes, num_slots)


def smallest_bucket(count: Int[Array, ""], sizes: tuple[int, ...]) -> Int[Array, ""]:
    """The index of the smallest of the increasing ``sizes`` that holds ``count`` items (the
    last one when none does)."""
    return jnp.sum(count > jnp.asarray(sizes[:-1], jnp.int32))


def live_box_histograms(
    image: UInt8[Array, "height width 3"],
    boxes: Float[Array, "num_boxes 4"],
    alive: Bool[Array, " num_boxes"],
    patch_shape: tuple[int, int] = PATCH_SHAPE,
) -> Float[Array, "num_boxes 49 64"]:
    """:func:`box_histograms` of the ``alive`` boxes; the other boxes' histograms are zero.

    The live boxes are gathered (in slot order) into the smallest of :func:`bucket_sizes`
    that holds them all, their histograms computed there and scattered back to their slots:
    the cost follows the number of live boxes, not of slots (the Hierarchical tracker's
    low-level slots are mostly free). Padding entries of a bucket point past the last slot:
    their histograms are computed on a copy of the last box and dropped by the scatter.

    The bucket is chosen by ``lax.switch`` on the live count; under ``vmap`` on the largest
    member's count (:func:`~jaxtrack.control.largest_member`), so that the switch stays a
    conditional running one bucket for the whole batch instead of every bucket for every
    member.

    Args:
        image: RGB image, uint8.
        boxes: ``(x, y, w, h)`` of each box, pixels.
        alive: the boxes whose histograms are wanted.
        patch_shape: ``(ph, pw)`` samples per box, static.

    Returns:
        ``[num_boxes, 49, 64]``: equal to :func:`box_histograms` on the alive boxes, zero
        on the others (as for a box wholly outside the image).
    """
    num_boxes = boxes.shape[0]
    if alive.shape != (num_boxes,):
        raise InputError(f"alive must be [{num_boxes}] like the boxes, got {alive.shape}")
    sizes = bucket_sizes(num_boxes)

    def compacted(size: int, image, boxes, alive):
        index = jnp.nonzero(alive, size=size, fill_value=num_boxes)[0]
        picked = box_histograms(image, jnp.take(boxes, index, axis=0, mode="clip"), patch_shape)
        empty = jnp.zeros((num_boxes, NUM_FEATURES, NUM_BINS), picked.dtype)
        return empty.at[index].set(picked, mode="drop")

    bucket = smallest_bucket(largest_member(jnp.sum(alive, dtype=jnp.int32)), sizes)
    branches = [functools.partial(compacted, size) for size in sizes]
    return jax.lax.switch(bucket, branches, image, boxes, alive)


def init_table(num_slots: int, num_current: int = 3, num_longrun: int = 3) -> AppearanceTable:
    """``num_slots`` empty slots with pools of ``M = num_current`` + ``N = num_longrun``."""
    _check_pool(num_current, num_longrun)
    empty = init_model(jnp.zeros((num_slots, NUM_FEATURES, NUM_BINS), jnp.float32))
    pool = jax.vmap(lambda _: init_pool(NUM_FEATURES))(jnp.arange(num_slots))
    features = jnp.full((num_slots, num_current + num_longrun), -1, jnp.int32)
    return AppearanceTable(empty, pool, features, jnp.zeros((num_slots, NUM_FEATURES)))


def reset_slots(table: AppearanceTable, slots: Bool[Array, " num_slots"]) -> AppearanceTable:
    """Empties ``slots`` for new trackers: their next update makes its histograms the model.

    (An empty model has ``n = 0``, so eq. 4's first step ``m_1 = p_1``.)
    """
    empty = init_table(table.features.shape[0], table.features.shape[1], 0)
    return jax.tree.map(lambda old, new: _where_slots(slots, new, old), table, empty)


def update_appearance(
    table: AppearanceTable,
    target_hist: Float[Array, "num_slots 49 64"],
    background_hist: Float[Array, "num_slots 49 64"],
    update: Bool[Array, " num_slots"],
    params: AppearanceParams,
    *,
    num_current: int = 3,
) -> AppearanceTable:
    """One appearance update of the slots in ``update`` (Hierarchical eq. 2-6).

    Per updated slot: variance ratio of every feature (eq. 2-3, floor ``epsilon``), the pool
    of ``M`` current + ``N`` long-run features, then every feature's mean histogram (eq. 4)
    and distance statistics (eq. 5-6). Slots not in ``update`` (grouped, occluded, dead) or
    whose box has no sample in the image are returned unchanged.

    Args:
        table: the appearance so far.
        target_hist: this frame's histograms of each slot's box (:func:`box_histograms`).
        background_hist: the same boxes' histograms on the background image.
        update: the slots to update.
        params: the tunable parameters.
        num_current: ``M``, static; ``N`` is the rest of the table's pool.

    Returns:
        The updated table.

    Raises:
        InputError: the histograms are not ``[S, 49, 64]`` for the table's ``S`` slots, or
            ``M`` does not fit the table's pool.
    """
    for name, hist in (("target", target_hist), ("background", background_hist)):
        if hist.shape != table.models.histogram.shape:
            raise InputError(
                f"{name} histograms must be {table.models.histogram.shape}, got {hist.shape}"
            )
    num_longrun = table.features.shape[1] - num_current
    _check_pool(num_current, num_longrun)
    observed = update & (jnp.sum(target_hist[:, 0], axis=-1) > 0)
    ratios = variance_ratio(target_hist, background_hist, params.delta)
    pool, features = jax.vmap(select_features, in_axes=(0, 0, None, None))(
        table.pool, ratios, num_current, num_longrun
    )
    models = update_model(table.models, target_hist, ~observed[:, None], params.rate_floor)
    distance = bhattacharyya_distance(table.models.histogram, target_hist)
    has_model = observed[:, None] & (table.models.count > 0)
    updated = AppearanceTable(
        models, pool, features, jnp.where(has_model, distance, table.last_distance)
    )
    return jax.tree.map(lambda new, old: _where_slots(observed, new, old), updated, table)


def _where_slots(slots, new, old):
    """``new`` in the chosen slots (leading axis), ``old`` elsewhere."""
    return jnp.where(slots.reshape(slots.shape + (1,) * (new.ndim - 1)), new, old)


def _check_pool(num_current: int, num_longrun: int) -> None:
    if num_current < 1 or num_longrun < 0 or num_current + num_longrun > NUM_FEATURES:
        raise InputError(
            f"a feature pool needs M >= 1 current and N >= 0 long-run features, M + N <= "
            f"{NUM_FEATURES}; got M = {num_current}, N = {num_longrun}"
        )
