"""The PHD tracker's configuration and parameters: what ``jaxtrack track`` runs.

* :class:`PHDConfig` is the documented pedestrian configuration (the same for every
  sequence; image size and frame rate come from each ``seqinfo.ini``): a frozen, validated,
  hashable dataclass (:mod:`jaxtrack.configs`).
* :func:`phd_params` builds the :class:`~jaxtrack.filters.phd.PHDParams` of a sequence,
  with uniform intensities (UM) or with a learned context (``jaxtrack learn-context``) in one
  of the paper's variants (:data:`VARIANTS`: GM, A1-A6; PHD-context Sec. V).
* :func:`build_phd` is the tracker's entry of the registry
  (:mod:`jaxtrack.filters.registry`): ``(config, info, context, variant) -> (Filter, params)``;
  the filter is cached on the configuration's static settings, so a setting compiles once per
  process.
* :func:`phd_properties` is the parameter-properties tree (:mod:`jaxtrack.parameters`) that
  the sweep and the tuner share; :func:`tuned_context` writes tuned magnitudes and uniform
  shares back into a learned context (``jaxtrack tune --context``).

**Birth rate.** ``birth_rate`` is ``lambda_s``, the magnitude of the birth intensity
``gamma`` (PHD-context eq. 19): expected births per frame from the second frame of a run on.
The first frame uses ``PHDParams.initial_intensity``, uniform with magnitude
``initial_rate``: a learned birth intensity says where targets *enter*, not where the
targets already in view when a span starts are. Configuration, sweep and tuner all mean this
(``birth_rate`` never changes ``initial_rate``). A context that records a learned
first-frame intensity (``Context.initial``: where the targets of the training span were,
with the mean number in view as magnitude; :mod:`jaxtrack.context.learn`) gives it to the
variants with a learned birth density (GM, A1, A4, A6) instead.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
from typing import Any, ClassVar, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.configs import (
    MAX_GAP,
    OUTPUT,
    RETRODICTION,
    SMOOTHING,
    Rule,
    TrackerConfig,
    check_retrodiction,
    setting,
)
from jaxtrack.context.intensity import Intensity, birth_speed_limit, uniform_birth_intensity
from jaxtrack.context.learn import volume_mass
from jaxtrack.context.scores import ScoreCalibration, calibration_from_metadata
from jaxtrack.context.target_clutter import target_clutter_from_metadata
from jaxtrack.errors import InputError
from jaxtrack.filters.base import Filter
from jaxtrack.filters.births import VELOCITY_PROPOSALS
from jaxtrack.filters.phd import CONFIRMATIONS, PHDParams, TargetClutter, phd_filter
from jaxtrack.filters.phd_defaults import (
    DEFAULT_DETECTION_PROB,
    DEFAULT_MEASUREMENT_NOISE_STD,
    DEFAULT_MOTION_NOISE_STD,
    DEFAULT_SURVIVAL_PROB,
    default_phd_params,
)
from jaxtrack.models.survival import SurvivalMap
from jaxtrack.parameters import LOG, LOGIT, SHARE, ParameterProperties, frozen_properties
from jaxtrack.resources import DETECTION_SLOT_BYTES, MemoryEstimate
from jaxtrack.types import SequenceInfo

#: Largest ``num_particles`` a configuration accepts (memory grows linearly with it).
MAX_PARTICLES = 1 << 20
#: Largest ``births_per_detection``.
MAX_BIRTHS_PER_DETECTION = 1024
#: Largest birth, initial or clutter rate (per frame).
MAX_RATE = 1e4
#: Estimate slots of the ``"gmm"`` extraction (mixture components) and track-table slots.
GMM_CLUSTERS = 32
MAX_TRACKS = 64

#: The names of the tunable parameters (:func:`phd_properties`), each a configuration key.
TUNABLE = (
    "clutter_rate",
    "birth_rate",
    "initial_rate",
    "detection_prob",
    "survival_prob",
    "motion_noise_std",
    "measurement_noise_std",
)
#: The tunable uniform shares ``pi_u`` of a learned context's densities, by context part.
#: They are no configuration keys: :func:`tuned_context` writes them into the context.
UNIFORM_SHARES = {"birth": "birth_uniform_share", "clutter": "clutter_uniform_share"}

_RATE = {"kind": float, "lower": 0.0, "upper": MAX_RATE, "lower_open": True}
_PROBABILITY = {"kind": float, "lower": 0.0, "upper": 1.0, "lower_open": True}
_NOISE = {"kind": tuple, "length": 4, "lower": 0.0, "upper": 10.0, "lower_open": True}


#: Values of :attr:`PHDConfig.frame_capacity` (:func:`~jaxtrack.filters.phd.phd_step`'s
#: ``split_capacity``).
FRAME_CAPACITIES = ("full", "split")


@dataclasses.dataclass(frozen=True)
class PHDConfig(TrackerConfig):
    """The particle PHD tracker's configuration (``jaxtrack track --config FILE.json``)."""

    tracker: ClassVar[str] = "phd"

    num_particles: int = setting(
        2048, Rule("particles kept after resampling", int, 1, MAX_PARTICLES)
    )
    births_per_detection: int = setting(
        32, Rule("birth particles per detection", int, 1, MAX_BIRTHS_PER_DETECTION)
    )
    extraction: str = setting(
        "partition",
        Rule(
            "state extraction: 'partition' (one estimate per detection) or 'gmm' (the paper's "
            "Gaussian-mixture clustering)",
            str,
            choices=("partition", "gmm"),
        ),
    )
    birth_rate: float = setting(
        0.2, Rule("lambda_s, expected births per frame (birth intensity magnitude)", **_RATE)
    )
    initial_rate: float = setting(
        0.2, Rule("magnitude of the first frame's uniform birth intensity", **_RATE)
    )
    clutter_rate: float = setting(
        1.0, Rule("lambda_r, expected false detections per frame", **_RATE)
    )
    detection_prob: float = setting(
        DEFAULT_DETECTION_PROB, Rule("pD = 1 - pM, probability of detection", **_PROBABILITY)
    )
    survival_prob: float = setting(
        DEFAULT_SURVIVAL_PROB, Rule("e(x), probability of survival per frame", **_PROBABILITY)
    )
    motion_noise_std: tuple = setting(
        DEFAULT_MOTION_NOISE_STD,
        Rule("SDV dynamics noise (sigma_n1, sigma_n2, nw, nh), relative to box size", **_NOISE),
    )
    measurement_noise_std: tuple = setting(
        DEFAULT_MEASUREMENT_NOISE_STD,
        Rule("SDV likelihood noise (s_1, s_2, s_w, s_h), relative to box size", **_NOISE),
    )
    confirmation: str = setting(
        "auto",
        Rule(
            "track confirmation: 'score' (one detection scoring at least confirm_score, 0.97), "
            "'evidence' (the score log-odds of the track's detections add up to logit(0.97): "
            "a target whose detections all score 0.8 is confirmed on its third) or 'auto' "
            "('evidence' with a context that carries the detector's score calibration, "
            "'score' without)",
            str,
            choices=tuple(CONFIRMATIONS),
        ),
    )
    output: str = setting("offline", OUTPUT)
    max_gap: int = setting(8, MAX_GAP)
    retrodiction: int = setting(0, RETRODICTION)
    smoothing: str = setting("none", SMOOTHING)
    birth_velocity: str = setting(
        "uniform",
        Rule(
            "the births' velocity proposal: 'uniform' (uniform over the birth intensity's "
            "velocity range, the paper's) or 'detections' (three quarters at the displacements "
            "from the previous frame's detections of a compatible size); both weight the "
            "births by the same birth intensity (an importance density, not a model change)",
            str,
            choices=VELOCITY_PROPOSALS,
        ),
    )
    frame_capacity: str = setting(
        "full",
        Rule(
            "detection slots of each frame's step: 'full' (the run's capacity, a power of two, "
            "on every frame) or 'split' (a frame whose detections fit in half the slots runs "
            "on that half: faster runs, twice the compile, results equal up to float32 "
            "rounding)",
            str,
            choices=FRAME_CAPACITIES,
        ),
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        check_retrodiction(self)


class Variant(NamedTuple):
    """Which parts of a learned context a tracker uses.

    Attributes:
        learned_birth: birth density from the context (else uniform), and its first-frame
            intensity when it has one (else uniform with ``initial_rate``).
        learned_clutter: clutter density from the context (else uniform).
        birth_magnitude_from_context: ``lambda_s`` measured on the training span (else the
            configuration's ``birth_rate``).
        clutter_magnitude_from_context: ``lambda_r`` measured on the training span (else the
            configuration's ``clutter_rate``).
    """

    learned_birth: bool
    learned_clutter: bool
    birth_magnitude_from_context: bool
    clutter_magnitude_from_context: bool


#: The variants of PHD-context Sec. V (SPEC section 1). A6 is GM with a context whose birth
#: samples were labelled (``jaxtrack learn-context --birth-from gt``); at tracking time it is GM.
VARIANTS: dict[str, Variant] = {
    "UM": Variant(False, False, False, False),
    "GM": Variant(True, True, True, True),
    "A1": Variant(True, False, True, False),
    "A2": Variant(False, True, False, True),
    "A3": Variant(False, False, True, True),
    "A4": Variant(True, False, True, True),
    "A5": Variant(False, True, True, True),
    "A6": Variant(True, True, True, True),
}


class Context(NamedTuple):
    """A learned context as read by :func:`jaxtrack.context.io.load_context_parts`.

    Attributes:
        birth: the birth intensity ``gamma``.
        clutter: the clutter intensity ``kappa``.
        metadata: what the learner recorded.
        initial: the first frame's intensity (the targets in view), None in a context that
            has none (learned before it existed, or written by hand).
    """

    birth: Intensity
    clutter: Intensity
    metadata: dict[str, Any]
    initial: Intensity | None = None

    @classmethod
    def from_learned(cls, learned: Any) -> Context:
        """The context of a :class:`~jaxtrack.context.learn.LearnedContext`."""
        return cls(learned.birth, learned.clutter, learned.metadata, learned.initial)


def phd_params(
    config: PHDConfig,
    info: SequenceInfo,
    context: Context | None = None,
    variant: str = "GM",
) -> PHDParams:
    """The PHD tracker's parameters for a sequence.

    Args:
        config: the configuration.
        info: the sequence's ``seqinfo.ini`` (image size, frame rate).
        context: a learned context; None gives UM (uniform intensities, the configuration's
            magnitudes). Its detector score calibration, when it records one
            (:mod:`jaxtrack.context.scores`), goes into ``labelling.score_calibration`` for
            every variant, UM included (read by the ``"evidence"`` confirmation, and by ``"auto"``,
            the default, which then confirms by evidence).
        variant: a key of :data:`VARIANTS` (used only with a context).

    Returns:
        The parameters.

    Raises:
        InputError: unknown variant, or a context learned on an image of another size.
    """
    if variant not in VARIANTS:
        raise InputError(f"unknown variant {variant!r}; known: {', '.join(VARIANTS)}")
    use = VARIANTS["UM" if context is None else variant]
    birth_rate, clutter_rate = config.birth_rate, config.clutter_rate
    if context is not None:
        _check_context_size(context, info)
        if use.birth_magnitude_from_context:
            birth_rate = _measured_magnitude(context, "birth")
        if use.clutter_magnitude_from_context:
            clutter_rate = _measured_magnitude(context, "clutter")
    params = default_phd_params(
        info.im_width, info.im_height, info.frame_rate, birth_rate, clutter_rate
    )
    max_speed = birth_speed_limit(info.im_height, info.frame_rate)
    params = params._replace(
        initial_intensity=uniform_birth_intensity(
            config.initial_rate, info.im_width, info.im_height, max_speed
        ),
        detection_prob=jnp.asarray(config.detection_prob, jnp.float32),
        survival_prob=jnp.asarray(config.survival_prob, jnp.float32),
        motion_noise_std=jnp.asarray(config.motion_noise_std, jnp.float32),
        measurement_noise_std=jnp.asarray(config.measurement_noise_std, jnp.float32),
    )
    if context is not None:
        params = with_score_calibration(params, calibration_from_metadata(context.metadata))
    if use.learned_birth:
        params = params._replace(birth_intensity=context.birth)
        if context.initial is not None:
            params = params._replace(initial_intensity=context.initial)
    if use.learned_clutter:
        params = params._replace(clutter_intensity=context.clutter)
        target_clutter = target_clutter_from_metadata(context.metadata)
        if target_clutter is not None:
            rate, spread = target_clutter
            params = params._replace(
                target_clutter=TargetClutter(
                    jnp.asarray(rate, jnp.float32), jnp.asarray(spread, jnp.float32)
                )
            )
    return params


def with_score_calibration(params: PHDParams, calibration: ScoreCalibration | None) -> PHDParams:
    """``params`` reading detector scores through ``calibration``
    (``labelling.score_calibration``; None leaves ``params`` as they are)."""
    if calibration is None:
        return params
    calibration = jax.tree.map(lambda x: jnp.asarray(x, jnp.float32), calibration)
    return params._replace(labelling=params.labelling._replace(score_calibration=calibration))


def build_phd(
    config: PHDConfig,
    info: SequenceInfo,
    context: Context | None = None,
    variant: str = "GM",
) -> tuple[Filter, PHDParams]:
    """The PHD tracker of a configuration for a sequence: ``(filter, params)``.

    The filter depends only on the static settings (``num_particles``,
    ``births_per_detection``, ``extraction``) and is cached on them: every caller gets the
    same object for the same setting, so the runner's and the sweep's compiled functions
    (cached per filter) compile once per process.
    """
    return phd_filter_of(config), phd_params(config, info, context, variant)


def phd_filter_of(config: PHDConfig) -> Filter:
    """The (cached) filter of a configuration's static settings."""
    return _phd_filter(
        config.num_particles,
        config.births_per_detection,
        config.extraction,
        config.frame_capacity == "split",
        config.confirmation,
        config.birth_velocity,
    )


@functools.lru_cache(maxsize=16)
def _phd_filter(
    num_particles: int,
    births_per_detection: int,
    extraction: str,
    split_capacity: bool,
    confirmation: str,
    birth_velocity: str,
) -> Filter:
    return phd_filter(
        num_particles,
        births_per_detection=births_per_detection,
        extraction=extraction,
        max_clusters=GMM_CLUSTERS,
        max_tracks=MAX_TRACKS,
        split_capacity=split_capacity,
        confirmation=confirmation,
        birth_velocities=birth_velocity,
    )


# Bytes of XLA's temporary buffers in a compiled chunk (:func:`phd_memory_estimate`).
#: Per particle of the update (survivors and births): about 32 float32 values (the states
#: and weights, predicted, concatenated with the births, resampled).
_PARTICLE_TEMP = 128
#: More per birth particle: the draws and their proposal density.
_BIRTH_TEMP = 56
#: Per detection slot: the update's ``[max_detections, block]`` arrays (block >= 128).
_SLOT_TEMP = 1024
#: Per particle and mixture component of the ``"gmm"`` extraction (responsibilities).
_GMM_TEMP = 22
#: Small buffers, whatever the sizes.
_FIXED_TEMP = 1 << 18
#: Bytes of one estimate slot of the per-frame outputs: ``tracks`` and ``candidates`` (box,
#: id, score, mask: 25 bytes each) and ``estimates`` (state, mass, score, mask: 33 bytes).
_ESTIMATE_SLOT_OUTPUT = 83
#: Per-frame outputs besides the slots (mass, log-likelihood, overflow), the frame's PRNG key
#: and index, and the parameters (a learned context included).
_FRAME_SCALARS = 12
_PARAMS = 1 << 12


def phd_memory_estimate(config: PHDConfig, capacity: int, chunk_frames: int) -> MemoryEstimate:
    """The PHD tracker's memory for a detection capacity, from the sizes (no compile).

    With ``N = num_particles``, ``B = births_per_detection x capacity`` birth particles, ``C =
    capacity``, ``K = chunk_frames`` and ``E`` estimate slots (``C`` for ``"partition"``,
    :data:`GMM_CLUSTERS` for ``"gmm"``), a compiled chunk holds

    * its arguments and outputs: the state twice (``28 N`` bytes and the track table), the
      chunk's padded detections (``21 K C``) and per-frame outputs (``83 K E``);
    * XLA's temporaries: ``128 (N + B) + 56 B + 1024 C`` bytes (``_PARTICLE_TEMP``,
      ``_BIRTH_TEMP``, ``_SLOT_TEMP``; the update and the births' proposal density work in
      blocks, so no term grows with ``C^2``), plus ``22 N E`` with ``"gmm"``, plus 0.25 MB.

    The coefficients were fitted to ``compiled.memory_analysis()`` (CPU, XLA of JAX 0.10) of
    the chunk scan over 16 to 5000 detection slots, 2^11 to 2^20 particles and 1 to 128 births
    per detection; the estimate is within 25% of it there (``tests/filters/test_memory.py``).

    Args:
        config: the configuration (``num_particles``, ``births_per_detection``,
            ``extraction``).
        capacity: detection slots per frame.
        chunk_frames: frames per compiled call.

    Returns:
        The :class:`~jaxtrack.resources.MemoryEstimate`.
    """
    particles, births = config.num_particles, config.births_per_detection * capacity
    slots = capacity if config.extraction == "partition" else GMM_CLUSTERS
    state = 28 * particles + 34 * MAX_TRACKS + 16
    frame_output = _ESTIMATE_SLOT_OUTPUT * slots + _FRAME_SCALARS
    temp = (
        _PARTICLE_TEMP * (particles + births)
        + _BIRTH_TEMP * births
        + _SLOT_TEMP * capacity
        + (_GMM_TEMP * particles * GMM_CLUSTERS if config.extraction == "gmm" else 0)
        + _FIXED_TEMP
    )
    inputs = chunk_frames * DETECTION_SLOT_BYTES * capacity
    chunk = 2 * state + _PARAMS + inputs + chunk_frames * frame_output + temp
    return MemoryEstimate(chunk_bytes=int(chunk), frame_output_bytes=int(frame_output))


def phd_properties(params: PHDParams) -> PHDParams:
    """The parameter-properties tree of :class:`~jaxtrack.filters.phd.PHDParams`.

    Named leaves (each name but the uniform shares is the :class:`PHDConfig` key that carries
    it): ``clutter_rate`` (``clutter_intensity.magnitude``, log), ``birth_rate``
    (``birth_intensity.magnitude``, log), ``initial_rate`` (``initial_intensity.magnitude``,
    log), ``detection_prob`` and ``survival_prob`` (logit; a survival map is not tunable), the
    SDV noise scales ``motion_noise_std`` and ``measurement_noise_std`` (log), and the uniform
    shares ``pi_u`` of the birth and clutter densities (PHD-context eq. 21),
    ``birth_uniform_share`` and ``clutter_uniform_share`` (``*_intensity.uniform_weight``,
    :data:`~jaxtrack.parameters.SHARE`: logit on ``[0, 1)``; a uniform intensity's
    ``pi_u = 1`` is refused when tuned, see :func:`has_learned_density`). All start frozen;
    :func:`~jaxtrack.parameters.with_trainable` picks the trainable ones.
    """
    props = frozen_properties(params)

    def named(name: str, transform) -> ParameterProperties:
        return ParameterProperties(trainable=False, transform=transform, name=name)

    survival = params.survival_prob
    return props._replace(
        clutter_intensity=props.clutter_intensity._replace(
            magnitude=named("clutter_rate", LOG),
            uniform_weight=named(UNIFORM_SHARES["clutter"], SHARE),
        ),
        birth_intensity=props.birth_intensity._replace(
            magnitude=named("birth_rate", LOG),
            uniform_weight=named(UNIFORM_SHARES["birth"], SHARE),
        ),
        initial_intensity=props.initial_intensity._replace(magnitude=named("initial_rate", LOG)),
        detection_prob=named("detection_prob", LOGIT),
        survival_prob=props.survival_prob
        if isinstance(survival, SurvivalMap)
        else named("survival_prob", LOGIT),
        motion_noise_std=named("motion_noise_std", LOG),
        measurement_noise_std=named("measurement_noise_std", LOG),
    )


def has_learned_density(intensity: Intensity) -> bool:
    """Whether an intensity's density has a learned part: live Gaussians and ``pi_u < 1``.

    Only then is its uniform share a parameter: a uniform (UM) intensity has ``pi_u = 1`` and
    no live Gaussians, so moving ``pi_u`` would share the density with nothing.
    """
    alive = np.any(np.asarray(intensity.weights) > 0)
    return bool(alive and float(intensity.uniform_weight) < 1)


def context_names(variant: str) -> dict[str, str]:
    """The tunable names whose values a variant takes from the context, by name: its part.

    A learned part's magnitude and uniform share, and the magnitude of a uniform part whose
    magnitude is measured (A3-A5); the others are configuration keys.
    """
    names = {}
    for part, learned, measured in _context_parts(variant):
        if learned or measured:
            names[f"{part}_rate"] = part
        if learned:
            names[UNIFORM_SHARES[part]] = part
    return names


def _context_parts(variant: str) -> tuple[tuple[str, bool, bool], ...]:
    """``(part, learned density, measured magnitude)`` of a variant's birth and clutter."""
    use = VARIANTS[variant]
    return (
        ("birth", use.learned_birth, use.birth_magnitude_from_context),
        ("clutter", use.learned_clutter, use.clutter_magnitude_from_context),
    )


def tuned_context(
    context: Context, params: PHDParams, variant: str, record: dict[str, Any]
) -> Context:
    """The context with the (tuned) magnitudes and uniform shares of ``params`` written in.

    The inverse of :func:`phd_params` for the parts the variant takes from the context, so
    that ``phd_params(config, info, tuned_context(...), variant)`` gives back ``params``'
    birth and clutter intensities (and every variant reads consistent values):

    * a learned part (GM; A1, A4 birth; A2, A5 clutter): the intensity takes ``params``'
      magnitude ``m`` and uniform share ``pi_u``; the recorded events per frame become
      ``lambda = m P_p(V)``, with ``P_p(V) = pi_u + (1 - pi_u) P_GMM(V)`` the density's mass
      in the volume (:mod:`jaxtrack.context.learn`; ``P_GMM(V)`` from the recorded
      ``volume_mass``, else by Monte Carlo);
    * a uniform part with a measured magnitude (A3; A4 clutter, A5 birth): ``lambda`` is
      ``params``' magnitude, the learned intensity's magnitude ``lambda / P_p(V)``;
    * a part the variant does not take from the context is unchanged.

    Args:
        context: the context tuned.
        params: the tuned parameters (from ``phd_params(config, info, context, variant)``).
        variant: the variant they were built with (not UM).
        record: what to note in the metadata's ``tuning`` list (span, objective, values).

    Returns:
        The tuned context; its metadata's ``birth`` and ``clutter`` hold the new
        ``magnitude``, ``uniform_weight`` and ``volume_mass``, ``tuning`` the records.
    """
    metadata = copy.deepcopy(context.metadata)
    parts = {}
    for part, learned, measured in _context_parts(variant):
        intensity = getattr(context, part)
        tuned = getattr(params, f"{part}_intensity")
        if learned:
            intensity = intensity._replace(uniform_weight=jnp.asarray(tuned.uniform_weight))
        mass = _volume_mass(context, part, float(intensity.uniform_weight))
        if learned:
            rate = float(tuned.magnitude) * mass
        elif measured:
            rate = float(tuned.magnitude)
        else:
            parts[part] = intensity
            continue
        parts[part] = intensity._replace(magnitude=jnp.asarray(rate / mass, jnp.float32))
        recorded = metadata.get(part)
        metadata[part] = {
            **(recorded if isinstance(recorded, dict) else {}),
            "magnitude": rate,
            "volume_mass": mass,
            "uniform_weight": float(intensity.uniform_weight),
        }
    metadata["tuning"] = [*metadata.get("tuning", []), record]
    return Context(parts["birth"], parts["clutter"], metadata, context.initial)


def _volume_mass(context: Context, part: str, uniform_weight: float) -> float:
    """``P_p(V)`` of a context part's density with its uniform share set to ``uniform_weight``."""
    intensity = getattr(context, part)
    if not np.any(np.asarray(intensity.weights) > 0):
        return 1.0
    recorded = context.metadata.get(part, {})
    learned_share = float(intensity.uniform_weight)
    if isinstance(recorded, dict) and "volume_mass" in recorded and learned_share < 1:
        gaussian_mass = (float(recorded["volume_mass"]) - learned_share) / (1 - learned_share)
    else:
        mixture = intensity._replace(uniform_weight=jnp.asarray(0.0))
        gaussian_mass = volume_mass(mixture, jax.random.key(0))
    gaussian_mass = min(max(gaussian_mass, 0.0), 1.0)
    return uniform_weight + (1 - uniform_weight) * gaussian_mass


def _measured_magnitude(context: Context, part: str) -> float:
    """Events per training frame of a context part (its intensity's magnitude if unrecorded)."""
    recorded = context.metadata.get(part, {})
    if isinstance(recorded, dict) and "magnitude" in recorded:
        return float(recorded["magnitude"])
    return float(getattr(context, part).magnitude)


def _check_context_size(context: Context, info: SequenceInfo) -> None:
    upper = np.asarray(context.clutter.upper)
    if not np.allclose(upper[:2], [info.im_width, info.im_height]):
        raise InputError(
            f"the context was learned on {upper[0]:g}x{upper[1]:g} images, the sequence "
            f"{info.name} has {info.im_width}x{info.im_height}"
        )
