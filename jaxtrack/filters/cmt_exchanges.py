"""Split exchanges: the observation model decides who is who when two components separate (not
in the CMT paper).

Two people who cross give overlapping boxes and, while one hides the other, often a single
blob. The two components then sit on the same blob and their particle clouds can change
places; when the people separate, each component follows the blob its motion points to, and
the box likelihood (:func:`~jaxtrack.filters.cmt.blob_owners`) outweighs the appearance term.
Measured in session 61 on twelve development crossings (synthetic video seeds 222-227,
``top`` and ``bottom`` families), on the first frame after the split where each person had a
detection of their own: the motion preferred the wrong pairing on 5 of the 12, by 0.9-25 nats
of box log-likelihood, and COM's appearance term (times ``appearance_weight`` 3) preferred
the right one on 4 of those 5, by 0.2-1.1 nats. Eq. 11's mixture bounds that term: a person
who matches a model on features of total weight ``w`` keeps at least ``w`` of its likelihood
(gap at most ``-log w``), and most colour buckets are empty for both people. CMT's argument
(Sec. V, Fig. 9) is that the observation model tells such targets apart; with the blob's box
in the likelihood it never gets the chance.

Here the components that collided keep their clouds (each goes on with the blob it holds) but
the *identities* are settled by the observation model on the first frame the two are apart:

* an *episode* opens for a pair of living components whose local decisions overlap by IoU at
  least :data:`EXCHANGE_IOU` (:func:`next_episodes`);
* it is *checked* on the first later frame where both components are confirmed and own a blob
  (:func:`~jaxtrack.filters.cmt.blob_owners`), the two blobs distinct and apart (IoU below
  :data:`EXCHANGE_IOU`): with ``L_s(b)`` the log-likelihood of blob ``b``'s features under
  component ``s``'s appearance model and weights (eq. 11: COM's ``rho`` for ``cmt``, uniform
  for ``cpd``), the pair's gain is ``L_i(b_j) + L_j(b_i) - L_i(b_i) - L_j(b_j)``: each model
  explains the other's blob better. The pair *exchanges* when the gain exceeds ``margin``
  (nats): the components swap their identities and appearance models (models and decayed
  histograms), so each identity goes on with the person its model was learned on. Pairs are
  resolved greedily by decreasing gain, each component in at most one exchange a frame;
* the episode then closes, whatever the outcome; a pair checked while its decisions still
  overlap opens no new episode until they have been apart (:func:`next_episodes`);
* while a component's decision overlaps another's (:func:`overlaps`), its appearance model
  is frozen, as under CMT's merge condition (where the tracker otherwise freezes it only when
  most particle weight drew *merge*): the box then holds parts of both people. On the drawn
  crossing of two differently dressed people (``tests/filters/test_cmt_exchanges.py``,
  margin 0.1) the pair kept its identities in 10 of 10 seeds with the freeze and 9 of 10
  without it: a small effect there, measured after the held-out decision, which was made with
  the freeze.

An exchange on the first frame the hidden person is picked up again costs no identity switch;
a later one (CLEAR MOT counts the wrong identity's start and the return) costs two, which is
why the check happens once, on the first frame the blobs allow it.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from jaxtrack.boxes import iou_matrix
from jaxtrack.filters.hier_exchanges import exchanges
from jaxtrack.types import Detections

#: IoU of two components' local decisions that opens an episode, and below which their two
#: blobs count as apart.
EXCHANGE_IOU = 0.4
#: Episode states of a pair (:func:`next_episodes`).
APART, OPEN, CHECKED = 0, 1, 2


def slot_blobs(owner: Int[Array, " max_detections"], num_slots: int) -> Int[Array, " num_slots"]:
    """The blob each slot owns (-1: none), from :func:`~jaxtrack.filters.cmt.blob_owners`'
    owner of each blob (-1: free)."""
    blobs = jnp.arange(owner.shape[0], dtype=jnp.int32)
    target = jnp.where(owner >= 0, owner, num_slots)  # free blobs scatter to a dropped row
    return jnp.full((num_slots + 1,), -1, jnp.int32).at[target].set(blobs)[:num_slots]


def paired_likelihoods(
    blob_log_appearance: Float[Array, "max_components max_detections"],
    held: Int[Array, " max_components"],
) -> Float[Array, "max_components max_components"]:
    """``[i, j] = L_i(b_j)``: the blob component ``j`` holds (``held[j]``; any index where it
    holds none, masked by :func:`split_exchanges`) under component ``i``'s model."""
    return blob_log_appearance[:, jnp.maximum(held, 0)]


def split_exchanges(
    episodes: Int[Array, "max_components max_components"],
    owner: Int[Array, " max_detections"],
    blobs: Detections,
    blob_log_appearance: Float[Array, "max_components max_detections"],
    eligible: Bool[Array, " max_components"],
    margin: Float[Array, ""],
) -> tuple[Int[Array, " max_components"], Bool[Array, "max_components max_components"]]:
    """This frame's exchanges (module docstring).

    Args:
        episodes: the pairs' episode states (:data:`OPEN` pairs are checked).
        owner: the component each blob is evidence for (-1: none).
        blobs: the frame's blobs.
        blob_log_appearance: ``L_s(b)``, each blob's appearance log-likelihood under each
            component's model (unscaled by the appearance exponent).
        eligible: components that may exchange (alive and confirmed).
        margin: the gain (nats) an exchange needs.

    Returns:
        ``partner``: the slot whose identity each slot takes (itself when it does not
        exchange), and ``checked``: the pairs checked this frame (symmetric).
    """
    num_slots = episodes.shape[0]
    held = slot_blobs(owner, num_slots)
    holds = eligible & (held >= 0)
    index = jnp.maximum(held, 0)
    own_boxes = blobs.boxes[index]
    apart = iou_matrix(own_boxes, own_boxes, jnp) < EXCHANGE_IOU
    distinct = held[:, None] != held[None, :]
    checked = (episodes == OPEN) & holds[:, None] & holds[None, :] & distinct & apart
    # The pair's gain L_i(b_j) + L_j(b_i) - L_i(b_i) - L_j(b_j) is the Hierarchical tracker's
    # D(i, i) + D(j, j) - D(i, j) - D(j, i) with D = -L: its greedy resolution applies.
    cross = jax.lax.stop_gradient(paired_likelihoods(blob_log_appearance, held))
    partner = exchanges(-cross, checked, margin)
    partner = jnp.where(partner >= 0, partner, jnp.arange(num_slots, dtype=jnp.int32))
    return partner, checked


def exchange_rows(partner: Int[Array, " max_components"], tree: Any) -> Any:
    """Every leaf of ``tree`` (leading axis: slots) with row ``s`` taken from ``partner[s]``."""
    return jax.tree.map(lambda leaf: leaf[partner], tree)


def living_pairs(
    live: Bool[Array, " max_components"],
) -> Bool[Array, "max_components max_components"]:
    """Pairs of distinct living components."""
    return live[:, None] & live[None, :] & ~jnp.eye(live.shape[0], dtype=bool)


def overlaps(
    boxes: Float[Array, "max_components 4"], live: Bool[Array, " max_components"]
) -> Bool[Array, "max_components max_components"]:
    """Pairs of distinct living components whose boxes (``x, y, w, h``) overlap by IoU at
    least :data:`EXCHANGE_IOU`."""
    return living_pairs(live) & (iou_matrix(boxes, boxes, jnp) >= EXCHANGE_IOU)


def next_episodes(
    episodes: Int[Array, "max_components max_components"],
    checked: Bool[Array, "max_components max_components"],
    close: Bool[Array, "max_components max_components"],
    live: Bool[Array, " max_components"],
) -> Int[Array, "max_components max_components"]:
    """The episode states after the frame (module docstring).

    A ``close`` pair (:func:`overlaps` of the living components' decisions) is :data:`OPEN`,
    unless it was checked this frame or before
    while still overlapping (:data:`CHECKED`); an open pair stays open until checked; a
    checked pair apart again is :data:`APART`. Pairs with a dead or new component, and a
    component with itself, are :data:`APART`.
    """
    was_checked = checked | (episodes == CHECKED)
    state = jnp.where(
        close,
        jnp.where(was_checked, CHECKED, OPEN),
        jnp.where((episodes == OPEN) & ~checked, OPEN, APART),
    )
    return jnp.where(living_pairs(live), state, APART).astype(jnp.int8)
