"""Host-side conversion of labelled tracks to result rows, with optional offline finishing.

:func:`track_rows` turns the padded per-frame :class:`~jaxtrack.types.Tracks` of a run into
one row per output box, ready for :func:`jaxtrack.io.write_results`. :func:`finalise_tracks`
is an offline alternative to the online output: it keeps the whole history of every track
that was confirmed at some point (the frames before its confirmation included) and fills
gaps of at most ``max_gap`` frames by linear interpolation of the boxes.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from jaxtrack.types import Tracks


class TrackRows(NamedTuple):
    """One row per output box (NumPy, host-side).

    Attributes:
        frames: 1-based frame numbers, ``[num_rows]``.
        ids: track identities, ``[num_rows]``.
        boxes: top-left ``(x, y, w, h)``, ``[num_rows, 4]``.
        scores: confidences, ``[num_rows]``.
    """

    frames: np.ndarray
    ids: np.ndarray
    boxes: np.ndarray
    scores: np.ndarray


def track_rows(tracks: Tracks, first_frame: int = 1) -> TrackRows:
    """Rows of the masked slots of ``tracks`` (``[num_frames, max_objects]``).

    Args:
        tracks: labelled boxes of a run, e.g. ``info.tracks`` of
            :func:`~jaxtrack.filters.base.run`.
        first_frame: frame number of index 0.

    Returns:
        The rows, in frame order.
    """
    mask = np.asarray(tracks.mask)
    frame_index, slot = np.nonzero(mask)
    return TrackRows(
        frames=frame_index + first_frame,
        ids=np.asarray(tracks.ids)[frame_index, slot],
        boxes=np.asarray(tracks.boxes, np.float64)[frame_index, slot],
        scores=np.asarray(tracks.scores, np.float64)[frame_index, slot],
    )


def finalise_tracks(
    tracks: Tracks, candidates: Tracks, max_gap: int = 0, first_frame: int = 1
) -> TrackRows:
    """Offline output: confirmed tracks over their whole life, short gaps interpolated.

    Args:
        tracks: the online output (confirmed tracks), ``info.tracks``.
        candidates: every labelled estimate, ``info.candidates``.
        max_gap: longest run of missing frames inside a track that is filled (0: none).
        first_frame: frame number of index 0.

    Returns:
        The rows of every identity that appears in ``tracks``, taken from ``candidates``,
        plus interpolated rows (score: the smaller score of the two ends), sorted by frame
        and identity.
    """
    online = track_rows(tracks, first_frame)
    rows = track_rows(candidates, first_frame)
    keep = np.isin(rows.ids, online.ids)
    parts = [TrackRows(*(column[keep] for column in rows))]
    kept = parts[0]
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
                TrackRows(
                    frames=gap,
                    ids=np.full(gap.size, identity),
                    boxes=kept.boxes[start] + fraction * (kept.boxes[end] - kept.boxes[start]),
                    scores=np.full(gap.size, min(kept.scores[start], kept.scores[end])),
                )
            )
    merged = TrackRows(*(np.concatenate(columns) for columns in zip(*parts, strict=True)))
    order = np.lexsort((merged.ids, merged.frames))
    return TrackRows(*(column[order] for column in merged))
