"""Host-side conversion of labelled tracks to result rows, with optional offline finishing.

:func:`track_rows` turns the padded per-frame :class:`~jaxtrack.types.Tracks` of a run into
one row per output box (a :class:`~jaxtrack.types.MotTable`, the table MOTChallenge files are
read into), ready for :func:`jaxtrack.io.write_results` and the metrics. :func:`finalise_tracks`
is an offline alternative to the online output: it keeps the whole history of every track
that was confirmed at some point (the frames before its confirmation included) and fills
gaps of at most ``max_gap`` frames by linear interpolation of the boxes, and, for a tracker
whose rows of score 0 are predictions without evidence (the Fusion tracker's coasting
targets), drops each identity's leading and trailing rows of score 0 (``trim``). For a
tracker that votes targets in, :func:`chain_candidates` (``chain_iou``) first gives each
confirmed identity the hypotheses that were dropped just before it at its place.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from jaxtrack.boxes import iou_matrix
from jaxtrack.types import MotTable, Tracks

#: Rows (after the first) over which a track's first velocity is measured
#: (:func:`first_motion`: the chaining here and the retrodiction's walk).
VELOCITY_ROWS = 5


def track_rows(tracks: Tracks, first_frame: int = 1) -> MotTable:
    """Rows of the masked slots of ``tracks`` (``[num_frames, max_objects]``).

    Args:
        tracks: labelled boxes of a run, e.g. ``info.tracks`` of
            :func:`~jaxtrack.filters.base.run`.
        first_frame: frame number of index 0.

    Returns:
        The rows, in frame order (slot order within a frame); ``confs`` are the track scores.
    """
    mask = np.asarray(tracks.mask)
    frame_index, slot = np.nonzero(mask)
    return MotTable.from_arrays(
        frame_index + first_frame,
        np.asarray(tracks.ids)[frame_index, slot],
        np.asarray(tracks.boxes, np.float64)[frame_index, slot],
        np.asarray(tracks.scores, np.float64)[frame_index, slot],
    )


def finalise_tracks(
    tracks: Tracks,
    candidates: Tracks,
    max_gap: int = 0,
    first_frame: int = 1,
    trim: bool = False,
    chain_iou: float = 0.0,
    breaks: Mapping[int, Sequence[int]] | None = None,
) -> MotTable:
    """Offline output: confirmed tracks over their whole life, short gaps interpolated.

    Args:
        tracks: the online output (confirmed tracks), ``info.tracks``.
        candidates: every labelled estimate, ``info.candidates``.
        max_gap: longest run of missing frames inside a track that is filled (0: none).
        first_frame: frame number of index 0.
        trim: drop the rows of score 0 before an identity's first row of positive score and
            after its last one (an identity without any is dropped whole).
        chain_iou: when positive, each confirmed identity first takes over the candidates
            that were never confirmed and ended just before it began
            (:func:`chain_candidates`, within ``max_gap`` frames, at this IoU); 0: off.
        breaks: ``{identity: frames}``: for each frame ``f``, the identity's last gap that
            ends at or before ``f`` is not filled (a join the tracker made with little
            evidence, e.g. the Hierarchical tracker's re-association by a fallback model;
            :func:`gap_breaks`). None: every gap up to ``max_gap`` is filled.

    Returns:
        The rows of every identity that appears in ``tracks``, taken from ``candidates``,
        plus interpolated rows (score: the smaller score of the two ends), sorted by frame
        and identity.
    """
    online = track_rows(tracks, first_frame)
    rows = track_rows(candidates, first_frame)
    if chain_iou > 0:
        rows = chain_candidates(rows, np.unique(online.ids), max_gap, chain_iou)
    kept = rows.select(np.isin(rows.ids, online.ids))
    if trim:
        kept = kept.select(_within_evidence(kept))
    parts = [kept]
    for identity in np.unique(kept.ids) if max_gap > 0 else []:
        own = np.nonzero(kept.ids == identity)[0]
        own = own[np.argsort(kept.frames[own])]
        frames = kept.frames[own]
        steps = np.diff(frames)
        gaps = steps > 1
        filled = gaps & (steps <= max_gap + 1)
        for frame in (breaks or {}).get(int(identity), ()):
            before = np.nonzero(gaps & (frames[1:] <= frame))[0]
            if before.size:
                filled[before[-1]] = False
        for k in np.nonzero(filled)[0]:
            start, end = own[k], own[k + 1]
            gap = np.arange(frames[k] + 1, frames[k + 1])
            fraction = ((gap - frames[k]) / steps[k])[:, None]
            parts.append(
                MotTable.from_arrays(
                    gap,
                    np.full(gap.size, identity),
                    kept.boxes[start] + fraction * (kept.boxes[end] - kept.boxes[start]),
                    np.full(gap.size, min(kept.confs[start], kept.confs[end])),
                )
            )
    merged = MotTable.from_arrays(
        np.concatenate([part.frames for part in parts]),
        np.concatenate([part.ids for part in parts]),
        np.concatenate([part.boxes for part in parts]),
        np.concatenate([part.confs for part in parts]),
    )
    return merged.select(np.lexsort((merged.ids, merged.frames)))


def gap_breaks(flags: np.ndarray, ids: np.ndarray, first_frame: int = 1) -> dict[int, list[int]]:
    """The ``breaks`` of :func:`finalise_tracks` from per-frame, per-slot flags.

    Args:
        flags: ``[num_frames, slots]``, True where the slot's identity is not to be
            interpolated across its gap before that frame.
        ids: ``[num_frames, slots]``, the slots' identities on each frame.
        first_frame: frame number of index 0.

    Returns:
        ``{identity: [frame, ...]}`` (frames in increasing order).
    """
    frame_index, slot = np.nonzero(np.asarray(flags))
    identities = np.asarray(ids)[frame_index, slot].tolist()
    breaks: dict[int, list[int]] = {}
    for index, identity in zip(frame_index.tolist(), identities, strict=True):
        breaks.setdefault(int(identity), []).append(index + first_frame)
    return breaks


def _within_evidence(rows: MotTable) -> np.ndarray:
    """Rows lying between their identity's first and last row of positive score."""
    ids = np.asarray(rows.ids)
    positive = np.asarray(rows.confs) > 0
    unique, index = np.unique(ids, return_inverse=True)
    first = np.full(unique.size, np.inf)
    last = np.full(unique.size, -np.inf)
    np.minimum.at(first, index[positive], rows.frames[positive])
    np.maximum.at(last, index[positive], rows.frames[positive])
    return (rows.frames >= first[index]) & (rows.frames <= last[index])


def first_motion(rows: MotTable, own: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """An identity's first frame, first box and the velocity of its top-left corner over its
    first :data:`VELOCITY_ROWS` + 1 rows (``own``: its rows in frame order; 0 for a single
    row), pixels per frame."""
    box = rows.boxes[own[0]]
    last = own[min(VELOCITY_ROWS, own.size - 1)]
    steps = max(int(rows.frames[last] - rows.frames[own[0]]), 1)
    return int(rows.frames[own[0]]), box, (rows.boxes[last, :2] - box[:2]) / steps


def chain_candidates(
    rows: MotTable, confirmed: np.ndarray, max_gap: int, min_iou: float
) -> MotTable:
    """Candidates that were never confirmed, relabelled as the confirmed identity they led to.

    A tracker that votes targets in (the Fusion tracker) drops a hypothesis on its first
    frame without support, and a new hypothesis on the same person starts on the next
    detection. Only the one that is voted in keeps its rows in the offline output. Here each
    confirmed identity (in the order of its first row) walks backwards: its first box is
    moved back at the velocity of its first rows
    to the last frame ``f`` of every unconfirmed, unclaimed identity that ended at most
    ``max_gap + 1`` frames before the confirmed identity's first frame. The identity whose
    last box the moved box overlaps most, by IoU ``min_iou`` or more, is taken over: its rows
    get the confirmed identity. The walk goes on from its first row and stops when no
    identity qualifies. The gap between them is left to the gap interpolation.

    Args:
        rows: every candidate row (confirmed and unconfirmed identities).
        confirmed: the identities that were confirmed.
        max_gap: the most frames between a taken identity's last row and the next row.
        min_iou: smallest overlap of the moved box with the taken identity's last box.

    Returns:
        ``rows`` with the taken identities relabelled (same rows, same order).
    """
    ids = np.asarray(rows.ids).copy()
    order = np.lexsort((rows.frames, ids))
    unique, starts = np.unique(ids[order], return_index=True)
    groups = dict(zip(unique.tolist(), np.split(order, starts[1:]), strict=True))
    confirmed_ids = set(np.asarray(confirmed).tolist())
    open_ids = [i for i in groups if i not in confirmed_ids]
    ends = {i: int(rows.frames[groups[i][-1]]) for i in open_ids}
    heads = sorted((int(rows.frames[groups[i][0]]), i) for i in confirmed_ids if i in groups)
    for _, identity in heads:
        frame, box, velocity = first_motion(rows, groups[identity])
        while True:
            near = [i for i in open_ids if frame - max_gap - 1 <= ends[i] < frame]
            if not near:
                break
            last_boxes = np.stack([rows.boxes[groups[i][-1]] for i in near])
            moved = np.stack([box] * len(near))
            moved[:, :2] -= velocity * (frame - np.asarray([ends[i] for i in near]))[:, None]
            overlap = np.diag(iou_matrix(moved, last_boxes, xp=np))
            best = int(np.argmax(overlap))
            if overlap[best] < min_iou:
                break
            taken = near[best]
            open_ids.remove(taken)
            ids[groups[taken]] = identity
            frame, box, taken_velocity = first_motion(rows, groups[taken])
            if groups[taken].size > 1:
                velocity = taken_velocity
    return MotTable.from_arrays(rows.frames, ids, rows.boxes, rows.confs, rows.extra)
