"""One Hierarchical tracker's appearance over a run, as the paper's Fig. 4b-c (host side).

From the per-frame outputs of a run (:class:`~jaxtrack.filters.hierarchical.HierarchicalInfo`
``pool`` ``[T, S, M + N]``, ``distances`` ``[T, S, 49]``, ``event_ids`` ``[T, S]`` and the
slots' update counts), stacked over frames as NumPy arrays:

* :func:`tracker_slots`: the slot of one high-level identity on each frame;
* :func:`feature_trace`: Fig. 4c's intra-target curve of one feature: the Bhattacharyya
  distance ``d^i_t = d(m^i_(t-1), p^i_t)`` (Hierarchical eq. 5) on the frames where the
  tracker updated its appearance with the feature in its pool, 1 elsewhere ("when this
  feature is not selected or target cannot be detected, the distance is set to one");
* :func:`state_runs`: the runs of equal event states (Sec. 5.5) of one tracker;
* :func:`pool_figure` (Fig. 4b: the ``M`` current and ``N`` long-run features over frames)
  and :func:`distance_figure` (Fig. 4c).
"""

from __future__ import annotations

from collections.abc import Mapping

import matplotlib.pyplot as plt
import numpy as np


def tracker_slots(event_ids: np.ndarray, identity: int) -> np.ndarray:
    """The high-level slot holding ``identity`` on each frame (-1: none).

    Args:
        event_ids: ``[T, S]`` each slot's identity per frame (-1: free).
        identity: the tracker's identity.
    """
    held = np.asarray(event_ids) == identity
    return np.where(held.any(axis=1), np.argmax(held, axis=1), -1)


def slot_updates(counts: np.ndarray, slots: np.ndarray) -> np.ndarray:
    """``[T]`` whether the tracker updated its appearance on each frame: its slot's update
    count ``n`` (:class:`~jaxtrack.appearance.model.AppearanceModel` ``count``, ``[T, S]``)
    grew since the previous frame, in the same slot."""
    counts, slots = np.asarray(counts), np.asarray(slots)
    frames = np.arange(len(slots))
    now = np.where(slots >= 0, counts[frames, np.clip(slots, 0, None)], 0.0)
    before = np.concatenate([[0.0], now[:-1]])
    same = np.concatenate([[False], slots[1:] == slots[:-1]])
    return (slots >= 0) & (now > np.where(same, before, 0.0))


def feature_trace(
    distances: np.ndarray, pool: np.ndarray, slots: np.ndarray, updated: np.ndarray, feature: int
) -> np.ndarray:
    """Fig. 4c's intra-target distance of ``feature`` on each frame (module docstring).

    Args:
        distances: ``[T, S, 49]`` each slot's distances at its last update.
        pool: ``[T, S, P]`` each slot's pooled features.
        slots: ``[T]`` the tracker's slot per frame (:func:`tracker_slots`).
        updated: ``[T]`` whether it updated on the frame (:func:`slot_updates`).
        feature: the feature index.

    Returns:
        ``[T]`` the distance where updated with ``feature`` pooled, else 1.
    """
    frames = np.arange(len(slots))
    slot = np.clip(slots, 0, None)
    pooled = np.any(np.asarray(pool)[frames, slot] == feature, axis=-1)
    value = np.asarray(distances)[frames, slot, feature]
    return np.where(updated & pooled & (slots >= 0), value, 1.0)


def state_runs(frames: np.ndarray, codes: np.ndarray, names) -> list[tuple[int, int, str]]:
    """Runs of equal event states: ``(first frame, last frame, name)``, in frame order.

    Args:
        frames: ``[n]`` increasing frame numbers of the tracker's rows.
        codes: ``[n]`` its event code on each.
        names: code -> name (:data:`~jaxtrack.filters.hier_events.EVENT_NAMES`).
    """
    frames, codes = np.asarray(frames), np.asarray(codes)
    if not frames.size:
        return []
    cut = np.flatnonzero((np.diff(codes) != 0) | (np.diff(frames) != 1)) + 1
    starts = np.concatenate([[0], cut])
    ends = np.concatenate([cut - 1, [len(frames) - 1]])
    return [
        (int(frames[a]), int(frames[b]), names[int(codes[a])])
        for a, b in zip(starts, ends, strict=True)
    ]


def pool_figure(frames: np.ndarray, pool: np.ndarray, num_current: int, span, title: str):
    """Fig. 4b: the pooled features of one tracker over frames.

    Args:
        frames: ``[T]`` frame numbers.
        pool: ``[T, M + N]`` the tracker's pool per frame (-1: no tracker or no pool).
        num_current: ``M``: the first ``M`` columns are the current best, the rest long-run.
        span: ``(first, last)`` frames of the event, shaded.
        title: the axes' title.

    Returns:
        The figure.
    """
    fig, ax = plt.subplots(figsize=(9, 4))
    ax.axvspan(span[0], span[1], color="0.85", label="scripted event")
    for columns, marker, label in (
        (slice(0, num_current), "s", f"M = {num_current} current best"),
        (slice(num_current, None), "x", f"N = {pool.shape[1] - num_current} long-run"),
    ):
        part = pool[:, columns]
        t, k = np.nonzero(part >= 0)
        ax.scatter(frames[t], part[t, k], marker=marker, s=6, lw=0.8, label=label)
    ax.set(xlabel="frame", ylabel="feature index", ylim=(-1, 49), title=title)
    ax.legend(loc="upper right", fontsize=8)
    return fig


def distance_figure(
    frames: np.ndarray,
    intra: np.ndarray,
    inter: Mapping[str, tuple[np.ndarray, np.ndarray]],
    span,
    title: str,
):
    """Fig. 4c: one feature's intra-target distance over frames (:func:`feature_trace`) and
    the inter-tracker distances of the same feature (squares).

    Args:
        frames: ``[T]`` frame numbers.
        intra: ``[T]`` the intra-target distance (1: not selected or not updated).
        inter: label -> ``(frames, distances)`` between this tracker's model and another's.
        span: ``(first, last)`` frames of the event, shaded.
        title: the axes' title.

    Returns:
        The figure.
    """
    fig, ax = plt.subplots(figsize=(9, 3.5))
    ax.axvspan(span[0], span[1], color="0.85", label="scripted event")
    ax.plot(frames, intra, lw=1, label="intra-target d(m_(t-1), p_t)")
    for label, (at, values) in inter.items():
        ax.plot(at, values, "s", ms=3, label=label)
    ax.set(xlabel="frame", ylabel="Bhattacharyya distance", ylim=(0, 1.05), title=title)
    ax.legend(loc="lower left", fontsize=8)
    return fig
