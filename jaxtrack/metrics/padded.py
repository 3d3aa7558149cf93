"""Scoring padded :class:`jaxtrack.types.Tracks` (e.g. a vmapped parameter sweep's output).

The metrics run host-side in NumPy/SciPy: their per-frame optimal assignments (Hungarian
algorithm, with TrackEval's tie-breaking) have no exact JAX equivalent, and the host path is
already several times faster than TrackEval. These helpers turn device outputs into tables
and score a whole batch of them against one ground truth.
"""

from __future__ import annotations

import numpy as np

from jaxtrack.metrics.evaluate import EvalConfig, Evaluation, evaluate_sequence
from jaxtrack.types import MotTable, Tracks


def table_from_tracks(tracks: Tracks, first_frame: int = 1) -> MotTable:
    """One row per occupied slot of an unbatched ``Tracks`` (``[num_frames, max_objects]``).

    Args:
        tracks: the tracker output; index ``t`` of the time axis is frame ``first_frame + t``.
        first_frame: 1-based frame number of index 0.

    Returns:
        The rows in frame order (slot order within a frame), boxes and scores as float64.
    """
    mask = np.asarray(tracks.mask, dtype=bool)
    if mask.ndim != 2:
        raise ValueError(f"expected unbatched Tracks [num_frames, max_objects], got {mask.shape}")
    frame_index, _ = np.nonzero(mask)
    return MotTable.from_arrays(
        frame_index + first_frame,
        np.asarray(tracks.ids)[mask],
        np.asarray(tracks.boxes, dtype=np.float64)[mask],
        np.asarray(tracks.scores, dtype=np.float64)[mask],
    )


def evaluate_tracks(
    gt: MotTable,
    tracks: Tracks,
    first_frame: int = 1,
    config: EvalConfig | None = None,
) -> Evaluation | list[Evaluation]:
    """Scores padded tracker output, unbatched or with one leading batch axis.

    Args:
        gt: ground truth of frames ``first_frame .. first_frame + num_frames - 1`` (cut it to
            that span first).
        tracks: ``Tracks`` with arrays ``[num_frames, max_objects, ...]``, or
            ``[batch, num_frames, max_objects, ...]`` (e.g. one output per swept parameter).
        first_frame: 1-based frame number of time index 0.
        config: evaluation settings.

    Returns:
        An :class:`Evaluation`, or a list of them (one per batch element).
    """
    mask = np.asarray(tracks.mask)
    if mask.ndim == 2:
        frames = (first_frame, first_frame + mask.shape[0] - 1)
        return evaluate_sequence(gt, table_from_tracks(tracks, first_frame), frames, config)
    if mask.ndim != 3:
        raise ValueError(f"expected Tracks with at most one batch axis, got mask {mask.shape}")
    host = Tracks(*(np.asarray(leaf) for leaf in tracks))
    return [
        evaluate_tracks(gt, Tracks(*(leaf[b] for leaf in host)), first_frame, config)
        for b in range(mask.shape[0])
    ]
