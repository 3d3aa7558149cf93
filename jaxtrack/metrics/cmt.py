"""CMT's error rates (Cui et al., Sec. VII-B): overall error OE, delay error DE, swap error SE.

The paper defines them in words: OE is "the ratio of the number of false tracked frames to
total frame number", DE "the ratio of the number of untracked entered targets [and] tracked
exited targets to total exited and entered objects", SE "the ratio of the number of false
identification swap frames to the total frame number". Made exact here on the CLEAR MOT
matching (:func:`jaxtrack.metrics.clear.clear_matching`): in each frame, ground-truth and
tracker boxes are matched one-to-one among the pairs with IoU >= 0.5 (the evaluation's
threshold), by the Hungarian assignment that keeps the previous frame's correspondences first
and then maximises the summed IoU. With ``F`` the frames of the scored span:

* A gt target is *correctly tracked* in a frame when it is matched there and the match is not
  an identity switch: its track is the one the target was last matched to, in any earlier
  frame (on the target's first match, any track). A frame is *falsely tracked* when a gt
  target in it is not correctly tracked (missed, or matched through a switch) or a tracker box
  in it is unmatched (a false track). ``OE = falsely tracked frames / F``.
* ``SE = frames with at least one identity switch (CLEAR's IDSW) / F``.
* A target *enters* when its first frame comes after the span's first frame and *exits* when
  its last frame comes before the span's last. An entering target is *picked up late* when
  it is not matched within ``tolerance`` frames of its first frame ``f0`` (no match in
  ``f0 .. f0 + tolerance``). An exiting target that was ever matched is *released late* when
  the track it was last matched to is a false track (an unmatched box) in each of the
  ``tolerance + 1`` frames after the target's last frame ``f1`` (``f1 + 1 .. f1 + tolerance
  + 1``): a track that stops, or goes on matched to another target, is released; frames
  after the span are not seen, so a window cut by the span's end is never late.
  ``DE = (entries picked up late + exits released late) / (entering + exiting targets)``; a
  target that both enters and exits counts twice.

* ``SE`` *on the crossings* (the paper's SE claim is about the crossings of similarly dressed
  people; :func:`crossing_swap_fields`): a crossing of people ``P`` scripted over frames
  ``first..last`` (their boxes overlap) has the window ``first .. last + tolerance`` (a swap
  shows when the matching picks the people up again after the overlap); ``SE_crossings =
  frames of a window in which one of its people has an identity switch / frames of the
  windows``, each frame counted once even where windows overlap.

The paper states no tolerance; the default :data:`DEFAULT_TOLERANCE` is 10 frames. Ratios
divide by ``max(1, denominator)`` as CLEAR's do. Host-side NumPy, like the other metrics.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from jaxtrack.metrics.clear import ClearMatching
from jaxtrack.metrics.preprocess import SequenceData

#: Frames a tracker may take to pick up an entering target or release an exiting one.
DEFAULT_TOLERANCE = 10
#: Fields summed when sequences are combined.
ADDITIVE_FIELDS = (
    "OE_frames",
    "SE_frames",
    "num_frames",
    "DE_late_pickups",
    "DE_late_releases",
    "DE_entering",
    "DE_exiting",
)


def cmt_fields(data: SequenceData, matching: ClearMatching, tolerance: int) -> dict:
    """The counts behind OE, DE and SE on one sequence (module docstring).

    Args:
        data: the scored boxes.
        matching: their CLEAR matching (:func:`~jaxtrack.metrics.clear.clear_matching`).
        tolerance: frames allowed to pick up or release a target (>= 0).

    Returns:
        ``OE_frames`` (falsely tracked frames), ``SE_frames`` (frames with a switch),
        ``num_frames``, ``DE_late_pickups``, ``DE_late_releases``, ``DE_entering`` and
        ``DE_exiting`` (ints).

    Raises:
        ValueError: a negative tolerance.
    """
    if tolerance < 0:
        raise ValueError(f"tolerance must be >= 0 frames, got {tolerance}")
    pairs, matched = data.pairs, matching.matched
    num_frames = data.num_frames
    false_frames = (
        (pairs.num_gt > matching.matches)
        | (pairs.num_tracker > matching.matches)
        | (matching.id_switches > 0)
    )
    first, last = _first_and_last(data.gt_id, data.gt_frame, data.num_gt_ids)
    entering = first > 0
    exiting = last < num_frames - 1

    gt_id = data.gt_id[pairs.gt_row[matched]]
    match_frame = pairs.frame[matched]
    first_match = np.full(data.num_gt_ids, np.iinfo(np.int64).max)
    np.minimum.at(first_match, gt_id, match_frame)
    late_pickups = entering & (first_match - first > tolerance)

    order = np.lexsort((match_frame, gt_id))
    is_last = np.ones(order.size, bool)
    is_last[:-1] = gt_id[order][1:] != gt_id[order][:-1]
    last_match = order[is_last]
    released_by = data.tracker_id[pairs.tracker_row[matched]][last_match]
    target = gt_id[last_match]
    late_releases = _false_track_runs(data, matched, released_by, last[target] + 1, tolerance)
    late_releases &= exiting[target]
    return {
        "OE_frames": int(np.sum(false_frames)),
        "SE_frames": int(np.sum(matching.id_switches > 0)),
        "num_frames": int(num_frames),
        "DE_late_pickups": int(np.sum(late_pickups)),
        "DE_late_releases": int(np.sum(late_releases)),
        "DE_entering": int(np.sum(entering)),
        "DE_exiting": int(np.sum(exiting)),
    }


def cmt_scores(fields: dict) -> dict:
    """``OE``, ``DE``, ``SE`` (fractions) and their counts, from the additive fields.

    Args:
        fields: from :func:`cmt_fields`, or their sums over sequences.

    Returns:
        ``OE, DE, SE`` and the fields except ``num_frames``.
    """
    frames = max(1, fields["num_frames"])
    events = max(1, fields["DE_entering"] + fields["DE_exiting"])
    scores = {
        "OE": fields["OE_frames"] / frames,
        "DE": (fields["DE_late_pickups"] + fields["DE_late_releases"]) / events,
        "SE": fields["SE_frames"] / frames,
    }
    scores.update({key: int(fields[key]) for key in ADDITIVE_FIELDS if key != "num_frames"})
    return scores


def crossing_swap_fields(
    switch_frames: np.ndarray,
    switch_gt_ids: np.ndarray,
    crossings: Sequence[tuple[Sequence[int], tuple[int, int]]],
    span: tuple[int, int],
    tolerance: int = DEFAULT_TOLERANCE,
) -> dict:
    """The counts behind ``SE`` on the crossings (module docstring).

    Args:
        switch_frames: 1-based frame of each identity switch (e.g.
            :attr:`~jaxtrack.metrics.switches.SwitchTable.frame`).
        switch_gt_ids: the ground-truth id of each switch's object (``SwitchTable.gt_id``).
        crossings: ``(people's gt ids, (first, last))`` of each scripted crossing, 1-based
            inclusive frames.
        span: the scored frames ``(first, last)``, 1-based inclusive: windows are cut to it.
        tolerance: frames after a crossing's last that its window holds (>= 0).

    Returns:
        ``crossing_frames`` (frames in a window) and ``crossing_swap_frames`` (those with a
        switch of one of the window's people), ints; ``SE_crossings`` is their ratio.

    Raises:
        ValueError: a negative tolerance.
    """
    if tolerance < 0:
        raise ValueError(f"tolerance must be >= 0 frames, got {tolerance}")
    windowed, swapped = set(), set()
    for people, (first, last) in crossings:
        frames = range(max(first, span[0]), min(last + tolerance, span[1]) + 1)
        windowed.update(frames)
        inside = np.isin(switch_gt_ids, list(people)) & np.isin(switch_frames, list(frames))
        swapped.update(int(frame) for frame in switch_frames[inside])
    return {"crossing_frames": len(windowed), "crossing_swap_frames": len(swapped)}


def crossing_swap_rate(fields: dict) -> float:
    """``SE_crossings`` (a fraction) from :func:`crossing_swap_fields` or their sums."""
    return fields["crossing_swap_frames"] / max(1, fields["crossing_frames"])


def _first_and_last(ids: np.ndarray, frames: np.ndarray, num_ids: int):
    """First and last frame index of each identity ``0..num_ids-1``."""
    first = np.full(num_ids, np.iinfo(np.int64).max)
    last = np.full(num_ids, -1)
    np.minimum.at(first, ids, frames)
    np.maximum.at(last, ids, frames)
    return first, last


def _false_track_runs(
    data: SequenceData, matched: np.ndarray, tracks: np.ndarray, starts: np.ndarray, length: int
) -> np.ndarray:
    """Whether each track has an unmatched box in all ``length + 1`` frames from its start.

    Args:
        data: the scored boxes.
        matched: ``[P]`` the matched pairs.
        tracks: ``[n]`` relabelled tracker ids.
        starts: ``[n]`` first frame index of each window.
        length: the tolerance; windows hold ``length + 1`` frames.

    Returns:
        ``[n]`` booleans (False for a window reaching past the span).
    """
    unmatched = np.ones(data.tracker_id.shape[0], bool)
    unmatched[data.pairs.tracker_row[matched]] = False
    # one key per unmatched box: (track, frame), unique since a track has one box per frame
    keys = np.sort(data.tracker_id[unmatched] * data.num_frames + data.tracker_frame[unmatched])
    lower = np.searchsorted(keys, tracks * data.num_frames + starts, side="left")
    upper = np.searchsorted(keys, tracks * data.num_frames + starts + length, side="right")
    inside = starts + length < data.num_frames
    return inside & (upper - lower == length + 1)
