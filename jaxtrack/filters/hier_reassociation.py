"""Appearance re-association of lost high-level trackers (Hierarchical Sec. 5.4).

A high-level tracker whose low-level tracker was removed (a long occlusion or group) is
*lost*; new-born high-level trackers are its candidate observations. For a lost tracker
``s`` and a candidate ``c``:

* the coincident features ``F_sc``: in both pools (the pools change while targets are
  grouped, but some long-run features are assumed to stay);
* per coincident feature ``i``, the Bhattacharyya distance ``d^i_sc = d(m^i_s, h^i_c)``
  between the lost tracker's mean histogram (learnt while the segmentation was reliable) and
  the candidate's histogram;
* the gate (Sec. 5.4, with eq. 5-6's statistics): ``d^i_sc <= mu^i_s + k max(sigma^i_s,
  sigma_min)``, on features whose model has at least ``min_updates`` updates;
* ``D_sc`` = the mean of ``d^i_sc`` over all the coincident features. The paper says only
  "the nearest one, according to the Bhattacharyya distance, within the gate". The mean
  over the features in the gate (or their minimum) cannot tell two targets apart that
  share one pooled feature (a red and a green person with the same blue channel: both
  pairs then score the shared feature's distance, about 0); over all coincident features
  the features that differ count against the wrong pair.

The pair is gated when at least one coincident feature is in the gate. :func:`reassociate`
then matches each lost tracker to its nearest gated candidate, one to one; a lost tracker
left unmatched tries again at the next frame (the caller calls it again).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from jaxtrack.appearance.similarity import bhattacharyya_distance
from jaxtrack.errors import InputError
from jaxtrack.filters.hier_appearance import (
    NUM_BINS,
    NUM_FEATURES,
    AppearanceParams,
    AppearanceTable,
)


def _pool_gate(table: AppearanceTable, params: AppearanceParams):
    """Per tracker and pooled feature: the feature index (-1 read as 0), the model's mean
    histogram ``[S, P, bins]``, the gate's threshold ``mu + k max(sigma, sigma_min)`` and
    whether the model has ``min_updates`` updates (``[S, P]``)."""
    safe = jnp.maximum(table.features, 0)
    take = jax.vmap(lambda leaf, index: leaf[index])
    model_hist = take(table.models.histogram, safe)
    spread = jnp.maximum(jnp.sqrt(jnp.maximum(table.models.distance_var, 0.0)), params.min_std)
    threshold = take(table.models.distance_mean + params.gate_sigmas * spread, safe)
    trained = take(table.models.count >= params.min_updates, safe)
    return safe, model_hist, threshold, trained


def own_track_gate(
    table: AppearanceTable,
    histograms: Float[Array, "num_slots 49 64"],
    params: AppearanceParams,
) -> tuple[Bool[Array, " num_slots"], Bool[Array, " num_slots"]]:
    """Whether each tracker's own model gates the histograms of its track's box (Sec. 5.4's
    gate, a tracker against its own track: every pooled feature is coincident).

    Args:
        table: the trackers' appearance.
        histograms: per tracker, the normalised histograms of its track's box on the frame.
        params: ``gate_sigmas``, ``min_std``, ``min_updates``.

    Returns:
        ``(gated, testable)``: at least one pooled, trained feature is within the gate; the
        tracker has at least one pooled, trained feature (without one nothing is tested).
    """
    safe, model_hist, threshold, trained = _pool_gate(table, params)
    take = jax.vmap(lambda leaf, index: leaf[index])
    trained = trained & (table.features >= 0)
    distance = bhattacharyya_distance(model_hist, take(histograms, safe))  # [S, P]
    return jnp.any(trained & (distance <= threshold), axis=-1), jnp.any(trained, axis=-1)


def association_distances(
    table: AppearanceTable,
    lost: Bool[Array, " num_slots"],
    candidate_hist: Float[Array, "num_candidates 49 64"],
    candidate_features: Int[Array, "num_candidates pool_size"],
    candidate: Bool[Array, " num_candidates"],
    params: AppearanceParams,
) -> tuple[Float[Array, "num_slots num_candidates"], Bool[Array, "num_slots num_candidates"]]:
    """Appearance distance ``D_sc`` and gate of every lost tracker and candidate (Sec. 5.4).

    Candidates are typically the new-born slots of the same table: ``table.models.histogram``
    (or this frame's :func:`~jaxtrack.filters.hier_appearance.box_histograms`) and
    ``table.features``, with ``candidate`` marking the new-born slots (disjoint from ``lost``:
    a slot in both would be its own candidate).

    Args:
        table: the trackers' appearance (lost trackers' models, frozen since they were lost).
        lost: the lost trackers.
        candidate_hist: each candidate's normalised histograms of the 49 features.
        candidate_features: each candidate's pooled feature indices (-1: none).
        candidate: the valid candidates (padding False).
        params: ``gate_sigmas`` ``k``, ``min_std`` ``sigma_min``, ``min_updates``.

    Returns:
        ``D_sc`` (``inf`` where not gated) and the gate (lost tracker, valid candidate, at
        least one coincident feature in the gate).

    Raises:
        InputError: the candidates' histograms, pools and mask do not agree in shape.
    """
    num_candidates = candidate.shape[0]
    if candidate_hist.shape != (num_candidates, NUM_FEATURES, NUM_BINS) or (
        candidate_features.shape != (num_candidates, table.features.shape[1])
    ):
        raise InputError(
            f"{num_candidates} candidates need histograms [C, {NUM_FEATURES}, {NUM_BINS}] and "
            f"pools [C, {table.features.shape[1]}], got {candidate_hist.shape} and "
            f"{candidate_features.shape}"
        )
    features = table.features
    safe, model_hist, threshold, trained = _pool_gate(table, params)

    in_candidate_pool = jnp.any(
        candidate_features[:, :, None] == jnp.arange(NUM_FEATURES), axis=1
    )  # [C, 49]
    coincident = in_candidate_pool[:, safe] & (features >= 0)  # [C, S, P]
    distance = bhattacharyya_distance(model_hist, candidate_hist[:, safe])  # [C, S, P]
    within = coincident & trained & (distance <= threshold)
    mean = jnp.sum(jnp.where(coincident, distance, 0.0), axis=-1) / jnp.maximum(
        jnp.sum(coincident, axis=-1), 1
    )
    gated = jnp.any(within, axis=-1).T & lost[:, None] & candidate[None, :]
    return jnp.where(gated, mean.T, jnp.inf), gated


def reassociate(
    distance: Float[Array, "num_slots num_candidates"],
    gated: Bool[Array, "num_slots num_candidates"],
) -> Int[Array, " num_slots"]:
    """Each lost tracker's nearest gated candidate, one to one (Sec. 5.4).

    Greedy in increasing distance: the gated pair of smallest ``D_sc`` is matched, its row and
    column removed, ``min(S, C)`` times (a fixed trip count).

    Returns:
        For each lost tracker, the matched candidate's index, or -1.
    """
    num_rows, num_cols = distance.shape

    def match_one(_, carry):
        cost, match = carry
        flat = jnp.argmin(cost)
        row, col = flat // num_cols, flat % num_cols
        found = jnp.isfinite(cost[row, col])
        match = match.at[row].set(jnp.where(found, col, match[row]))
        cost = jnp.where(found, cost.at[row, :].set(jnp.inf).at[:, col].set(jnp.inf), cost)
        return cost, match

    cost = jnp.where(gated, distance, jnp.inf)
    match = jnp.full(num_rows, -1, jnp.int32)
    _, match = jax.lax.fori_loop(0, min(num_rows, num_cols), match_one, (cost, match))
    return match
