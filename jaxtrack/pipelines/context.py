"""Learning a sequence's context: what ``jaxtrack learn-context`` does, as library code.

:func:`learn_context` collects birth and clutter events from a training span (a UM tracker
run, the ground truth or a labels file; :mod:`jaxtrack.context.samples`) and learns their
intensities by recursive MAP-EM (:mod:`jaxtrack.context.learn`, PHD-context Sec. IV), and
on request the first frame's intensity from the states of the birth source's trajectories
(where the targets are; not in the paper).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import jax
import numpy as np

from jaxtrack.context.clutter_labels import load_clutter_labels
from jaxtrack.context.heldout import (
    BIRTH_BACKGROUND_GRID,
    BIRTH_CANDIDATES,
    CLUTTER_BACKGROUND_GRID,
    CLUTTER_CANDIDATES,
    candidate_learner,
    combine,
    select_density,
)
from jaxtrack.context.learn import (
    BIRTH_EPOCHS,
    CLUTTER_EPOCHS,
    LearnedContext,
    birth_grid,
    clutter_grid,
    learn_density,
    live_components,
    uniform_volumes,
    volume_mass,
)
from jaxtrack.context.map_em import MixtureState, to_intensity
from jaxtrack.context.samples import (
    OCCUPANCY_STRIDE,
    WARMUP_FRAMES,
    EventSamples,
    birth_samples_from_gt,
    birth_samples_from_tracks,
    clutter_samples_from_gt,
    clutter_samples_from_labels,
    clutter_samples_from_tracks,
    matched_detections,
    occupancy_samples_from,
)
from jaxtrack.context.scores import ScoreCalibration, learn_score_calibration
from jaxtrack.context.target_clutter import (
    METADATA_KEY,
    TargetClutterFit,
    chance_events,
    learn_target_clutter,
)
from jaxtrack.errors import InputError
from jaxtrack.filters.phd_tracker import PHDConfig, phd_params, with_score_calibration
from jaxtrack.io.motchallenge import MotSequence, load_sequence
from jaxtrack.pipelines.tracking import track_sequences

#: ``fold_in`` data of the first-frame intensity's key (the birth and clutter keys are the
#: two halves of ``PRNGKey(seed)``, as before that intensity was learned).
INITIAL_KEY = 3


def uniform_tracker_rows(
    sequence: MotSequence,
    seed: int = 0,
    config: PHDConfig | None = None,
    calibration: ScoreCalibration | None = None,
):
    """Trajectories of the PHD tracker with uniform (UM) intensities on a sequence's span.

    The tracker configuration (default :class:`PHDConfig`) with uniform intensities and no
    gap filling, run as ``jaxtrack track`` runs it (sharing its compile). Each confirmed
    track is kept from its first estimate on
    (:func:`~jaxtrack.association.offline.finalise_tracks`), so that its first state is
    where the target was first picked up, not where a high-scoring detection confirmed it.
    The configuration's ``retrodiction`` and ``smoothing`` are not applied (output rules; the
    context learned does not depend on them): on the development bank scenes, births from
    retrodicted tracks scored no better (README, "Retrodiction").

    Args:
        sequence: the loaded training span.
        seed: PRNG seed of the run.
        config: the tracker's configuration (its ``max_gap``, ``retrodiction`` and
            ``smoothing`` are ignored: gaps stay open, tracks start at their first estimate).
        calibration: the detector's score calibration (read by the ``"evidence"``
            confirmation; None: scores read as probabilities).

    Returns:
        The rows (:class:`~jaxtrack.types.MotTable`).
    """
    config = (config or PHDConfig()).replace(max_gap=0, retrodiction=0, smoothing="none")
    params = with_score_calibration(phd_params(config, sequence.info), calibration)
    (rows,) = track_sequences([sequence], config, seed, [params])
    return rows


def training_span(
    sequence: MotSequence | str | Path,
    frames: tuple[int, int] | str | None,
    notify: Callable[[str], None],
) -> MotSequence:
    """A loaded sequence as given, or a sequence folder loaded over ``frames``.

    Raises:
        InputError: ``frames`` given with an already loaded sequence (its own span is used).
    """
    if isinstance(sequence, MotSequence):
        if frames is not None:
            raise InputError("give frames only with a sequence folder, not a loaded sequence")
        return sequence
    notify("loading sequence")
    return load_sequence(sequence, frames=frames)


def learn_context(
    sequence: MotSequence | str | Path,
    frames: tuple[int, int] | str | None = None,
    *,
    birth_from: str = "tracks",
    clutter_from: str | Path = "gt",
    seed: int = 0,
    birth_epochs: int = BIRTH_EPOCHS,
    clutter_epochs: int = CLUTTER_EPOCHS,
    warmup_frames: int = WARMUP_FRAMES,
    tracker_config: PHDConfig | None = None,
    heldout: bool = True,
    first_frame: bool = False,
    progress: Callable[[str], None] | None = None,
) -> LearnedContext:
    """Learns the birth and clutter intensities of a sequence's training span.

    Args:
        sequence: a sequence folder (loaded with ``frames``) or a loaded
            :class:`~jaxtrack.io.MotSequence` (its own span is used; ``frames`` must be None).
        frames: the training span ``(first, last)`` or ``"A:B"``; default: all frames.
        birth_from: ``"tracks"`` (a UM tracker run, the paper's source) or ``"gt"``.
        clutter_from: ``"gt"``, ``"tracks"``, or the path of a clutter labels file
            (:mod:`jaxtrack.context.clutter_labels`).
        seed: seeds the tracker run and the order in which samples are learned.
        birth_epochs: passes over the birth events.
        clutter_epochs: passes over the clutter events.
        warmup_frames: trajectories starting in the span's first frames are not births
            (:func:`~jaxtrack.context.samples.birth_samples`).
        tracker_config: configuration of the UM tracker run (default :class:`PHDConfig`).
        heldout: select each density's learner setting (from :data:`BIRTH_CANDIDATES` /
            :data:`CLUTTER_CANDIDATES`, ``birth_epochs`` and ``clutter_epochs`` then being
            ignored) and its uniform share by held-out likelihood
            (:mod:`jaxtrack.context.heldout`); False: the paper's recursion alone, with the
            given passes (its ``pi_u`` ends near the floor).
        first_frame: also learn the first frame's intensity (``LearnedContext.initial``,
            where the targets are: from the birth source's trajectories, with the births'
            learner, grid and held-out check; README "The targets in view at the first
            frame": on held-out scenes it changed nothing on average, so it is not learned
            by default).
        progress: called with a short description before each long step.

    Returns:
        The :class:`LearnedContext`.

    Raises:
        InputError: an unknown source, ground truth asked for but missing, a span too short
            for the warm-up, no birth or clutter events, or a bad span or labels file.
    """
    notify = progress or (lambda _: None)
    if birth_from not in ("tracks", "gt"):
        raise InputError(f"birth source must be 'tracks' or 'gt', got {birth_from!r}")
    sequence = training_span(sequence, frames, notify)
    span = (sequence.first_frame, sequence.last_frame)
    labels_path = None if str(clutter_from) in ("gt", "tracks") else Path(clutter_from)
    uses_gt = birth_from == "gt" or str(clutter_from) == "gt"
    if uses_gt and sequence.gt_table is None:
        raise InputError(
            f"{sequence.path}: no ground truth (gt/gt.txt) but it was asked for as a source; "
            "use --birth-from tracks and --clutter-from tracks or a labels file"
        )
    if warmup_frames >= sequence.num_frames:
        raise InputError(
            f"training span {span[0]}:{span[1]} has {sequence.num_frames} frames, not more "
            f"than the {warmup_frames} warm-up frames"
        )

    clutter = None
    if labels_path is not None:  # read before the tracker runs: fail early on a bad file
        clutter = clutter_samples_from_labels(
            load_clutter_labels(labels_path), span, str(labels_path)
        )
        if clutter.num_frames == 0:
            raise InputError(
                f"{labels_path}: no labelled frame inside the span {span[0]}:{span[1]}"
            )

    calibration, calibration_summary = None, {"learned": False, "source": None}
    if uses_gt:
        notify("calibrating the detector's scores on the ground truth")
        targets = matched_detections(sequence.det_table, sequence.gt_table, span)
        calibration, calibration_summary = learn_score_calibration(
            sequence.det_table.confs, targets
        )
        calibration_summary["source"] = "gt"

    rows = None
    if birth_from == "tracks" or str(clutter_from) == "tracks":
        notify(f"tracking frames {span[0]}:{span[1]} with uniform intensities")
        rows = uniform_tracker_rows(sequence, seed, tracker_config, calibration)

    notify("collecting events")
    if birth_from == "gt":
        births = birth_samples_from_gt(sequence.gt_table, span, warmup_frames=warmup_frames)
    else:
        births = birth_samples_from_tracks(rows, span, warmup_frames=warmup_frames)
    if str(clutter_from) == "gt":
        clutter = clutter_samples_from_gt(sequence.det_table, sequence.gt_table, span)
    elif str(clutter_from) == "tracks":
        clutter = clutter_samples_from_tracks(sequence.det_table, rows, span)
    target_clutter = _target_clutter(sequence, rows, str(clutter_from), clutter)
    for name, events in (("birth", births), ("clutter", clutter)):
        if events.count == 0:
            left_out = (
                f" ({events.object_overlaps} detections overlapping objects left out)"
                if events.object_overlaps
                else ""
            )
            raise InputError(
                f"no {name} events from {events.source} in frames {span[0]}:{span[1]}"
                f"{left_out}; use a longer training span or another source"
            )

    uniform_birth, uniform_clutter = uniform_volumes(
        sequence.info.im_width, sequence.info.im_height, sequence.info.frame_rate
    )
    key_birth, key_clutter = jax.random.split(jax.random.PRNGKey(seed))
    clutter_size = _mean_size(clutter.values[:, 2:4])
    birth_state, birth_snapshots, birth_check = _learn_in_birth_space(
        "birth", births, uniform_birth, birth_epochs, heldout, key_birth, notify
    )
    clutter_state, clutter_snapshots, clutter_check = _learn(
        "clutter",
        clutter_grid(uniform_clutter, clutter_size),
        clutter_grid(uniform_clutter, clutter_size, CLUTTER_BACKGROUND_GRID),
        clutter,
        clutter_epochs,
        CLUTTER_CANDIDATES if heldout else None,
        key_clutter,
        notify,
    )
    key_birth_mass, key_clutter_mass = jax.random.split(jax.random.fold_in(key_birth, 1))
    birth_mass = volume_mass(to_intensity(birth_state, 1.0), key_birth_mass)
    clutter_mass = volume_mass(to_intensity(clutter_state, 1.0), key_clutter_mass)
    birth = live_components(to_intensity(birth_state, births.magnitude / birth_mass))
    clutter_intensity = live_components(
        to_intensity(clutter_state, clutter.magnitude / clutter_mass)
    )
    metadata = {
        "sequence": str(sequence.path),
        "sequence_name": sequence.info.name,
        "frames": list(span),
        "seed": seed,
        "birth": _summary(births, birth_state, birth_check, birth_mass),
        "clutter": _summary(clutter, clutter_state, clutter_check, clutter_mass),
        "warmup_frames": warmup_frames,
        METADATA_KEY: target_clutter.as_dict(),
        "score_calibration": calibration_summary
        | (
            {}
            if calibration is None
            else {
                "scores": np.asarray(calibration.scores).tolist(),
                "probabilities": np.asarray(calibration.probabilities).tolist(),
            }
        ),
    }
    initial, occupancy = None, None
    if first_frame:
        trajectories = sequence.gt_table if birth_from == "gt" else rows
        occupancy = occupancy_samples_from(trajectories, span, birth_from)
        initial, metadata["initial"] = _learn_first_frame(
            occupancy, uniform_birth, birth_epochs, heldout, seed, notify
        )
    return LearnedContext(
        birth=birth,
        clutter=clutter_intensity,
        metadata=metadata,
        birth_samples=births,
        clutter_samples=clutter,
        birth_snapshots=birth_snapshots,
        clutter_snapshots=clutter_snapshots,
        initial=initial,
        initial_samples=occupancy,
    )


def _learn_first_frame(occupancy, uniform_birth, epochs, heldout, seed, notify):
    """The first frame's intensity and its metadata, learned like the births from the
    occupancy events, with its own key (``fold_in(PRNGKey(seed), INITIAL_KEY)``) so that the
    birth and clutter densities are those learned without it."""
    key, key_mass = jax.random.split(jax.random.fold_in(jax.random.PRNGKey(seed), INITIAL_KEY))
    state, _, check = _learn_in_birth_space(
        "first-frame", occupancy, uniform_birth, epochs, heldout, key, notify
    )
    mass = volume_mass(to_intensity(state, 1.0), key_mass)
    intensity = live_components(to_intensity(state, occupancy.magnitude / mass))
    return intensity, _summary(occupancy, state, check, mass) | {"stride": OCCUPANCY_STRIDE}


def _target_clutter(sequence: MotSequence, rows, clutter_from: str, clutter: EventSamples):
    """What the targets generate besides their own detections
    (:mod:`jaxtrack.context.target_clutter`), from the detections the clutter events left
    out beside objects (``clutter.left_out``) and the objects the clutter source knows: the
    ground truth's boxes (every row: an ignored object's extra boxes are left out of the
    clutter too) or the UM run's; a labels file knows no objects. The clutter events'
    coverage says how many of them are the scene's clutter landing on objects."""
    if clutter_from not in ("gt", "tracks"):
        return TargetClutterFit(0.0, None, 0, 0, "labels")
    objects = sequence.gt_table if clutter_from == "gt" else rows
    chance = chance_events(clutter.count, clutter.coverage)
    return learn_target_clutter(
        sequence.det_table, objects, clutter.left_out, len(objects), clutter_from, chance
    )


def _mean_size(sizes: np.ndarray) -> tuple[float, float]:
    """Mean ``(w, h)`` of the events' boxes."""
    mean = np.mean(sizes, axis=0)
    return float(mean[0]), float(mean[1])


def _learn_in_birth_space(name, events, uniform_birth, epochs, heldout, key, notify):
    """:func:`_learn` of a density over the birth state space (births, the first frame): the
    paper's birth grid and the background grid at the events' mean box size, the birth
    candidates when ``heldout``."""
    size = _mean_size(events.values[:, 4:6])
    return _learn(
        name,
        birth_grid(uniform_birth, size),
        birth_grid(uniform_birth, size, BIRTH_BACKGROUND_GRID),
        events,
        epochs,
        BIRTH_CANDIDATES if heldout else None,
        key,
        notify,
    )


def _learn(name, grid, background, events, epochs, candidates, key, notify):
    """One density: ``(state, snapshots, summary of the settings and the held-out check)``."""
    learner, check = None, {"epochs": epochs, "heldout": None}
    if candidates is not None:
        notify(f"checking {name} settings on held-out events ({len(candidates)} candidates)")
        candidate, held = select_density(
            grid, background, events.values, events.frames, key, candidates
        )
        epochs = candidate.epochs
        learner = candidate_learner(candidate.prior_count)
        check = {"epochs": epochs, "prior_count": candidate.prior_count, "heldout": held.as_dict()}
    notify(f"learning {name} density ({events.count} events, {epochs} passes)")
    state, snapshots = learn_density(grid, events.values, epochs, key, learner)
    if candidates is not None:
        state = combine(state, background, held)
        snapshots = (*snapshots[:-1], snapshots[-1]._replace(state=state))
    return state, snapshots, check


def _summary(events: EventSamples, state: MixtureState, check: dict, mass: float) -> dict:
    """Metadata of one learned density."""
    return {
        "source": events.source,
        "num_events": events.count,
        "object_overlaps": events.object_overlaps,
        "coverage": events.coverage,
        "num_frames": events.num_frames,
        "magnitude": events.magnitude,
        "volume_mass": mass,
        **check,
        "components_alive": int(np.sum(np.asarray(state.alive))),
        "uniform_weight": float(state.uniform_weight),
    }
