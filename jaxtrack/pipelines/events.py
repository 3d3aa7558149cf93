"""Event states of a tracking run, as written beside its results (``RES.events.csv``).

A tracker whose registry entry ``writes_events`` (the Hierarchical tracker) has, per frame, the
event state of each of its high-level slots and the slot's identity
(:class:`~jaxtrack.filters.hierarchical.HierarchicalInfo` ``events``, ``event_ids``).
:func:`event_outputs` keeps them beside the tracks (``frame_output`` of
:func:`~jaxtrack.filters.base.run`); :func:`event_rows` turns them into one row per result
row (identity and frame of the written results: the events of a frame the offline output
interpolated are those of the tracker while it was lost), and labels the end of each track
that leaves before the span's end as exiting
(:func:`~jaxtrack.filters.hier_events.label_exits`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from jaxtyping import Array

from jaxtrack.filters.hier_events import (
    EVENT_NAMES,
    MIN_GROUP_SECONDS,
    drop_short_groups,
    label_exits,
    moving_ends,
    rows_at_zones,
    unlabel_entries,
)
from jaxtrack.metrics.events import EventRows
from jaxtrack.types import MotTable, Tracks


class EventOutputs(NamedTuple):
    """Per frame: the tracks and candidates (for the result rows), the slots' events and
    identities, the identities merged into them by re-associations, whether a table was
    full (``overflow``; None for a tracker without the flag) and the slots whose identity's
    gap before the frame is not to be filled offline (``unfilled``, the Hierarchical
    tracker's; None for a tracker without it)."""

    tracks: Tracks
    candidates: Tracks
    events: Array
    event_ids: Array
    merged: Array
    overflow: Any = None
    unfilled: Any = None


def event_outputs(state: Any, info: Any, index: Any) -> EventOutputs:
    """The per-frame output of a run that writes events (``frame_output`` of
    :func:`~jaxtrack.filters.base.run`)."""
    del state, index
    return EventOutputs(
        info.tracks,
        info.candidates,
        info.events,
        info.event_ids,
        info.merged,
        getattr(info, "overflow", None),
        getattr(info, "unfilled", None),
    )


def identity_merges(merged: np.ndarray, event_ids: np.ndarray) -> dict[int, int]:
    """Which identity each merged identity became: ``{merged: tracker}``, chains resolved.

    Args:
        merged: per frame and slot, the identity merged into the slot's tracker on the
            frame (-1: none), ``[num_frames, S]``.
        event_ids: per frame and slot, the tracker's identity, ``[num_frames, S]``.
    """
    direct = _direct_merges(merged, event_ids)
    return {source: _resolve(source, direct)[0] for source in direct}


def _direct_merges(merged, event_ids) -> dict[int, int]:
    """``{merged: tracker}`` of each re-association (one merge each)."""
    merged, event_ids = np.asarray(merged), np.asarray(event_ids)
    pairs = merged >= 0
    return dict(zip(merged[pairs].tolist(), event_ids[pairs].tolist(), strict=True))


def _resolve(identity: int, direct: dict[int, int]) -> tuple[int, int]:
    """The final tracker of ``identity`` through the chain of ``direct`` merges, and the
    number of merges on the way (0: not merged)."""
    depth, seen = 0, set()
    while identity in direct and identity not in seen:
        seen.add(identity)
        identity, depth = direct[identity], depth + 1
    return identity, depth


def merge_identities(outputs: Any) -> Any:
    """The per-frame outputs (with ``tracks``, ``candidates``, ``event_ids`` and
    ``merged``, NumPy or JAX leaves) with every merged identity replaced by its tracker's
    (:func:`identity_merges`): the rows of a target before a lost tracker took it back are
    the tracker's."""
    direct = _direct_merges(outputs.merged, outputs.event_ids)
    if not direct:
        return outputs
    keys = np.array(sorted(direct), np.int64)
    values, depths = np.array([_resolve(key, direct) for key in keys.tolist()], np.int64).T

    def relabel(tracks: Tracks) -> Tracks:
        ids = np.array(tracks.ids, copy=True)
        found = np.isin(ids, keys)
        index = np.searchsorted(keys, ids[found])
        depth = np.zeros(ids.shape, np.int64)
        depth[found] = depths[index]
        ids[found] = values[index]
        # Rows that become one identity on one frame (tracks that overlapped in time): the
        # row nearest the tracker in the merge chain stays (its own row first; ties: the
        # first slot), the others are dropped.
        same = (ids[..., :, None] == ids[..., None, :]) & (ids[..., None, :] >= 0)
        slots = np.arange(ids.shape[-1])
        before = (depth[..., None, :] < depth[..., :, None]) | (
            (depth[..., None, :] == depth[..., :, None]) & (slots[None, :] < slots[:, None])
        )
        clash = np.any(same & before, axis=-1)
        return tracks._replace(ids=np.where(clash, -1, ids), mask=np.asarray(tracks.mask) & ~clash)

    event_ids = np.array(outputs.event_ids, copy=True)
    changed = np.isin(event_ids, keys)
    event_ids[changed] = values[np.searchsorted(keys, event_ids[changed])]
    return outputs._replace(
        tracks=relabel(outputs.tracks),
        candidates=relabel(outputs.candidates),
        event_ids=event_ids,
    )


def event_rows(
    outputs: EventOutputs,
    rows: MotTable,
    first_frame: int,
    frame_rate: float | None = None,
    image_size: tuple[float, float] | None = None,
) -> EventRows:
    """The event state of every result row.

    Args:
        outputs: the run's :class:`EventOutputs`, stacked over frames.
        rows: the written results (:func:`~jaxtrack.pipelines.tracking.output_rows`).
        first_frame: MOT frame number of the run's first frame.
        frame_rate: frames per second of the sequence (None: 25), for the shortest group
            episode reported (:data:`~jaxtrack.filters.hier_events.MIN_GROUP_SECONDS`).
        image_size: ``(width, height)`` of the frames, for the entry/exit zones learned from
            the rows (:func:`~jaxtrack.filters.hier_events.rows_at_zones`); None: no zones
            (every track end is an exit, every start an entry).

    Returns:
        One row per result row, sorted by frame then identity; group episodes shorter than
        half a second dropped (:func:`~jaxtrack.filters.hier_events.drop_short_groups`);
        with ``image_size``, entries of tracks that start away from every zone dropped
        (:func:`~jaxtrack.filters.hier_events.unlabel_entries`); exits labelled (with
        ``image_size``, of tracks that end in a zone).
    """
    events = np.asarray(outputs.events)
    ids = np.asarray(outputs.event_ids)
    num_frames = events.shape[0]
    state = {}
    for t, s in zip(*np.nonzero(ids >= 0), strict=True):
        state[(first_frame + int(t), int(ids[t, s]))] = int(events[t, s])
    order = np.lexsort((rows.ids, rows.frames))
    frames, identities = rows.frames[order], rows.ids[order]
    codes = np.array(
        [state.get((int(f), int(i)), -1) for f, i in zip(frames, identities, strict=True)],
        np.int64,
    )
    last_frame = first_frame + num_frames - 1
    rate = frame_rate or 25.0
    min_frames = max(1, round(MIN_GROUP_SECONDS * rate))
    codes = drop_short_groups(frames, identities, _filled(identities, codes), min_frames)
    boxes = rows.boxes[order]
    passage = moving_ends(frames, identities, boxes, rate)
    if image_size is not None:
        at_zone = rows_at_zones(frames, identities, boxes, (first_frame, last_frame), image_size)
        passage = passage if at_zone is None else passage & at_zone
    codes = unlabel_entries(frames, identities, codes, passage)
    codes = label_exits(frames, identities, codes, last_frame, at_zone=passage)
    names = np.asarray(EVENT_NAMES, dtype=object)[codes] if codes.size else np.array([], object)
    return EventRows(frames.astype(np.int64), identities.astype(np.int64), names)


def _filled(identities: np.ndarray, codes: np.ndarray) -> np.ndarray:
    """Each identity's unknown codes (-1, rows of a track before its tracker started) take
    the next known code of the identity (rows sorted by frame), else the previous one."""
    out = codes.copy()
    for identity in np.unique(identities):
        rows = np.flatnonzero(identities == identity)
        known = rows[codes[rows] >= 0]
        if not known.size:
            out[rows] = 0
            continue
        after = np.searchsorted(known, rows).clip(max=known.size - 1)
        out[rows] = codes[known[after]]
        out[rows[codes[rows] >= 0]] = codes[rows[codes[rows] >= 0]]
    return out
