"""Identity exchanges undone when two trackers separate (a departure from the Hierarchical paper).

Two people who cross or walk together give the low level overlapping (or single) boxes, and
its nearest-measurement association may hand each person's track to the other: an identity
*exchange*. The paper's high level re-associates a tracker only once its track is *lost*;
an exchange loses no track, so the paper keeps it. Here, when two trackers that collided
(:func:`~jaxtrack.filters.hier_events.collision_map`) since they were last apart are both
single again, their appearance models, frozen while they collided (the model is updated
only while single), are compared with the histograms of the two boxes on the frame:

* ``D(s, t)``: the mean Bhattacharyya distance between tracker ``s``'s mean histograms and
  the histograms of tracker ``t``'s box, over the 49 features whose model has at least
  ``min_updates`` updates;
* the pair is swapped when ``D(i, j) + D(j, i) + margin < D(i, i) + D(j, j)``: each model is
  nearer the other's box. The trackers then exchange their low-level tracks (and boxes), so
  each identity goes on with its own person; the appearance update that follows uses the
  exchanged boxes.

A pair is checked once, on the first frame both are single and measured with a trained
model; the episode is then closed (a pair without a trained model is closed unchecked).
Pairs are resolved greedily by decreasing gain, each tracker in at most one swap a frame.

Why all 49 features and not the tracker's pool: the pool is chosen to tell a target from the
background, not from another target. Measured offline before it was built (development
scenes: synthetic video seeds 0-2, 4-6 and 168-173, their detections, the full tracker's
output tracks; models the mean of each track's last 10 single frames before the episode, one
frame after it): of 207 collision episodes, the 5 exchanges had ``D(i, i) + D(j, j) - D(i,
j) - D(j, i)`` of 0.23 to 0.66, every kept pair below -0.6 (the 5 % quantile -0.82), so a
margin of 0.1 (:data:`DEFAULT_MARGIN`) is far from both.

As built (session 47; the same twelve development scenes, full tracker, tracker seed 0,
MOTA / IDF1 / IDSW, before -> after): detections 93.1 / 84.0 / 78 -> 93.1 / 85.5 / 90, blobs
57.1 / 54.5 / 605 -> 57.1 / 54.8 / 611; crossings whose identities were kept 18 -> 20 of 24
on the detections; the scripted occlusions and group walks 49 -> 49 of 87. IDSW rises: an
exchange undone once the pair is apart is a second switch for each person (CLEAR MOT counts
the exchange and the return), while IDF1, the share of each person's frames under one
identity, rises.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from jaxtrack.appearance.similarity import bhattacharyya_distance
from jaxtrack.filters.hier_appearance import AppearanceTable

#: Smallest gain (sum of two mean Bhattacharyya distances) for which a pair is swapped.
DEFAULT_MARGIN = 0.1


def margin_parameter(margin: float) -> Float[Array, ""]:
    """A configuration's margin as the check's parameter: ``margin``, or ``inf`` (never
    swap) when it is negative."""
    return jnp.float32(margin if margin >= 0 else jnp.inf)


def trained_features(table: AppearanceTable, min_updates: Float[Array, ""]) -> Bool[Array, "S 49"]:
    """Which feature models of each tracker have at least ``min_updates`` updates."""
    return table.models.count >= min_updates


def model_distances(
    table: AppearanceTable,
    histograms: Float[Array, "S 49 64"],
    trained: Bool[Array, "S 49"],
) -> Float[Array, "S S"]:
    """``D[s, t]``: the mean Bhattacharyya distance of tracker ``s``'s ``trained`` feature
    models (:func:`trained_features`) to ``histograms[t]`` (module docstring); 0 in the rows
    of trackers with no trained feature."""
    distance = bhattacharyya_distance(table.models.histogram[:, None], histograms[None])
    weight = trained[:, None, :].astype(distance.dtype)  # distance: [S, S, 49]
    return jnp.sum(distance * weight, axis=-1) / jnp.maximum(jnp.sum(weight, axis=-1), 1.0)


def exchanges(
    distances: Float[Array, "S S"],
    ready: Bool[Array, "S S"],
    margin: Float[Array, ""],
) -> Int[Array, " S"]:
    """Each tracker's swap partner (-1: none): the ``ready`` pairs (symmetric) whose
    ``D(i, j) + D(j, i) + margin < D(i, i) + D(j, j)``, greedily by decreasing gain, each
    tracker in at most one pair."""
    size = distances.shape[0]
    own = jnp.diagonal(distances)
    gain = own[:, None] + own[None, :] - distances - distances.T - margin
    upper = jnp.triu(jnp.ones((size, size), bool), 1)
    gain = jnp.where(ready & upper & (gain > 0), gain, -jnp.inf)

    def pick(_, carry):
        gain, partner = carry
        flat = jnp.argmax(gain)
        i, j = flat // size, flat % size
        found = jnp.isfinite(gain[i, j])
        partner = jnp.where(found, partner.at[i].set(j).at[j].set(i), partner)
        cleared = gain.at[jnp.array([i, j])].set(-jnp.inf).at[:, jnp.array([i, j])].set(-jnp.inf)
        return jnp.where(found, cleared, gain), partner

    partner = jnp.full((size,), -1, jnp.int32)
    _, partner = jax.lax.fori_loop(0, size // 2, pick, (gain, partner))
    return partner
