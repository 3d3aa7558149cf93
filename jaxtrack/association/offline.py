"""Host-side conversion of labelled tracks to result rows, with optional offline finishing.

:func:`track_rows` turns the padded per-frame :class:`~jaxtrack.types.Tracks` of a run into
one row per output box (a :class:`~jaxtrack.types.MotTable`, the table MOTChallenge files are
read into), ready for :func:`jaxtrack.io.write_results` and the metrics. :func:`finalise_tracks`
is an offline alternative to the online output: it keeps the whole history of every track
that was confirmed at some point (the frames before its confirmation included) and fills
gaps of at most ``max_gap`` frames by linear interpolation of the boxes, and, for a tracker
whose rows of score 0 are predictions without evidence (the Fusion tracker's coasting
targets), drops each identity's leading and trailing rows of score 0 (``trim``).
"""

from __future__ import annotations

import numpy as np

from jaxtrack.types import MotTable, Tracks


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
    tracks: Tracks, candidates: Tracks, max_gap: int = 0, first_frame: int = 1, trim: bool = False
) -> MotTable:
    """Offline output: confirmed tracks over their whole life, short gaps interpolated.

    Args:
        tracks: the online output (confirmed tracks), ``info.tracks``.
        candidates: every labelled estimate, ``info.candidates``.
        max_gap: longest run of missing frames inside a track that is filled (0: none).
        first_frame: frame number of index 0.
        trim: drop the rows of score 0 before an identity's first row of positive score and
            after its last one (an identity without any is dropped whole).

    Returns:
        The rows of every identity that appears in ``tracks``, taken from ``candidates``,
        plus interpolated rows (score: the smaller score of the two ends), sorted by frame
        and identity.
    """
    online = track_rows(tracks, first_frame)
    rows = track_rows(candidates, first_frame)
    kept = rows.select(np.isin(rows.ids, online.ids))
    if trim:
        kept = kept.select(_within_evidence(kept))
    parts = [kept]
    for identity in np.unique(kept.ids) if max_gap > 0 else []:
        own = np.nonzero(kept.ids == identity)[0]
        own = own[np.argsort(kept.frames[own])]
        frames = kept.frames[own]
        steps = np.diff(frames)
        for k in np.nonzero((steps > 1) & (steps <= max_gap + 1))[0]:
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
