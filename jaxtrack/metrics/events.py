"""Precision and recall of a tracker's events against scripted ones (Hierarchical Sec. 5.5).

The paper shows its events on examples only; this scores them on scenes whose events are
known (the synthetic video scenes' scripted events). Four kinds of *onsets* are scored,
each a ``(frame, identity)``:

* **Scored truths** (ground-truth ids): a ``crossing`` with frames ``(first, last)`` (the
  two people's boxes overlap) gives a ``group`` onset at ``first`` and a ``split`` onset at
  ``last`` for each of its two ids; a ``group`` event ``(entry, split)`` gives a ``group``
  onset at ``entry`` and a ``split`` onset at ``split`` for each member; an ``entry`` gives an
  ``entry`` onset and an ``exit`` an ``exit`` onset at its frame (the person's first / last),
  unless the person's box overlaps another's there (:func:`gt_collisions`). ``occlusion``
  and ``standing`` events are not scored.
* **Unscored truths** ("don't care", like MOTChallenge's ignored boxes): people's boxes also
  overlap outside the scripted events (a scene puts some twenty people on 640 x 480 pixels,
  and boxes of people at different depths overlap in the image). Each start (``group``) and
  end (``split``) of a run of frames in which a person's gt box overlaps another's, and the
  entries and exits left out above, are true events that the script does not name.
* **Predicted** (tracker ids), from each identity's rows in frame order (``prev`` its
  previous row's event, none on its first row): ``group`` where the event is ``grouping``
  or ``grouped`` and ``prev`` is neither (or none); ``split`` where the event is neither
  and ``prev`` is one of them; ``entry`` where the event is ``entering`` and ``prev`` is
  not; ``exit`` at the *last* row of each run of ``exiting`` rows (the frame the tracker
  leaves, compared with the person's last frame).

A predicted onset ``(f, i)`` may match a truth onset ``(f*, g)`` of the same kind when
``|f - f*| <= tolerance`` and tracker ``i`` is matched to ground-truth ``g`` by the CLEAR MOT
matching (:func:`~jaxtrack.metrics.clear.clear_matching`, IoU >= 0.5) on some frame in
``f* - tolerance .. f* + tolerance``. Predicted and scored onsets of a kind are matched one
to one, as many as possible; an unmatched predicted onset that may match an unscored truth
is *ignored*. ``precision = matched / (predicted - ignored)``, ``recall = matched /
scored``, per kind and over the four kinds together; ratios divide by ``max(1,
denominator)`` as CLEAR's.

The default :data:`DEFAULT_TOLERANCE` is 25 frames, 1 s at the synthetic scenes' 25 fps: a
tracker confirms a new track a few frames after its first detection (M-of-N), an event
machine sees a collision only once the estimated boxes overlap, and a group tracker is born
only once confirmed; a second covers these delays.
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


def gt_collisions(gt: MotTable) -> np.ndarray:
    """``[N]`` whether each gt row's box intersects (positive area) another gt box of its
    frame: the scenes' own definition of two people overlapping."""
    colliding = np.zeros(len(gt), bool)
    order = np.argsort(gt.frames, kind="stable")
    bounds = np.flatnonzero(np.diff(gt.frames[order])) + 1
    for rows in np.split(order, bounds):
        low, high = gt.boxes[rows, :2], gt.boxes[rows, :2] + gt.boxes[rows, 2:]
        sides = np.minimum(high[:, None], high[None]) - np.maximum(low[:, None], low[None])
        overlap = np.all(sides > 0, axis=-1)
        np.fill_diagonal(overlap, False)
        colliding[rows] = overlap.any(axis=1)
    return colliding


def scripted_onsets(
    events: Sequence[Scripted], gt: MotTable
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The scored and the unscored ("don't care") truth onsets (module docstring).

    Returns:
        ``(scored, unscored)``: for each kind, ``[n, 2]`` ``(frame, gt id)``.
    """
    colliding = gt_collisions(gt)
    touching = set(zip(gt.frames[colliding].tolist(), gt.ids[colliding].tolist(), strict=True))
    scored = {kind: [] for kind in KINDS}
    unscored = {kind: [] for kind in KINDS}
    for event in events:
        if event.kind in ("crossing", "group"):
            first, last = event.frames
            scored["group"] += [(first, pid) for pid in event.ids]
            scored["split"] += [(last, pid) for pid in event.ids]
        if event.kind in ("entry", "exit"):
            onset = (event.frames[0], event.ids[0])
            (unscored if onset in touching else scored)[event.kind].append(onset)
    order = np.lexsort((gt.frames, gt.ids))
    ids, frames, together = gt.ids[order], gt.frames[order], colliding[order]
    first = np.ones(len(ids), bool)
    first[1:] = ids[1:] != ids[:-1]
    before = ~first & np.roll(together, 1)
    for kind, keep in (("group", together & ~before), ("split", ~together & before)):
        unscored[kind] += list(zip(frames[keep].tolist(), ids[keep].tolist(), strict=True))
    return tuple(
        {kind: np.array(rows, np.int64).reshape(-1, 2) for kind, rows in onsets.items()}
        for onsets in (scored, unscored)
    )


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


def onset_summary(rows: EventRows) -> str:
    """How many onsets of each kind a tracker's events hold (:func:`predicted_onsets`), for
    a run's report: e.g. ``"onsets: 12 group, 11 split, 20 entry, 18 exit"``."""
    counts = {kind: len(onsets) for kind, onsets in predicted_onsets(rows).items()}
    return "onsets: " + ", ".join(f"{counts[kind]} {kind}" for kind in KINDS)


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


def compatible(
    predicted: np.ndarray, truth: np.ndarray, matches: np.ndarray, tolerance: int
) -> np.ndarray:
    """``[n, m]`` whether predicted onset ``i`` may match truth onset ``j`` (module docstring).

    Args:
        predicted: ``[n, 2]`` ``(frame, tracker id)``.
        truth: ``[m, 2]`` ``(frame, gt id)``.
        matches: ``[k, 3]`` ``(frame, gt id, tracker id)`` from :func:`matched_identities`.
        tolerance: frames, >= 0.
    """
    allowed = np.abs(predicted[:, None, 0] - truth[None, :, 0]) <= tolerance
    for j, (frame, gt_id) in enumerate(truth):
        window = (np.abs(matches[:, 0] - frame) <= tolerance) & (matches[:, 1] == gt_id)
        allowed[:, j] &= np.isin(predicted[:, 1], matches[window, 2])
    return allowed


def match_onsets(allowed: np.ndarray) -> np.ndarray:
    """Matches predicted and truth onsets one to one, as many as possible (an optimal
    assignment in which a forbidden pair costs 1, an allowed one 0).

    Args:
        allowed: ``[n, m]`` from :func:`compatible`.

    Returns:
        ``[n]`` True for each matched predicted onset.
    """
    matched = np.zeros(allowed.shape[0], bool)
    if allowed.size:
        rows, cols = linear_sum_assignment(np.where(allowed, 0.0, 1.0))
        matched[rows[allowed[rows, cols]]] = True
    return matched


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
        ``{kind: {"predicted", "ignored", "scripted", "matched", "precision", "recall"}}``
        (counts of onsets, ``scripted`` the scored truths) for each of
        :data:`KINDS` and ``"overall"``, and ``"tolerance"``.

    Raises:
        InputError: a negative tolerance.
    """
    if tolerance < 0:
        raise InputError(f"event tolerance must be >= 0 frames, got {tolerance}")
    predicted = predicted_onsets(rows)
    scored, unscored = scripted_onsets(scripted, gt)
    matches = matched_identities(results, gt)
    counts = {}
    for kind in KINDS:
        onsets = predicted[kind]
        matched = match_onsets(compatible(onsets, scored[kind], matches, tolerance))
        ignored = compatible(onsets, unscored[kind], matches, tolerance).any(axis=1) & ~matched
        counts[kind] = (len(onsets), int(ignored.sum()), len(scored[kind]), int(matched.sum()))
    counts["overall"] = tuple(sum(column) for column in zip(*counts.values(), strict=True))
    scores = {kind: _ratios(*count) for kind, count in counts.items()}
    return {**scores, "tolerance": tolerance}


#: The counts of a kind's scores (:func:`score_events`), in the order :func:`_ratios` takes.
COUNTS = ("predicted", "ignored", "scripted", "matched")


def pool_scores(runs: Sequence[dict]) -> dict:
    """Scores of several runs pooled: each kind's counts summed, the ratios taken again.

    Precision and recall of the pool are those of one run holding all the runs' onsets,
    ``sum matched / max(1, sum (predicted - ignored))`` and ``sum matched / max(1, sum
    scored)`` (not the mean of the runs' ratios, and not ``matched / predicted``: an ignored
    onset stays ignored in the pool).

    Args:
        runs: outputs of :func:`score_events`, with the same tolerance.

    Returns:
        The same mapping as :func:`score_events` for the pooled onsets.

    Raises:
        InputError: no runs, or runs scored with different tolerances.
    """
    if not runs:
        raise InputError("no event scores to pool")
    tolerances = {run["tolerance"] for run in runs}
    if len(tolerances) > 1:
        raise InputError(f"event scores with different tolerances {sorted(tolerances)}")
    scores = {
        kind: _ratios(*(sum(run[kind][count] for run in runs) for count in COUNTS))
        for kind in (*KINDS, "overall")
    }
    return {**scores, "tolerance": tolerances.pop()}


def _ratios(predicted: int, ignored: int, scripted: int, matched: int) -> dict:
    return {
        "predicted": predicted,
        "ignored": ignored,
        "scripted": scripted,
        "matched": matched,
        "precision": matched / max(1, predicted - ignored),
        "recall": matched / max(1, scripted),
    }
