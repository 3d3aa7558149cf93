"""Learning a sequence's scene zones: what ``jaxtrack learn-zones`` does, as library code.

:func:`learn_sequence_zones` takes the trajectories of a training span (the ground truth, or
the tracks of the default tracker run with uniform intensities, as ``learn-context`` runs
it) and learns their entry/exit zones and activity mask
(:func:`jaxtrack.context.zones.learn_zones`, Fusion Sec. 2.3).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from jaxtrack.context.zones import MARGIN_FRAMES, LearnedZones, SceneZones, learn_zones
from jaxtrack.errors import InputError
from jaxtrack.io.motchallenge import MotSequence
from jaxtrack.io.zones import load_zones
from jaxtrack.pipelines.context import training_span, uniform_tracker_rows
from jaxtrack.types import MotTable

#: The trajectory sources.
SOURCES = ("gt", "tracks")


def training_trajectories(sequence: MotSequence, source: str, seed: int = 0) -> MotTable:
    """The trajectories of a loaded span: its ground truth or a tracker run's output.

    Args:
        sequence: the loaded training span.
        source: ``"gt"`` (rows with ``conf == 0`` left out) or ``"tracks"`` (the default
            PHD tracker with uniform intensities, :func:`~jaxtrack.pipelines.context.
            uniform_tracker_rows`).
        seed: PRNG seed of the tracker run.

    Returns:
        The rows.

    Raises:
        InputError: an unknown source, or ``"gt"`` for a sequence without ground truth.
    """
    if source not in SOURCES:
        raise InputError(f"trajectory source must be one of {', '.join(SOURCES)}, got {source!r}")
    if source == "tracks":
        return uniform_tracker_rows(sequence, seed)
    if sequence.gt_table is None:
        raise InputError(f"{sequence.path}: no ground truth (gt/gt.txt); use --from tracks")
    return sequence.gt_table.select(~sequence.gt_table.ignored)


def learn_sequence_zones(
    sequence: MotSequence | str | Path,
    frames: tuple[int, int] | str | None = None,
    *,
    source: str = "tracks",
    seed: int = 0,
    margin_frames: int = MARGIN_FRAMES,
    progress: Callable[[str], None] | None = None,
) -> LearnedZones:
    """Entry/exit zones and activity mask of a sequence's training span.

    Args:
        sequence: a sequence folder (loaded with ``frames``) or a loaded
            :class:`~jaxtrack.io.MotSequence` (its own span is used; ``frames`` must be None).
        frames: the training span ``(first, last)`` or ``"A:B"``; default: all frames.
        source: ``"gt"`` or ``"tracks"`` (:func:`training_trajectories`).
        seed: seeds the tracker run.
        margin_frames: trajectories starting (ending) in the span's first (last) frames give
            no start (end) point (:func:`~jaxtrack.context.zones.trajectory_endpoints`).
        progress: called with a short description before each long step.

    Returns:
        The :class:`~jaxtrack.context.zones.LearnedZones`.

    Raises:
        InputError: a bad span or source, or no trajectory starting or ending in the span.
    """
    notify = progress or (lambda _: None)
    sequence = training_span(sequence, frames, notify)
    span = (sequence.first_frame, sequence.last_frame)
    if source == "tracks":
        notify(f"tracking frames {span[0]}:{span[1]} with uniform intensities")
    rows = training_trajectories(sequence, source, seed)
    notify("learning zones")
    info = sequence.info
    return learn_zones(
        rows.frames,
        rows.ids,
        rows.boxes,
        span,
        info.im_width,
        info.im_height,
        margin_frames=margin_frames,
    )


def tracker_zones(
    sequence: MotSequence, zones_path: str | Path | None = None, seed: int = 0
) -> tuple[SceneZones | None, str]:
    """The entry/exit zones a tracker uses on a loaded sequence (``--zones``), and what they
    are, in words (for the user and the run's ``.config.json``).

    With ``zones_path`` the zones file (``jaxtrack learn-zones``); else the zones learned on
    the fly from the tracked span itself, from the trajectories of the PHD tracker with
    uniform intensities on its detections (no ground truth is read); when that span gives no
    zone (no trajectory starts or ends inside it), no zones (the tracker then samples no
    exits).

    Raises:
        FileFormatError: a bad zones file.
    """
    if zones_path is not None:
        return load_zones(zones_path), f"zones from {zones_path}"
    span = f"{sequence.first_frame}:{sequence.last_frame}"
    try:
        learned = learn_sequence_zones(sequence, source="tracks", seed=seed)
    except InputError as err:
        return None, f"no zones (learning them from the tracks of frames {span} failed: {err})"
    count = len(learned.scene.boxes)
    return learned.scene, (
        f"{count} zone(s) learned on the fly from the PHD tracks of frames {span} "
        "(give --zones to use others)"
    )
