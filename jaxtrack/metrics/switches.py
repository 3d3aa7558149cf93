"""Where identity switches come from: each CLEAR MOT switch classified by what its two tracks did.

A CLEAR MOT identity switch (:mod:`jaxtrack.metrics.clear`) is a ground-truth object ``g``
matched to track ``a`` at frame ``f0`` (its last match) and next to another track ``b`` at
frame ``f1 > f0``. The count says how often identities break, not why; the fixes differ
(re-identification, exclusion between tracks, appearance, motion gating). Each switch is
given one of five kinds, from the two tracks' matches to *other* objects and from ``a``'s
output frames:

=============  ==============================================================================
``exchange``   ``a`` is matched to another object after ``f0`` and ``b`` was matched to
               another object before ``f1``: the two tracks traded (or hopped between) objects.
``drift``      ``a`` is matched to another object after ``f0``; ``b`` came from no other
               object (new, or it had followed nothing): ``a`` left ``g`` for someone else.
``takeover``   ``b`` was matched to another object before ``f1``; ``a`` never matches another
               object after ``f0``: ``b`` came over from someone else.
``lost``       neither, and ``a`` has no output box from ``f1`` on: ``a``'s track ended (or
               paused) and another identity picked ``g`` up (what re-identification fixes).
``replaced``   neither, and ``a`` still has output boxes at ``f1`` or later, none of them on
               ``g`` or on any other object at that time: a second track took ``g`` over
               while ``a`` stayed off every object (a duplicate, or a box misplaced).
=============  ==============================================================================

The kinds are exhaustive and exclusive, so their counts add up to ``IDSW``. ``gap`` is
``f1 - f0`` (1: the switch happened from one frame to the next). The classification uses
the same matching as the counts (:func:`~jaxtrack.metrics.clear.clear_matching`), so it
inherits its threshold and conventions. :func:`~jaxtrack.metrics.evaluate.evaluate_sequence`
reports the counts (``IDSW_<kind>`` in its scores, summed when sequences are combined);
:func:`~jaxtrack.metrics.evaluate.switch_table` lists the switches of one sequence.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from jaxtrack.metrics.clear import ClearMatching, matches_by_object
from jaxtrack.metrics.preprocess import SequenceData

#: Switch kinds, in the order of the codes of :attr:`SwitchTable.kind`.
KINDS = ("exchange", "drift", "takeover", "lost", "replaced")
EXCHANGE, DRIFT, TAKEOVER, LOST, REPLACED = range(len(KINDS))
#: The name of each kind's count among an evaluation's scores (``IDSW_<kind>``).
SCORE_NAMES = {kind: f"IDSW_{kind}" for kind in KINDS}


class SwitchTable(NamedTuple):
    """Every identity switch of a sequence, in ground-truth object then frame order.

    Attributes:
        frame: ``[n]`` 1-based frame of the switch (``f1``, the first match with ``b``).
        gt_id: ``[n]`` the object's id as in the ground-truth file.
        from_id: ``[n]`` track ``a``'s id as in the result file.
        to_id: ``[n]`` track ``b``'s id.
        gap: ``[n]`` ``f1 - f0`` frames.
        kind: ``[n]`` index into :data:`KINDS`.
    """

    frame: np.ndarray
    gt_id: np.ndarray
    from_id: np.ndarray
    to_id: np.ndarray
    gap: np.ndarray
    kind: np.ndarray

    def counts(self) -> dict[str, int]:
        """``{kind: number of switches}`` for every kind of :data:`KINDS` (zeros included)."""
        totals = np.bincount(self.kind, minlength=len(KINDS))
        return {name: int(count) for name, count in zip(KINDS, totals, strict=True)}

    def rows(self) -> list[dict]:
        """One dict per switch (``frame, gt_id, from_id, to_id, gap, kind``), kinds by name."""
        return [
            {
                "frame": int(frame),
                "gt_id": int(gt),
                "from_id": int(a),
                "to_id": int(b),
                "gap": int(gap),
                "kind": KINDS[int(kind)],
            }
            for frame, gt, a, b, gap, kind in zip(*self, strict=True)
        ]


def classify_switches(data: SequenceData, matching: ClearMatching) -> SwitchTable:
    """Classifies every identity switch of ``matching`` (module docstring).

    Args:
        data: the scored boxes (:func:`~jaxtrack.metrics.preprocess.prepare_sequence`).
        matching: their CLEAR MOT matching.

    Returns:
        The switches; ``len(table.frame)`` equals the sequence's ``IDSW``.
    """
    gt_id, tracker_id, frame = matches_by_object(data, matching.matched)
    switch = np.flatnonzero((gt_id[1:] == gt_id[:-1]) & (tracker_id[1:] != tracker_id[:-1])) + 1
    # each track's matches sorted by frame, and its output frames
    by_track = np.lexsort((frame, tracker_id))
    track_start = np.searchsorted(tracker_id[by_track], np.arange(data.num_tracker_ids + 1))
    track_frames, track_objects = frame[by_track], gt_id[by_track]
    last_output = np.full(data.num_tracker_ids, -1, np.int64)
    np.maximum.at(last_output, data.tracker_id, data.tracker_frame)

    def other_object(track: int, obj: int, lo: int, hi: int) -> bool:
        """Is ``track`` matched to an object other than ``obj`` at a frame in [lo, hi)?"""
        start, stop = track_start[track], track_start[track + 1]
        frames = track_frames[start:stop]
        window = slice(
            start + np.searchsorted(frames, lo, "left"), start + np.searchsorted(frames, hi, "left")
        )
        return bool(np.any(track_objects[window] != obj))

    kinds = np.empty(switch.size, np.int64)
    end = data.num_frames + 1
    for k, i in enumerate(switch):
        obj, a, b, f0, f1 = gt_id[i], tracker_id[i - 1], tracker_id[i], frame[i - 1], frame[i]
        a_left = other_object(a, obj, f0 + 1, end)
        b_came = other_object(b, obj, 0, f1)
        if a_left:
            kinds[k] = EXCHANGE if b_came else DRIFT
        elif b_came:
            kinds[k] = TAKEOVER
        else:
            kinds[k] = LOST if last_output[a] < f1 else REPLACED
    return SwitchTable(
        frame=(frame[switch] + data.first_frame).astype(np.int64),
        gt_id=data.gt_labels[gt_id[switch]].astype(np.int64),
        from_id=data.tracker_labels[tracker_id[switch - 1]].astype(np.int64),
        to_id=data.tracker_labels[tracker_id[switch]].astype(np.int64),
        gap=(frame[switch] - frame[switch - 1]).astype(np.int64),
        kind=kinds,
    )
