"""The track table shared by every tracker: slots, identities, missed frames, overflow.

A tracker keeps its tracks in a fixed table of ``max_tracks`` slots (``lax.scan`` needs fixed
shapes). Per frame it links some tracks to new evidence (estimates or detections), and then,
with the functions here,

1. :func:`count_missed`: a linked track's missed-frame counter restarts at 0, an unlinked
   one's grows by 1; a track ends after more than ``max_missed_frames`` missed frames;
2. :func:`start_tracks`: the unlinked evidence that should start tracks takes the free slots
   (those not held by a track still alive) in order, each with a new identity from the
   table's counter (identities start at 1 and never repeat); evidence that finds no free
   slot is dropped and flagged (``overflow``, an error for the caller to report);
3. :func:`commit_tracks`: the table after the frame.

The PHD labelling (:mod:`~jaxtrack.association.labelling`) and the Kalman tracker
(:mod:`~jaxtrack.filters.kalman`) carry their own per-track values (boxes, velocities, Kalman
means) beside a :class:`TrackTable`.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int


class TrackTable(NamedTuple):
    """The slots of a tracker's tracks.

    Attributes:
        ids: identity of each track (-1 for free slots).
        active: True where a slot holds a live track.
        confirmed: True for confirmed tracks.
        missed: consecutive frames since each track was last linked.
        next_id: identity the next new track gets.
    """

    ids: Int[Array, " max_tracks"]
    active: Bool[Array, " max_tracks"]
    confirmed: Bool[Array, " max_tracks"]
    missed: Int[Array, " max_tracks"]
    next_id: Int[Array, ""]


class NewTracks(NamedTuple):
    """New tracks of one frame (:func:`start_tracks`).

    Attributes:
        source: per slot, the index of the evidence that starts a track there
            (``num_items`` where none does).
        born: True for the slots that start a track.
        ids: identities of the new tracks (meaningful where ``born``).
        next_id: the identity counter after the new tracks.
        overflow: True when some evidence found no free slot.
    """

    source: Int[Array, " max_tracks"]
    born: Bool[Array, " max_tracks"]
    ids: Int[Array, " max_tracks"]
    next_id: Int[Array, ""]
    overflow: Bool[Array, ""]


def init_track_table(max_tracks: int) -> TrackTable:
    """An empty table of ``max_tracks`` slots; the first identity is 1."""
    return TrackTable(
        ids=jnp.full((max_tracks,), -1, jnp.int32),
        active=jnp.zeros((max_tracks,), bool),
        confirmed=jnp.zeros((max_tracks,), bool),
        missed=jnp.zeros((max_tracks,), jnp.int32),
        next_id=jnp.asarray(1, jnp.int32),
    )


def count_missed(
    table: TrackTable, linked: Bool[Array, " max_tracks"], max_missed_frames: Float[Array, ""]
) -> tuple[Int[Array, " max_tracks"], Bool[Array, " max_tracks"]]:
    """Missed-frame counters after a frame, and the tracks that stay alive.

    Args:
        table: the table before the frame.
        linked: True for the tracks linked on this frame.
        max_missed_frames: a track ends after more consecutive missed frames than this.

    Returns:
        The counters (0 where linked, one more elsewhere) and ``active & missed <= max``.
    """
    missed = jnp.where(linked, 0, table.missed + 1)
    return missed, table.active & (missed <= max_missed_frames)


def start_tracks(
    alive: Bool[Array, " max_tracks"], starts: Bool[Array, " num_items"], next_id: Int[Array, ""]
) -> NewTracks:
    """Puts each item that starts a track in a free slot, in item order.

    Free slots (``~alive``) are taken in slot order by the starting items in item order; the
    ``r``-th starting item (from 0) gets identity ``next_id + r``. Items beyond the free
    slots are dropped: they get no identity and set ``overflow``.

    Args:
        alive: slots held by live tracks after this frame's ending.
        starts: True for the items (estimates, detections) that start a track.
        next_id: the table's identity counter.

    Returns:
        The :class:`NewTracks`.
    """
    num_tracks, num_items = alive.shape[0], starts.shape[0]
    rank = jnp.cumsum(starts, dtype=jnp.int32) - 1
    free_slots = jnp.argsort(alive, stable=True)
    stored = starts & (rank < jnp.sum(~alive))
    slot = jnp.where(stored, free_slots[jnp.clip(rank, 0, num_tracks - 1)], num_tracks)
    source = (
        jnp.full(num_tracks, num_items, jnp.int32)
        .at[slot]
        .set(jnp.arange(num_items, dtype=jnp.int32), mode="drop")
    )
    born = source < num_items
    return NewTracks(
        source=source,
        born=born,
        ids=next_id + rank[jnp.minimum(source, num_items - 1)],
        next_id=next_id + jnp.sum(stored, dtype=jnp.int32),
        overflow=jnp.any(starts & ~stored),
    )


def commit_tracks(
    new: NewTracks,
    table: TrackTable,
    alive: Bool[Array, " max_tracks"],
    missed: Int[Array, " max_tracks"],
    confirmed: Bool[Array, " max_tracks"],
) -> TrackTable:
    """The table after a frame: live tracks kept, new tracks added, ended ones freed.

    Args:
        new: the frame's new tracks.
        table: the table before the frame.
        alive: tracks still alive (:func:`count_missed` and any tracker-specific ending).
        missed: missed-frame counters (:func:`count_missed`).
        confirmed: confirmation of every slot after the frame (the tracker's rule).

    Returns:
        The new :class:`TrackTable` (free slots have identity -1 and counter 0).
    """
    return TrackTable(
        ids=jnp.where(new.born, new.ids, jnp.where(alive, table.ids, -1)).astype(jnp.int32),
        active=alive | new.born,
        confirmed=confirmed,
        missed=jnp.where(new.born | ~alive, 0, missed),
        next_id=new.next_id,
    )
