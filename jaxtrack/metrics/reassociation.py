"""Identity kept across scripted occlusions, crossings and group walks (Hierarchical goal).

For each scripted event of :data:`KINDS` (:class:`~jaxtrack.datasets.video_scene.
ScriptedEvent`) and each person in it, the tracker identity matched to the person (CLEAR MOT
matching at IoU 0.5, :func:`~jaxtrack.metrics.events.matched_identities`) *before* the event
is compared with the one matched *after* it:

* ``occlusion`` and ``crossing`` (frames ``first..last``: hidden behind the occluder, boxes
  overlapping): before = the last match in ``[first - window, first)``, after = the first
  match in ``(last, last + window]``;
* ``group`` (frames ``entry..split``: the people enter together and walk side by side):
  before = the last match within the group walk ``[first, last]``, after = the first match
  in ``(last, last + window]``.

A case counts when both exist; it is *kept* when they are the same identity. Cases where the
person is not matched on one side (missed by the tracker, or gone) are counted apart
(``unscored``), not as failures or successes.
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


def identity_kept(
    results: MotTable,
    gt: MotTable,
    scripted: Sequence[Scripted],
    window: int = DEFAULT_WINDOW,
) -> dict:
    """The share of scripted events after which each person keeps their tracker identity.

    Args:
        results: the tracker's output boxes.
        gt: the ground truth.
        scripted: the scene's scripted events (others than :data:`KINDS` are ignored).
        window: frames searched on each side of an event.

    Returns:
        ``{kind: {"cases", "kept", "unscored", "rate"}}`` for each of :data:`KINDS` and
        ``"overall"`` (``rate`` None without cases), and ``"window"``.
    """
    matches = matched_identities(results, gt)
    counts = {kind: [0, 0, 0] for kind in KINDS}
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
            tally = counts[event.kind]
            if not len(before) or not len(after):
                tally[2] += 1
                continue
            tally[0] += 1
            tally[1] += int(before[-1, 2] == after[0, 2])
    counts["overall"] = [sum(column) for column in zip(*counts.values(), strict=True)]
    scores = {
        kind: {
            "cases": cases,
            "kept": kept,
            "unscored": unscored,
            "rate": kept / cases if cases else None,
        }
        for kind, (cases, kept, unscored) in counts.items()
    }
    return {**scores, "window": window}
