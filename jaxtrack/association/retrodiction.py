"""Retrodiction: confirmed tracks extended backwards onto the detections that preceded them.

A tracker that waits for evidence starts its tracks late. The PHD tracker's extraction
needs the detection's share of the updated PHD, ``C(z) / (kappa(z) + C(z))``, above one half,
and a target first seen where the birth intensity is low (or the clutter intensity high)
takes several frames of detections to get there; the offline output
(:func:`~jaxtrack.association.offline.finalise_tracks`) keeps a track from its first
*estimate*, so those frames stay misses although the detector saw the target. Once a track
is confirmed, the frames before its first estimate can be read again with hindsight, as a
fixed-interval smoother would: walking back from the track's first box with its velocity,
each earlier frame's detection that the constant-velocity box overlaps by ``min_iou`` or
more, and that no output box already covers, is taken as the track's box on that frame.
The walk stops at the first frame without such a detection (no gap is crossed), after
``max_frames`` frames, or at the span's first frame.

This is host-side post-processing of the offline output (NumPy), like the gap
interpolation: it adds rows on detections only, never moves or removes a row, and changes no
identity. ``PHDConfig.retrodiction`` turns it on (:func:`jaxtrack.pipelines.tracking.output_rows`,
:func:`jaxtrack.pipelines.sweep.sweep`).
"""

from __future__ import annotations

import numpy as np

from jaxtrack.association.offline import first_motion, track_rows
from jaxtrack.boxes import iou_matrix
from jaxtrack.types import Detections, MotTable, Tracks

#: Overlap of the constant-velocity box with the detection it takes: the CLEAR MOT match
#: threshold, so that a taken detection is one that would match the same object.
RETRODICTION_IOU = 0.5


def detection_rows(detections: Detections, first_frame: int = 1) -> MotTable:
    """The real (masked) slots of padded detections as rows (ids -1, confs the scores),
    read as :func:`~jaxtrack.association.offline.track_rows` reads tracks."""
    ids = np.full(np.shape(detections.mask), -1)
    tracks = Tracks(detections.boxes, ids, detections.scores, detections.mask)
    return track_rows(tracks, first_frame)


def retrodict(
    rows: MotTable,
    detections: MotTable,
    first_frame: int,
    max_frames: int,
    min_iou: float = RETRODICTION_IOU,
) -> MotTable:
    """Extends every identity of ``rows`` backwards onto the detections before its first row.

    Identities are taken in the order of their first frame (then identity). For each, with
    ``b`` its first box, ``f0`` its frame and ``v`` the velocity of its top-left corner over
    its first :data:`~jaxtrack.association.offline.VELOCITY_ROWS` + 1 rows (pixels per frame;
    0 for a single row; :func:`~jaxtrack.association.offline.first_motion`), frames
    ``f0 - 1, f0 - 2, ...`` are visited: the box ``b`` moved by ``-v`` is compared with the
    frame's detections that no output box (``rows`` and the rows added so far) overlaps by
    ``min_iou``; the most overlapping one, if its IoU is at least ``min_iou``, becomes the
    identity's row on that frame (its box and score) and the new ``b``. The walk ends at the
    first frame without one, after ``max_frames`` frames, or before ``first_frame``.

    Args:
        rows: a tracker's (offline) output.
        detections: the detections the tracker was given (:func:`detection_rows`).
        first_frame: the span's first frame (no row is added before it).
        max_frames: the most frames an identity is extended by (0: ``rows`` unchanged).
        min_iou: overlap of the walked box with the detection it takes.

    Returns:
        ``rows`` plus the added rows, sorted by frame and identity.
    """
    if max_frames <= 0 or len(rows) == 0 or len(detections) == 0:
        return rows
    by_frame = _rows_by_frame(detections.frames)
    output_by_frame = _rows_by_frame(rows.frames)
    covered: dict[int, np.ndarray] = {}

    def free(frame: int) -> np.ndarray:
        """The frame's detections no output box covers (computed once, then updated)."""
        if frame not in covered:
            own = by_frame.get(frame, _NONE)
            taken = np.zeros(own.size, bool)
            out = output_by_frame.get(frame, _NONE)
            if own.size and out.size:
                overlap = iou_matrix(detections.boxes[own], rows.boxes[out], xp=np)
                taken = overlap.max(axis=1) >= min_iou
            covered[frame] = taken
        return covered[frame]

    order = np.lexsort((rows.ids, rows.frames))
    identities, starts = np.unique(rows.ids[order], return_index=True)
    added: list[tuple[int, int, np.ndarray, float]] = []
    for identity in identities[np.argsort(starts, kind="stable")]:
        own = order[rows.ids[order] == identity]
        frame0, box, velocity = first_motion(rows, own)
        box = box.copy()
        for frame in range(frame0 - 1, max(first_frame, frame0 - max_frames) - 1, -1):
            box[:2] -= velocity
            own_dets = by_frame.get(frame, _NONE)
            if own_dets.size == 0:
                break
            taken = free(frame)
            overlap = iou_matrix(box[None], detections.boxes[own_dets], xp=np)[0]
            overlap[taken] = -1.0
            best = int(np.argmax(overlap))
            if overlap[best] < min_iou:
                break
            box = detections.boxes[own_dets[best]].copy()
            # The new row covers every detection it overlaps by min_iou, itself included.
            taken |= iou_matrix(box[None], detections.boxes[own_dets], xp=np)[0] >= min_iou
            score = float(detections.confs[own_dets[best]])
            added.append((frame, int(identity), box.copy(), score))
    if not added:
        return rows
    frames, ids, boxes, confs = zip(*added, strict=True)
    extended = MotTable.from_arrays(
        np.concatenate([rows.frames, frames]),
        np.concatenate([rows.ids, ids]),
        np.concatenate([rows.boxes, np.stack(boxes)]),
        np.concatenate([rows.confs, confs]),
        np.concatenate([rows.extra, np.full((len(added), rows.extra.shape[1]), -1.0)]),
    )
    return extended.select(np.lexsort((extended.ids, extended.frames)))


_NONE = np.zeros(0, np.int64)


def _rows_by_frame(frames: np.ndarray) -> dict[int, np.ndarray]:
    """Row indices of each frame."""
    order = np.argsort(frames, kind="stable")
    values, starts = np.unique(frames[order], return_index=True)
    return {
        int(value): part for value, part in zip(values, np.split(order, starts[1:]), strict=True)
    }
