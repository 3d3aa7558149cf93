"""Precision and recall of a tracker's events against scripted ones (Hierarchical Sec. 5.5).

The paper shows its events on examples only; this scores them on scenes whose events are
known (the synthetic video scenes' scripted events). Four kinds of *onsets* are scored,
each a ``(frame, identity)``:

* **Scripted** (ground-truth ids): a ``crossing`` with frames ``(first, last)`` (the two
  people's boxes overlap) gives a ``group`` onset at ``first`` and a ``split`` onset at
  ``last`` for each of its two ids; a ``group`` event ``(entry, split)`` gives a ``group``
  onset at ``entry`` and a ``split`` onset at ``split`` for each member; an ``entry`` gives an
  ``entry`` onset at its frame, except for a member entering with its group on the group's
  first frame (it collides from its first frame, so it is grouping, not entering); an
  ``exit`` gives an ``exit`` onset at its frame (the person's last). ``occlusion`` and
  ``standing`` events are not scored.
* **Predicted** (tracker ids), from each identity's rows in frame order (``prev`` its
  previous row's event, none on its first row): ``group`` where the event is ``grouping``
  or ``grouped`` and ``prev`` is neither (or none); ``split`` where the event is neither
  and ``prev`` is one of them; ``entry`` where the event is ``entering`` and ``prev`` is
  not; ``exit`` at the *last* row of each run of ``exiting`` rows (the frame the tracker
  leaves, compared with the person's last frame).

A predicted onset ``(f, i)`` may match a scripted one ``(f*, g)`` of the same kind when
``|f - f*| <= tolerance`` and tracker ``i`` is matched to ground-truth ``g`` by the CLEAR MOT
matching (:func:`~jaxtrack.metrics.clear.clear_matching`, IoU >= 0.5) on some frame in
``f* - tolerance .. f* + tolerance``. Predicted and scripted onsets of a kind are then
matched one to one, as many as possible (an optimal assignment on ``|f - f*|`` with
forbidden pairs). ``precision = matched / predicted``, ``recall = matched / scripted``, per
kind and over the four kinds together; ratios divide by ``max(1, denominator)`` as CLEAR's.

The default :data:`DEFAULT_TOLERANCE` is 25 frames, 1 s at the synthetic scenes' 25 fps: a
tracker confirms a new track a few frames after its first detection (M-of-N), an event
machine sees a collision only once the estimated boxes overlap, and a group tracker is born
only once confirmed; a second covers these delays without merging two events of one person
(the scripted events of a person are further apart).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple, Protocol

import numpy as np
from scipy.optimize import linear_sum_assignment

from jaxtrack.errors import InputError
from jaxtrack.metrics.clear import clear_matching
from jaxtrack.metrics.preprocess import prepare_sequence
from jaxtrack.types import MotTable

#: Scored kinds of onsets.
KINDS = ("group", "split", "entry", "exit")
#: Event names of a tracker in a group (the ``group`` and ``split`` onsets' states).
GROUP_STATES = ("grouping", "grouped")
#: Default matching tolerance, frames (1 s at 25 fps; module docstring).
DEFAULT_TOLERANCE = 25
#: IoU of a CLEAR MOT match.
IOU_THRESHOLD = 0.5


class EventRows(NamedTuple):
    """A tracker's events, one row per output identity and frame (host-side NumPy).

    Attributes:
        frames: ``[N]`` 1-based frames.
        ids: ``[N]`` identities (those of the tracker's results).
        names: ``[N]`` event names (``jaxtrack.filters.hier_events.EVENT_NAMES``).
    """

    frames: np.ndarray
    ids: np.ndarray
    names: np.ndarray


class Scripted(Protocol):
    """A scripted event (as :class:`jaxtrack.datasets.video_scene.ScriptedEvent`)."""

    kind: str
    ids: tuple[int, ...]
    frames: tuple[int, int]


def scripted_onsets(events: Sequence[Scripted]) -> dict[str, np.ndarray]:
    """The scripted onsets of each kind (module docstring), ``[n, 2]`` ``(frame, gt id)``."""
    onsets = {kind: [] for kind in KINDS}
    group_entries = set()
    for event in events:
        if event.kind in ("crossing", "group"):
            first, last = event.frames
            onsets["group"] += [(first, pid) for pid in event.ids]
            onsets["split"] += [(last, pid) for pid in event.ids]
        if event.kind == "group":
            group_entries |= {(event.frames[0], pid) for pid in event.ids}
    for event in events:
        onset = (event.frames[0], event.ids[0])
        if event.kind == "entry" and onset not in group_entries:
            onsets["entry"].append(onset)
        if event.kind == "exit":
            onsets["exit"].append(onset)
    return {kind: np.array(rows, np.int64).reshape(-1, 2) for kind, rows in onsets.items()}


def predicted_onsets(rows: EventRows) -> dict[str, np.ndarray]:
    """The predicted onsets of each kind (module docstring), ``[n, 2]`` ``(frame, id)``."""
    order = np.lexsort((rows.frames, rows.ids))
    frames, ids, names = rows.frames[order], rows.ids[order], np.asarray(rows.names)[order]
    grouped = np.isin(names, GROUP_STATES)
    exiting, entering = names == "exiting", names == "entering"
    first = np.ones(len(ids), bool)
    first[1:] = ids[1:] != ids[:-1]
    last = np.roll(first, -1)
    previous_grouped = ~first & np.roll(grouped, 1)
    previous_entering = ~first & np.roll(entering, 1)
    next_exiting = ~last & np.roll(exiting, -1)
    starts = {
        "group": grouped & ~previous_grouped,
        "split": ~grouped & previous_grouped,
        "entry": entering & ~previous_entering,
        "exit": exiting & ~next_exiting,
    }
    return {kind: np.stack([frames[keep], ids[keep]], 1) for kind, keep in starts.items()}


def matched_identities(results: MotTable, gt: MotTable) -> np.ndarray:
    """``[m, 3]`` ``(frame, gt id, tracker id)`` of every CLEAR MOT match (IoU >= 0.5)."""
    last = max(int(results.frames.max(initial=1)), int(gt.frames.max(initial=1)))
    data = prepare_sequence(gt, results, (1, last))
    matched = clear_matching(data, IOU_THRESHOLD).matched
    gt_ids = np.unique(gt.ids[np.trunc(gt.confs) != 0])
    tracker_ids = np.unique(results.ids)
    pairs = data.pairs
    return np.stack(
        [
            data.first_frame + pairs.frame[matched],
            gt_ids[data.gt_id[pairs.gt_row[matched]]],
            tracker_ids[data.tracker_id[pairs.tracker_row[matched]]],
        ],
        1,
    ).astype(np.int64)


def match_onsets(
    predicted: np.ndarray, scripted: np.ndarray, matches: np.ndarray, tolerance: int
) -> int:
    """How many predicted and scripted onsets of one kind match one to one (module docstring).

    Args:
        predicted: ``[n, 2]`` ``(frame, tracker id)``.
        scripted: ``[m, 2]`` ``(frame, gt id)``.
        matches: ``[k, 3]`` ``(frame, gt id, tracker id)`` from :func:`matched_identities`.
        tolerance: frames, >= 0.

    Returns:
        The number of matched pairs.
    """
    if not len(predicted) or not len(scripted):
        return 0
    near = np.abs(predicted[:, None, 0] - scripted[None, :, 0]) <= tolerance
    allowed = np.zeros_like(near)
    for j, (frame, gt_id) in enumerate(scripted):
        window = (np.abs(matches[:, 0] - frame) <= tolerance) & (matches[:, 1] == gt_id)
        allowed[:, j] = np.isin(predicted[:, 1], matches[window, 2])
    allowed &= near
    gaps = np.abs(predicted[:, None, 0] - scripted[None, :, 0]).astype(np.float64)
    forbidden = (tolerance + 1.0) * (min(near.shape) + 1)  # above any sum of allowed gaps
    rows, cols = linear_sum_assignment(np.where(allowed, gaps, forbidden))
    return int(allowed[rows, cols].sum())


def score_events(
    rows: EventRows,
    results: MotTable,
    gt: MotTable,
    scripted: Sequence[Scripted],
    tolerance: int = DEFAULT_TOLERANCE,
) -> dict:
    """Event precision and recall per kind and overall (module docstring).

    Args:
        rows: the tracker's events (identities of ``results``).
        results: the tracker's output boxes.
        gt: the ground truth.
        scripted: the scene's scripted events.
        tolerance: largest onset frame difference of a match, frames (>= 0).

    Returns:
        ``{kind: {"predicted", "scripted", "matched", "precision", "recall"}}`` for each of
        :data:`KINDS` and ``"overall"``, and ``"tolerance"``.

    Raises:
        InputError: a negative tolerance.
    """
    if tolerance < 0:
        raise InputError(f"event tolerance must be >= 0 frames, got {tolerance}")
    predicted, truth = predicted_onsets(rows), scripted_onsets(scripted)
    matches = matched_identities(results, gt)
    counts = {
        kind: (
            len(predicted[kind]),
            len(truth[kind]),
            match_onsets(predicted[kind], truth[kind], matches, tolerance),
        )
        for kind in KINDS
    }
    counts["overall"] = tuple(sum(column) for column in zip(*counts.values(), strict=True))
    scores = {kind: _ratios(*count) for kind, count in counts.items()}
    return {**scores, "tolerance": tolerance}


def _ratios(predicted: int, scripted: int, matched: int) -> dict:
    return {
        "predicted": predicted,
        "scripted": scripted,
        "matched": matched,
        "precision": matched / max(1, predicted),
        "recall": matched / max(1, scripted),
    }
