"""Running a tracker over sequences: what ``jaxtrack track`` does, as library code.

:func:`track_sequences` runs any registered tracker (:mod:`jaxtrack.filters.registry`) on
several sequences with few compiles: the tracker's filter is cached on its configuration's
static setting and each sequence runs in chunks of a fixed number of frames
(:func:`~jaxtrack.filters.base.run` with ``chunk_frames`` and ``fit_capacity``), each chunk
at a detection capacity from the sequence's own counts (a power of two; crowded frames in
chunks of their own), so a compiled chunk is reused across frames, sequences and calls of
the same capacity, and **a sequence's result does not depend on the other sequences tracked
with it** (each gets the same key, ``PRNGKey(seed)``, and its own capacities).

Output (the configuration's ``output``): ``"offline"`` keeps every confirmed track over its
whole life, the frames before its confirmation included, and fills gaps of up to ``max_gap``
frames by linear interpolation (:func:`~jaxtrack.association.offline.finalise_tracks`);
``"online"`` writes what the filter outputs frame by frame.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Sequence
from typing import Any, NamedTuple

import jax
import numpy as np
from tqdm import tqdm

from jaxtrack.association.estimates import Estimates
from jaxtrack.association.offline import finalise_tracks, gap_breaks, track_rows
from jaxtrack.association.retrodiction import RETRODICTION_IOU, detection_rows, retrodict
from jaxtrack.association.smoothing import smooth_tracks
from jaxtrack.configs import TrackerConfig
from jaxtrack.context.io import load_context_parts
from jaxtrack.errors import InputError, InputWarning
from jaxtrack.filters.base import Filter, fit_detections, plan_chunks, run
from jaxtrack.filters.kalman_tracker import KalmanConfig, kalman_description
from jaxtrack.filters.phd_defaults import DEFAULT_MEASUREMENT_NOISE_STD, DEFAULT_MOTION_NOISE_STD
from jaxtrack.filters.phd_tracker import Context
from jaxtrack.filters.registry import build_tracker, tracker_entry
from jaxtrack.io import MotSequence
from jaxtrack.io.frame_stream import stream_bytes
from jaxtrack.resources import check_memory
from jaxtrack.types import Detections, MotTable, Tracks

#: Default number of previous frames in a track's trail (:func:`phd_frame_snapshot`).
DEFAULT_TRAIL = 30
#: :func:`~jaxtrack.filters.base.run` compiled once per filter and shapes.
_run = jax.jit(run, static_argnums=0)


def track_sequences(
    sequences: Sequence[MotSequence],
    config: TrackerConfig,
    seed: int = 0,
    params: Sequence[Any] | None = None,
    progress: bool = False,
    chunk_frames: int = 128,
) -> list[MotTable]:
    """Tracks several sequences (or spans) with one compiled run.

    Args:
        sequences: the loaded sequences.
        config: the tracker's configuration (its type selects the tracker).
        seed: PRNG seed (the same key for every sequence, so a sequence gives the same
            result alone and in company).
        params: one parameter PyTree per sequence (default: the registry's, e.g. uniform
            intensities for the PHD tracker). Parameters of different PyTree shapes (e.g.
            contexts with different numbers of components) compile once per shape.
        progress: show a progress bar over the sequences.
        chunk_frames: frames per compiled call.

    Returns:
        The result rows of each sequence. A sequence with detections but no result rows
        raises an :class:`~jaxtrack.errors.InputWarning` (a one-line warning in the CLI): the
        run is legal but its empty result is most likely not what was meant.

    Raises:
        InputError: a configuration of no registered tracker, or of one that uses frames
            (:func:`jaxtrack.pipelines.stream.track_streamed` runs those).
        ResourceError: a sequence's run would need more memory than the machine has
            (:func:`check_tracking_memory`), before anything runs.
    """
    if tracker_entry(config.tracker).uses_frames:
        raise InputError(
            f"the {config.tracker} tracker uses frames: run it with "
            "jaxtrack.pipelines.stream.track_streamed"
        )
    check_tracking_memory(sequences, config, chunk_frames)
    # The filter is the same for every sequence; default params are built only when needed.
    built = [
        build_tracker(config, seq.info) for seq in (sequences if params is None else sequences[:1])
    ]
    filt = built[0][0]
    if params is None:
        params = [seq_params for _, seq_params in built]
    key = jax.random.PRNGKey(seed)
    results = []
    items = zip(sequences, params, strict=True)
    for seq, seq_params in tqdm(
        items, total=len(sequences), desc="tracking", unit="seq", disable=not progress
    ):
        warn_if_scores_ignored(seq, seq_params, config)
        _, info = run(
            filt,
            key,
            seq_params,
            seq.detections,
            chunk_frames=chunk_frames,
            fit_capacity=True,
            frame_output=track_outputs,
        )
        rows = output_rows(info, config, seq.first_frame, seq.detections)
        warn_if_no_tracks(seq, rows, config)
        results.append(rows)
    return results


#: Share of a sequence's detections below a tracker's ``min_score`` from which
#: :func:`warn_if_scores_ignored` warns.
IGNORED_SHARE = 0.5


def warn_if_scores_ignored(seq: MotSequence, params: Any, config: TrackerConfig) -> None:
    """Warns (:class:`~jaxtrack.errors.InputWarning`) when a tracker with a score threshold
    (a ``min_score`` parameter: the Kalman tracker's default preset, 0.9, chosen on MOT15's
    detector) ignores at least :data:`IGNORED_SHARE` of a sequence's detections: a detector
    whose scores live on another scale (e.g. 0.5-0.9) is then mostly dropped, silently."""
    threshold = getattr(params, "min_score", None)
    scores = np.asarray(seq.det_table.confs)
    if threshold is None or np.ndim(threshold) != 0 or scores.size == 0:
        return
    ignored = int(np.sum(scores < float(threshold)))
    if ignored >= IGNORED_SHARE * scores.size:
        warnings.warn(
            InputWarning(
                f"{seq.info.name}: {ignored} of {scores.size} detections "
                f"({100 * ignored / scores.size:.0f} %) score below the {config.tracker} "
                f"tracker's min_score {float(threshold):g} and are ignored (median score "
                f"{float(np.median(scores)):.3g}){_score_remedy(config)}"
            ),
            stacklevel=3,
        )


def _score_remedy(config: TrackerConfig) -> str:
    """How a user of ``config`` keeps the detections :func:`warn_if_scores_ignored` names."""
    if hasattr(config, "min_score"):
        return "; if that is not meant, lower min_score with --config"
    if isinstance(config, KalmanConfig):
        return "; if that is not meant, the 'sort' preset takes every detection (--preset sort)"
    return ""


def warn_if_no_tracks(seq: MotSequence, rows: MotTable, config: TrackerConfig) -> None:
    """Warns (:class:`~jaxtrack.errors.InputWarning`) when a sequence with detections gave no
    result rows: the run is legal but its empty result is most likely not what was meant."""
    if len(rows) == 0 and len(seq.det_table) > 0:
        warnings.warn(
            InputWarning(
                f"{seq.info.name}: {len(seq.det_table)} detections in frames "
                f"{seq.first_frame}..{seq.last_frame} gave no tracks (the {config.tracker} "
                "tracker confirmed none: check the boxes against the image size and "
                "frame rate, or the configuration)"
            ),
            stacklevel=3,
        )


def warn_if_overflow(seq: MotSequence, overflow: Any, config: TrackerConfig) -> None:
    """Warns (:class:`~jaxtrack.errors.InputWarning`) when a tracker's tables were full on
    some frames (per-frame ``overflow`` flags, any leading batch axes): a detection then
    started no track (or no tracker), and its target is missing from the result. Names the
    frames and the configuration's slot settings to raise.

    Args:
        seq: the tracked sequence (name; first frame of the flags).
        overflow: per-frame flags ``[..., frames]``, or None (a tracker without them).
        config: the tracker's configuration.
    """
    if overflow is None:
        return
    flags = np.asarray(overflow, bool)
    full = np.nonzero(flags.reshape(-1, flags.shape[-1]).any(axis=0))[0] if flags.ndim else []
    if len(full) == 0:
        return
    slots = {
        field.name: getattr(config, field.name)
        for field in dataclasses.fields(config)
        if field.name.startswith("max_") and field.name != "max_gap"
    }
    now = ", ".join(f"{name}={value}" for name, value in slots.items())
    example = ", ".join(f'"{name}": {2 * value}' for name, value in slots.items())
    first = seq.first_frame + int(full[0])
    warnings.warn(
        InputWarning(
            f"{seq.info.name}: on {len(full)} frame(s) (first: frame {first}) "
            f"the {config.tracker} tracker's tables were full and a new track was not "
            f"started ({now}); raise them with --config, e.g. {{{example}}}"
        ),
        stacklevel=3,
    )


def check_tracking_memory(
    sequences: Sequence[MotSequence],
    config: TrackerConfig,
    chunk_frames: int = 128,
    configurations: int = 1,
) -> None:
    """Refuses, before any work, a run whose estimated peak memory the machine lacks.

    For each sequence, the tracker's estimate (the registry's ``memory``, no compile) at the
    largest chunk capacity :func:`~jaxtrack.filters.base.plan_chunks` gives it, over its
    frames, times ``configurations`` run at once (a sweep's group), plus, for a tracker that
    uses frames, the images its stream holds (:func:`~jaxtrack.io.frame_stream.stream_bytes`
    at the ``seqinfo.ini`` size, shared by the configurations), is compared with
    :func:`~jaxtrack.resources.available_memory_bytes`.

    Raises:
        ResourceError: naming the sequence, the bytes needed and available, and the options
            that lower them.
    """
    entry = tracker_entry(config.tracker)
    for seq in sequences:
        counts = np.asarray(seq.detections.mask).sum(axis=1)
        capacity = max(chunk.capacity for chunk in plan_chunks(counts, chunk_frames))
        images = (
            stream_bytes(seq.info.im_height, seq.info.im_width, chunk_frames)
            if entry.uses_frames
            else 0
        )
        run_bytes = entry.memory(config, capacity, chunk_frames).run_bytes(seq.num_frames)
        check_memory(
            configurations * run_bytes + images,
            f"tracking {seq.info.name} ({seq.num_frames} frames, up to {capacity} detection "
            f"slots) with the {config.tracker} tracker"
            + (f", {configurations} configurations at once" if configurations > 1 else ""),
            "--config num_particles or births_per_detection, or a shorter --frames span",
        )


class TrackOutputs(NamedTuple):
    """What :func:`track_sequences` keeps of each frame's info: the tracks and candidates,
    and for a tracker whose info has one, the frame's ``overflow`` flag (a new track or
    component found its table full; :func:`warn_if_overflow`), else None."""

    tracks: Tracks
    candidates: Tracks
    overflow: Any = None


def track_outputs(state: Any, info: Any, index: Any) -> TrackOutputs:
    """The per-frame output of a tracking run (``frame_output`` of
    :func:`~jaxtrack.filters.base.run`): only what :func:`output_rows` reads."""
    del state, index
    return TrackOutputs(info.tracks, info.candidates, getattr(info, "overflow", None))


def load_tracker_context(path: str | None) -> Context | None:
    """The learned context in the file at ``path`` (``jaxtrack learn-context``), or None.

    Raises:
        FileFormatError: a missing or malformed context file.
    """
    return None if path is None else Context(*load_context_parts(path))


def output_rows(
    info: Any, config: TrackerConfig, first_frame: int, detections: Detections | None = None
) -> MotTable:
    """The result rows of a run's per-frame infos, as the configuration's ``output`` says.

    A configuration with a ``retrodiction`` (:class:`~jaxtrack.filters.phd_tracker.PHDConfig`)
    extends the offline output backwards onto ``detections``, the padded detections the
    tracker was given (:func:`~jaxtrack.association.retrodiction.retrodict`; None: not
    extended). One with ``smoothing="rts"`` then smooths every track's boxes
    (:func:`~jaxtrack.association.smoothing.smooth_tracks`) under :func:`smoothing_noise`.
    """
    if config.output == "online":
        return track_rows(info.tracks, first_frame)
    unfilled = getattr(info, "unfilled", None)
    rows = finalise_tracks(
        info.tracks,
        info.candidates,
        config.max_gap,
        first_frame,
        trim=config.trims_tails,
        chain_iou=getattr(config, "chain_iou", 0.0),
        breaks=None if unfilled is None else gap_breaks(unfilled, info.event_ids, first_frame),
    )
    frames = getattr(config, "retrodiction", 0)
    if frames and detections is not None:
        min_iou = getattr(config, "retrodiction_iou", RETRODICTION_IOU)
        rows = retrodict(
            rows, detection_rows(detections, first_frame), first_frame, frames, min_iou
        )
    if getattr(config, "smoothing", "none") == "rts":
        rows = smooth_tracks(rows, *smoothing_noise(config))
    return rows


def smoothing_noise(source: Any, index: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The ``(motion_noise_std, measurement_noise_std)`` the offline output's smoothing
    (:func:`~jaxtrack.association.smoothing.smooth_tracks`) runs under: the configuration's
    or parameters' own (configuration ``index`` of batched parameters), or the PHD tracker's
    defaults for a tracker without them (Kalman, CMT, hierarchical, fusion)."""
    if not hasattr(source, "motion_noise_std"):
        return np.asarray(DEFAULT_MOTION_NOISE_STD), np.asarray(DEFAULT_MEASUREMENT_NOISE_STD)
    motion, measurement = (
        np.asarray(source.motion_noise_std),
        np.asarray(source.measurement_noise_std),
    )
    if index is not None:
        motion, measurement = motion[index], measurement[index]
    return motion, measurement


def tracker_description(config: TrackerConfig) -> dict[str, Any]:
    """What a run used, for the ``.config.json`` beside the results.

    ``{"tracker": NAME, **config}``; for the Kalman tracker also its preset's assignment cost
    and parameters.
    """
    described = {"tracker": config.tracker, **config.to_dict()}
    if isinstance(config, KalmanConfig):
        described.update(kalman_description(config))
    return described


class FrameSnapshot(NamedTuple):
    """A PHD tracker on one frame of a run (for :func:`jaxtrack.plot.tracks.phd_frame_figure`).

    Attributes:
        particles: the particle cloud after the frame's update and resampling.
        log_weights: their log-weights.
        mass: the PHD mass.
        estimates: the frame's extracted states.
        tracks: the tracks of the trail's frames, the last row being the frame.
        frame_index: 0-based index of the frame in the run.
    """

    particles: np.ndarray
    log_weights: np.ndarray
    mass: float
    estimates: Estimates
    tracks: Tracks
    frame_index: int


def phd_frame_snapshot(
    filt: Filter,
    key: jax.Array,
    params: Any,
    detections: Detections,
    frame_index: int,
    trail: int = DEFAULT_TRAIL,
) -> FrameSnapshot:
    """Runs a PHD tracker up to a frame and returns its state there (PHD-context Fig. 3).

    The tracker runs (:func:`~jaxtrack.filters.base.run`) over the detections of frames
    ``0..frame_index`` (the padded arrays sliced along time); its final state is the particle
    cloud after that frame's update and resampling. The per-frame keys of ``run`` do not
    depend on the number of frames (``jax.random.split`` is prefix-stable with the default
    partitionable Threefry), and the detections are first brought to the capacity
    :func:`track_sequences` gives the sequence (:func:`~jaxtrack.filters.base.fit_detections`),
    so the snapshot shows the run ``jaxtrack track`` makes with the same key (unless the
    sequence has crowded frames, which the tracker runs at a capacity of their own).

    Args:
        filt: a PHD tracker (:func:`~jaxtrack.filters.phd.phd_filter`), whose infos carry
            ``estimates`` and ``tracks``.
        key: the run's PRNG key.
        params: the tracker's parameters.
        detections: padded detections ``[num_frames, max_detections]``.
        frame_index: 0-based index of the frame in ``detections``.
        trail: previous frames of the tracks kept (0: none).

    Raises:
        ValueError: ``frame_index`` outside the detections' frames, or a negative ``trail``.
    """
    num_frames = int(np.shape(detections.mask)[0])
    if not 0 <= frame_index < num_frames:
        raise ValueError(
            f"frame_index {frame_index} is outside 0..{num_frames - 1}: the detections hold "
            f"{num_frames} frames"
        )
    if trail < 0:
        raise ValueError(f"trail must be >= 0, got {trail}")
    sliced = jax.tree.map(lambda x: x[: frame_index + 1], fit_detections(detections))
    state, infos = _run(filt, key, params, sliced)
    return FrameSnapshot(
        particles=np.asarray(state.particles),
        log_weights=np.asarray(state.log_weights),
        mass=float(state.mass),
        estimates=jax.tree.map(lambda x: np.asarray(x[frame_index]), infos.estimates),
        tracks=jax.tree.map(
            lambda x: np.asarray(x[max(0, frame_index - trail) : frame_index + 1]), infos.tracks
        ),
        frame_index=frame_index,
    )
