"""Identity kept across scripted occlusions, crossings and group walks (Hierarchical goal).

For each scripted event of :data:`KINDS` (:class:`~jaxtrack.datasets.video_scene.
ScriptedEvent`) and each person in it, the tracker identity matched to the person (CLEAR MOT
matching at IoU 0.5, :func:`~jaxtrack.metrics.events.matched_identities`) *before* the event
is compared with the one matched *after* it:

* ``occlusion`` and ``crossing`` (frames ``first..last``: hidden behind the occluder, boxes
  overlapping): before = the last match in ``[first - window, first)``, after = the first
  match in ``(last, last + window]``;
* ``group`` (frames ``entry..split``: the people enter together and walk side by side):
  before = the *first* match within the group walk ``[first, last]`` (the identity the
  person was given when the walk was picked up), after = the first match in ``(last, last +
  window]``, so that an identity swapped during the walk is not kept.

A case counts when the person is matched before the event. It is *kept* when the identity
after is the same; it is *lost* (counted, not kept) when the person is in the ground truth
within ``window`` frames after the event but no track is matched to them there (the tracker
did not pick them up again). A person unmatched before the event, or gone from the ground
truth after it, is counted apart (``unscored``), neither a failure nor a success.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from jaxtrack.metrics.events import Scripted, matched_identities
from jaxtrack.types import MotTable

#: The scripted events whose identities are checked.
KINDS = ("occlusion", "crossing", "group")
#: Frames searched before and after an event for a match (2 s at 25 fps).
DEFAULT_WINDOW = 50


#: A case's outcome: kept, another identity after (switched), not picked up again (lost),
#: or not scored (unmatched before the event, or gone after it).
OUTCOMES = ("kept", "switched", "lost", "unscored")


def identity_cases(
    results: MotTable,
    gt: MotTable,
    scripted: Sequence[Scripted],
    window: int = DEFAULT_WINDOW,
) -> list[dict]:
    """Every (scripted event, person) case of :data:`KINDS`, with its identities.

    Args:
        results: the tracker's output boxes.
        gt: the ground truth.
        scripted: the scene's scripted events (others than :data:`KINDS` are ignored).
        window: frames searched on each side of an event.

    Returns:
        One dict per case, in the events' order: ``kind``, ``person``, ``frames`` (the
        event's ``[first, last]``), ``before`` and ``after`` (the tracker identities the
        module docstring defines, None where there is no match) and ``outcome`` (one of
        :data:`OUTCOMES`).
    """
    matches = matched_identities(results, gt)
    cases = []
    for event in scripted:
        if event.kind not in KINDS:
            continue
        first, last = event.frames
        start = first if event.kind == "group" else first - window
        stop = last if event.kind == "group" else first - 1
        for person in event.ids:
            own = matches[matches[:, 1] == person]
            own = own[np.argsort(own[:, 0], kind="stable")]
            before = own[(own[:, 0] >= start) & (own[:, 0] <= stop)]
            after = own[(own[:, 0] > last) & (own[:, 0] <= last + window)]
            seen = gt.frames[(gt.ids == person) & (gt.frames > last) & (gt.frames <= last + window)]
            identity = None
            if len(before):
                identity = int(before[0, 2] if event.kind == "group" else before[-1, 2])
            successor = int(after[0, 2]) if len(after) else None
            if identity is None or not (len(after) or len(seen)):
                outcome = "unscored"
            elif successor is None:
                outcome = "lost"
            else:
                outcome = "kept" if identity == successor else "switched"
            cases.append(
                {
                    "kind": event.kind,
                    "person": int(person),
                    "frames": [int(first), int(last)],
                    "before": identity,
                    "after": successor,
                    "outcome": outcome,
                }
            )
    return cases


def identity_kept(
    results: MotTable,
    gt: MotTable,
    scripted: Sequence[Scripted],
    window: int = DEFAULT_WINDOW,
) -> dict:
    """The share of scripted events after which each person keeps their tracker identity
    (the cases of :func:`identity_cases`, whose arguments these are, counted).

    Returns:
        ``{kind: {"cases", "kept", "lost", "unscored", "rate"}}`` for each of :data:`KINDS`
        and ``"overall"`` (``lost`` cases are among ``cases``; ``rate = kept / cases``, None
        without cases), and ``"window"``.
    """
    return count_cases(identity_cases(results, gt, scripted, window), window)


def count_cases(cases: Sequence[dict], window: int = DEFAULT_WINDOW) -> dict:
    """:func:`identity_kept`'s counts of the cases of :func:`identity_cases`."""
    counts = {kind: [0, 0, 0, 0] for kind in KINDS}
    for case in cases:
        tally = counts[case["kind"]]
        outcome = case["outcome"]
        if outcome == "unscored":
            tally[3] += 1
            continue
        tally[0] += 1
        tally[1] += int(outcome == "kept")
        tally[2] += int(outcome == "lost")
    counts["overall"] = [sum(column) for column in zip(*counts.values(), strict=True)]
    scores = {
        kind: {
            "cases": cases,
            "kept": kept,
            "lost": lost,
            "unscored": unscored,
            "rate": kept / cases if cases else None,
        }
        for kind, (cases, kept, lost, unscored) in counts.items()
    }
    return {**scores, "window": window}
