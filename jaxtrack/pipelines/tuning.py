"""Tuning the PHD tracker on a MOTChallenge sequence span: what ``jaxtrack tune`` does.

:func:`tune_sequence` starts from the tracker's configuration
(:class:`~jaxtrack.filters.phd_tracker.PHDConfig`, uniform intensities) or, given a learned
context, from the context's intensities in one of the paper's variants; it tunes the chosen
parameters with :func:`~jaxtrack.pipelines.tuner.tune` on the span's detections (and ground
truth for the supervised objective), and returns the tuned tracker configuration (a JSON
object for ``jaxtrack track --config``), the tuned context (``jaxtrack track --context``;
:func:`~jaxtrack.filters.phd_tracker.tuned_context`) and a report of the run.

**Tuning a context.** With a context the default parameters are the magnitudes and the
uniform shares ``pi_u`` of the parts the variant takes from it
(:data:`CONTEXT_TRAINABLE`; e.g. A1: ``birth_rate`` and ``birth_uniform_share``; a share
only where the part's density has a learned part). A learned part's magnitude is its
intensity's magnitude ``lambda / P_p(V)`` (PHD-context eq. 19-21 with the volume mass of
:mod:`jaxtrack.context.learn`); the tuned context records the events per frame
``lambda = m P_p(V)`` beside it, so that every variant reads the tuned values.

The tuning filter is the tracker's filter with fewer particles by default
(:data:`TUNING_PARTICLES`): the tuned magnitudes hardly depend on the particle count, and a
gradient step costs a forward and a backward pass per key.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any, NamedTuple

import jax
import numpy as np
import optax

from jaxtrack.errors import InputError
from jaxtrack.filters.phd import PHDParams
from jaxtrack.filters.phd_tracker import (
    UNIFORM_SHARES,
    VARIANTS,
    Context,
    PHDConfig,
    context_names,
    has_learned_density,
    phd_params,
    tuned_context,
)
from jaxtrack.io import MotSequence
from jaxtrack.pipelines.tuner import DEFAULT_LEARNING_RATE, TuneResult, tune
from jaxtrack.tuning.objectives import ESTIMATORS, make_objective, tuning_filter
from jaxtrack.tuning.transforms import (
    parameter_space,
    parameter_values,
    round_significant,
    to_config,
)

#: Particles of the tuning filter (the tracker itself runs with the configuration's count).
TUNING_PARTICLES = 512
#: Birth particles per detection of the tuning filter.
TUNING_BIRTHS_PER_DETECTION = 16
#: Parameters that ``jaxtrack tune`` tunes by default: the clutter and birth magnitudes (the
#: axes of PHD-context's sweeps); ``--tune`` adds others.
CONFIG_TRAINABLE = ("clutter_rate", "birth_rate")
#: Parameters tuned by default with a learned context: of these, the ones the variant takes
#: from the context (:func:`context_trainable`).
CONTEXT_TRAINABLE = ("clutter_rate", "birth_rate", "birth_uniform_share", "clutter_uniform_share")


class SequenceTuning(NamedTuple):
    """Outcome of :func:`tune_sequence`.

    Attributes:
        config: the tuned tracker configuration (``jaxtrack track --config``); with a
            context, the start configuration plus the tuned parameters it carries (those the
            variant does not take from the context).
        result: the :class:`~jaxtrack.pipelines.tuner.TuneResult`.
        report: a JSON-ready summary: sequence, frames, objective, settings, start and tuned
            values of the trainable parameters, the history and the run time; with a context
            also the variant and the tuned context's parts.
        context: the tuned context (``jaxtrack track --context``), or None without one.
    """

    config: PHDConfig
    result: TuneResult
    report: dict[str, Any]
    context: Context | None = None


def tune_sequence(
    sequence: MotSequence,
    objective: str = "likelihood",
    config: PHDConfig | None = None,
    trainable: Sequence[str] | None = None,
    *,
    context: Context | None = None,
    variant: str = "GM",
    seed: int = 0,
    num_steps: int = 60,
    num_keys: int = 2,
    learning_rate: float = DEFAULT_LEARNING_RATE,
    patience: int = 20,
    average_steps: int = 10,
    num_particles: int = TUNING_PARTICLES,
    births_per_detection: int = TUNING_BIRTHS_PER_DETECTION,
    estimator: str = "stop_gradient",
    progress: bool = False,
) -> SequenceTuning:
    """Tunes the tracker's parameters on a sequence span.

    Args:
        sequence: the loaded span (ground truth needed for ``"supervised"``).
        objective: ``"likelihood"`` (no ground truth) or ``"supervised"``.
        config: the tracker configuration to start from (default :class:`PHDConfig`); the
            tuned one keeps its other keys.
        trainable: parameter names to tune (:func:`~jaxtrack.tuning.transforms.tunable_names`);
            default :data:`CONFIG_TRAINABLE`, with a context :func:`context_trainable`.
        context: a learned context to start from (and to tune); None: uniform intensities.
        variant: which parts of the context the tracker uses (not UM; ignored without one).
        seed: PRNG seed of the filter runs.
        num_steps: the most adam steps.
        num_keys: keys per step (common random numbers).
        learning_rate: adam's learning rate (log / logit units).
        patience: early-stopping patience (0: run all steps).
        average_steps: the result averages the last ``average_steps`` iterates.
        num_particles: particles of the tuning filter.
        births_per_detection: birth particles per detection of the tuning filter.
        estimator: resampling gradient estimator (:data:`~jaxtrack.tuning.objectives.ESTIMATORS`).
        progress: show a progress bar.

    Returns:
        The :class:`SequenceTuning`.

    Raises:
        InputError: a bad objective, estimator, setting, variant or parameter name, a
            uniform share of a density with no learned part, a supervised objective without
            ground truth, or a span without detections.
    """
    if objective not in ("likelihood", "supervised"):
        raise InputError(f"objective must be 'likelihood' or 'supervised', got {objective!r}")
    if estimator not in ESTIMATORS:
        raise InputError(f"estimator must be one of {', '.join(ESTIMATORS)}, got {estimator!r}")
    for name, value in (("steps", num_steps), ("keys", num_keys), ("particles", num_particles)):
        if value <= 0:
            raise InputError(f"{name} must be positive, got {value}")
    if births_per_detection <= 0:
        raise InputError(f"births per detection must be positive, got {births_per_detection}")
    if not learning_rate > 0:
        raise InputError(f"learning rate must be positive, got {learning_rate}")
    if patience < 0 or average_steps <= 0:
        raise InputError("patience must be >= 0 and average_steps positive")
    config = config or PHDConfig()
    if objective == "supervised" and sequence.ground_truth is None:
        raise InputError(f"{sequence.path}: the supervised objective needs gt/gt.txt")
    if not np.any(np.asarray(sequence.detections.mask)):
        raise InputError(f"{sequence.path}: no detections in frames {_span(sequence)}")
    if context is not None and variant == "UM":
        raise InputError("variant UM uses no context: give another variant, or no context")
    start = phd_params(config, sequence.info, context, variant)
    if trainable is None:
        trainable = CONFIG_TRAINABLE if context is None else context_trainable(start, variant)
    _check_uniform_shares(start, trainable, context, variant)
    _check_initial_rate(trainable, context, variant)
    space = parameter_space(start, trainable)
    filt = tuning_filter(num_particles, births_per_detection, estimator)
    began = time.perf_counter()
    result = tune(
        make_objective(objective, filt),
        start,
        sequence.detections,
        jax.random.key(seed),
        ground_truth=sequence.ground_truth if objective == "supervised" else None,
        space=space,
        optimizer=optax.adam(learning_rate),
        num_steps=num_steps,
        num_keys=num_keys,
        patience=patience,
        average_steps=average_steps,
        progress=progress,
    )
    seconds = time.perf_counter() - began
    in_context = {} if context is None else context_names(variant)
    tuned_config = (
        to_config(result.params, config)
        if context is None
        else to_config(result.params, config, [n for n in space.trainable if n not in in_context])
    )
    report = {
        "sequence": str(sequence.path),
        "frames": [sequence.first_frame, sequence.last_frame],
        "objective": objective,
        "estimator": estimator,
        "seed": seed,
        "num_particles": num_particles,
        "births_per_detection": births_per_detection,
        "learning_rate": learning_rate,
        "num_keys": num_keys,
        "steps": len(result.history["loss"]),
        "stop_reason": result.stop_reason,
        "filter_runs": result.filter_runs,
        "seconds": round(seconds, 1),
        "start": parameter_values(start, space.trainable),
        "tuned": parameter_values(result.params, space.trainable),
        "config": tuned_config.overrides(),
        "history": {
            "loss": round_significant(result.history["loss"]),
            **{name: round_significant(v) for name, v in result.history["values"].items()},
        },
    }
    if context is None:
        return SequenceTuning(tuned_config, result, report)
    record = {
        key: report[key]
        for key in ("sequence", "frames", "objective", "steps", "stop_reason", "start", "tuned")
    }
    record["variant"] = variant
    tuned = tuned_context(context, result.params, variant, record)
    report["variant"] = variant
    report["context"] = {
        part: {key: tuned.metadata[part][key] for key in ("magnitude", "uniform_weight")}
        for part in sorted(set(in_context.values()))
    }
    return SequenceTuning(tuned_config, result, report, tuned)


def context_trainable(params: PHDParams, variant: str) -> tuple[str, ...]:
    """The parameters tuned by default with a context: of :data:`CONTEXT_TRAINABLE`, those
    the variant takes from the context, a uniform share only where the part's density has a
    learned part (:func:`~jaxtrack.filters.phd_tracker.has_learned_density`)."""
    taken = context_names(variant)
    return tuple(
        name
        for name in CONTEXT_TRAINABLE
        if name in taken
        and (
            name not in UNIFORM_SHARES.values()
            or has_learned_density(getattr(params, f"{taken[name]}_intensity"))
        )
    )


def _check_uniform_shares(
    params: PHDParams, names: Sequence[str], context: Context | None, variant: str
) -> None:
    """Refuses to tune the uniform share of a density with no learned part."""
    for part, name in UNIFORM_SHARES.items():
        if name not in names or has_learned_density(getattr(params, f"{part}_intensity")):
            continue
        if context is None:
            raise InputError(
                f"{name} is the uniform share of a learned {part} density: it needs a learned "
                "context (--context CTX.npz); without one the intensities are uniform"
            )
        if not getattr(VARIANTS[variant], f"learned_{part}"):
            users = ", ".join(v for v, use in VARIANTS.items() if getattr(use, f"learned_{part}"))
            raise InputError(
                f"{name}: variant {variant} uses no learned {part} density (those that do: {users})"
            )
        raise InputError(
            f"{name}: the context's {part} density is uniform (pi_u = "
            f"{float(getattr(context, part).uniform_weight):g}, no live Gaussians below 1): "
            "there is no learned part to share with"
        )


def _check_initial_rate(names: Sequence[str], context: Context | None, variant: str) -> None:
    """Refuses to tune ``initial_rate`` where the run starts from the context's learned
    first-frame intensity (the tuned value would be written to a configuration key that
    such a run ignores)."""
    if "initial_rate" in names and context is not None and context.initial is not None:
        if VARIANTS[variant].learned_birth:
            raise InputError(
                f"initial_rate: variant {variant} starts from the context's learned first-frame "
                "intensity, not from the uniform one whose magnitude initial_rate is; tune "
                "without it, or with a variant whose births are uniform (A2, A3, A5)"
            )


def _span(sequence: MotSequence) -> str:
    return f"{sequence.first_frame}:{sequence.last_frame}"
