"""The PHD tracker as a tool: one configuration, learned-context variants, runs over sequences.

What ``jaxtrack track`` does, as library code for scripts and notebooks:

* :data:`DEFAULT_CONFIG` is the documented pedestrian configuration (the same for every
  sequence; image size and frame rate come from each ``seqinfo.ini``);
  :func:`check_config` validates overrides.
* :func:`tracker_params` builds the :class:`~jaxtrack.filters.phd.PHDParams` of a sequence,
  with uniform intensities (UM) or with a learned context (``jaxtrack learn-context``) in one
  of the paper's variants (:data:`VARIANTS`: GM, A1-A6; PHD-context Sec. V). The first
  frame's births always use the uniform birth intensity with the configured ``birth_rate``
  (``PHDParams.initial_intensity``): a learned birth intensity says where targets enter,
  not where the targets already in view at the start of a span are.
* :func:`track_sequences` runs the tracker on several sequences with **one compile**: the
  padded detections of all of them are brought to a common number of detection slots and run
  in chunks of a fixed number of frames (:func:`~jaxtrack.filters.base.run` with
  ``chunk_frames``), so the compiled chunk is reused across frames and sequences.

``tracker="kalman"`` runs the baseline data-association tracker instead
(:mod:`~jaxtrack.filters.kalman`, a bank of Kalman filters with gating and optimal assignment)
with one of its presets (:data:`~jaxtrack.filters.kalman.KALMAN_PRESETS`: ``"default"``,
``"sort"``); of the configuration it uses ``output`` and ``max_gap`` (:data:`KALMAN_CONFIG_KEYS`).

Output: ``"offline"`` (default) keeps every confirmed track over its whole life, the frames
before its confirmation included, and fills gaps of up to ``max_gap`` frames by linear
interpolation (:func:`~jaxtrack.association.offline.finalise_tracks`); ``"online"`` writes
what the filter outputs frame by frame.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.association.offline import TrackRows, finalise_tracks, track_rows
from jaxtrack.context.intensity import Intensity
from jaxtrack.errors import InputError
from jaxtrack.filters.base import Filter, run
from jaxtrack.filters.kalman import KALMAN_PRESETS, KalmanParams, kalman_filter
from jaxtrack.filters.phd import PHDParams, phd_filter
from jaxtrack.filters.phd_defaults import (
    DEFAULT_DETECTION_PROB,
    DEFAULT_MEASUREMENT_NOISE_STD,
    DEFAULT_MOTION_NOISE_STD,
    DEFAULT_SURVIVAL_PROB,
    default_phd_params,
)
from jaxtrack.io import MotSequence, SequenceInfo
from jaxtrack.types import PAD_BOX, Detections

#: The documented default configuration (one for all sequences).
DEFAULT_CONFIG: dict[str, Any] = {
    "num_particles": 2048,
    "births_per_detection": 32,
    "extraction": "partition",
    "birth_rate": 0.2,
    "clutter_rate": 1.0,
    "detection_prob": DEFAULT_DETECTION_PROB,
    "survival_prob": DEFAULT_SURVIVAL_PROB,
    "motion_noise_std": list(DEFAULT_MOTION_NOISE_STD),
    "measurement_noise_std": list(DEFAULT_MEASUREMENT_NOISE_STD),
    "output": "offline",
    "max_gap": 8,
}
#: Keys whose values are lists of 4 positive numbers (the SDV noise scales).
NOISE_KEYS = ("motion_noise_std", "measurement_noise_std")


#: Trackers of :func:`track_sequences` (``jaxtrack track --tracker``).
TRACKERS = ("phd", "kalman")
#: The keys of the configuration that the Kalman tracker uses (the others are the PHD's).
KALMAN_CONFIG_KEYS = ("output", "max_gap")


class Variant(NamedTuple):
    """Which parts of a learned context a tracker uses.

    Attributes:
        learned_birth: birth density from the context (else uniform).
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
    """A learned context as read by :func:`jaxtrack.context.io.load_context`."""

    birth: Intensity
    clutter: Intensity
    metadata: dict[str, Any]

    @classmethod
    def from_learned(cls, learned: Any) -> Context:
        """The context of a :class:`~jaxtrack.context.learn.LearnedContext`."""
        return cls(learned.birth, learned.clutter, learned.metadata)


def check_config(config: dict[str, Any]) -> str | None:
    """Why ``config`` is not a valid tracker configuration, or None when it is."""
    for key in config:
        if key not in DEFAULT_CONFIG:
            return f"unknown key {key!r}; known: {', '.join(DEFAULT_CONFIG)}"
    for key in NOISE_KEYS:
        value = config.get(key, DEFAULT_CONFIG[key])
        if (
            not isinstance(value, list)
            or len(value) != 4
            or not all(_is_number(v) and math.isfinite(v) and v > 0 for v in value)
        ):
            return f"{key} must be a list of 4 positive numbers, got {value!r}"
    for key, default in DEFAULT_CONFIG.items():
        if key in NOISE_KEYS:
            continue
        value = config.get(key, default)
        expected = type(default)
        ok = isinstance(value, expected) or (
            expected is float and isinstance(value, int) and not isinstance(value, bool)
        )
        if not ok or isinstance(value, bool):
            return f"{key} must be a {expected.__name__}, got {value!r}"
    merged = {**DEFAULT_CONFIG, **config}
    if merged["extraction"] not in ("partition", "gmm"):
        return "extraction must be 'partition' or 'gmm'"
    if merged["output"] not in ("offline", "online"):
        return "output must be 'offline' or 'online'"
    for key in ("num_particles", "births_per_detection", "birth_rate", "clutter_rate"):
        if merged[key] <= 0:
            return f"{key} must be positive, got {merged[key]}"
    if merged["max_gap"] < 0:
        return f"max_gap must be >= 0, got {merged['max_gap']}"
    for key in ("detection_prob", "survival_prob"):
        if not 0 < merged[key] <= 1:
            return f"{key} must be in (0, 1], got {merged[key]}"
    return None


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def tracker_params(
    info: SequenceInfo,
    config: dict[str, Any] | None = None,
    context: Context | None = None,
    variant: str = "GM",
) -> PHDParams:
    """The PHD tracker's parameters for a sequence.

    Args:
        info: the sequence's ``seqinfo.ini`` (image size, frame rate).
        config: overrides of :data:`DEFAULT_CONFIG`.
        context: a learned context; None gives UM (uniform intensities, the configuration's
            magnitudes).
        variant: a key of :data:`VARIANTS` (used only with a context).

    Returns:
        The parameters.

    Raises:
        InputError: unknown variant, or a context learned on an image of another size.
    """
    config = {**DEFAULT_CONFIG, **(config or {})}
    if variant not in VARIANTS:
        raise InputError(f"unknown variant {variant!r}; known: {', '.join(VARIANTS)}")
    use = VARIANTS["UM" if context is None else variant]
    birth_rate, clutter_rate = config["birth_rate"], config["clutter_rate"]
    if context is not None:
        _check_context_size(context, info)
        if use.birth_magnitude_from_context:
            birth_rate = _measured_magnitude(context, "birth")
        if use.clutter_magnitude_from_context:
            clutter_rate = _measured_magnitude(context, "clutter")
    params = default_phd_params(
        info.im_width, info.im_height, info.frame_rate, birth_rate, clutter_rate
    )
    # Targets in view on the first frame are born anywhere, at the configured uniform rate.
    uniform = default_phd_params(
        info.im_width, info.im_height, info.frame_rate, config["birth_rate"], clutter_rate
    )
    params = params._replace(
        initial_intensity=uniform.initial_intensity,
        detection_prob=jnp.asarray(config["detection_prob"], jnp.float32),
        survival_prob=jnp.asarray(config["survival_prob"], jnp.float32),
        motion_noise_std=jnp.asarray(config["motion_noise_std"], jnp.float32),
        measurement_noise_std=jnp.asarray(config["measurement_noise_std"], jnp.float32),
    )
    if use.learned_birth:
        params = params._replace(birth_intensity=context.birth)
    if use.learned_clutter:
        params = params._replace(clutter_intensity=context.clutter)
    return params


def track_sequences(
    sequences: Sequence[MotSequence],
    config: dict[str, Any] | None = None,
    seed: int = 0,
    params: Sequence[PHDParams] | Sequence[KalmanParams] | None = None,
    progress: bool = False,
    chunk_frames: int = 128,
    tracker: str = "phd",
    preset: str = "default",
) -> list[TrackRows]:
    """Tracks several sequences (or spans) with one compiled run.

    Args:
        sequences: the loaded sequences.
        config: overrides of :data:`DEFAULT_CONFIG`.
        seed: PRNG seed (the same key for every sequence).
        params: one parameter PyTree per sequence: :class:`~jaxtrack.filters.phd.PHDParams`
            (default :func:`tracker_params` with uniform intensities) or, with
            ``tracker="kalman"``, :class:`~jaxtrack.filters.kalman.KalmanParams` (default:
            the preset's). Parameters of different PyTree shapes (e.g. contexts with
            different numbers of components) compile once per shape.
        progress: show a progress bar over the sequences.
        chunk_frames: frames per compiled call.
        tracker: one of :data:`TRACKERS`.
        preset: the Kalman tracker's preset (a key of
            :data:`~jaxtrack.filters.kalman.KALMAN_PRESETS`; its assignment cost is used
            with ``params`` too).

    Returns:
        The result rows of each sequence.

    Raises:
        InputError: a bad configuration, tracker or preset.
    """
    config = {**DEFAULT_CONFIG, **(config or {})}
    reason = check_config(config)
    if reason is not None:
        raise InputError(f"bad tracker configuration: {reason}")
    filt = build_filter(config, tracker, preset)
    if params is None:
        if tracker == "kalman":
            params = [KALMAN_PRESETS[preset].params() for _ in sequences]
        else:
            params = [tracker_params(seq.info, config) for seq in sequences]
    capacity = max(seq.detections.mask.shape[1] for seq in sequences)
    key = jax.random.PRNGKey(seed)
    results = []
    items = zip(sequences, params, strict=True)
    if progress:
        from tqdm import tqdm

        items = tqdm(items, total=len(sequences), desc="tracking", unit="seq")
    for seq, seq_params in items:
        detections = pad_to(seq.detections, seq.num_frames, capacity)
        _, info = run(filt, key, seq_params, detections, chunk_frames=chunk_frames)
        if config["output"] == "online":
            results.append(track_rows(info.tracks, seq.first_frame))
        else:
            results.append(
                finalise_tracks(info.tracks, info.candidates, config["max_gap"], seq.first_frame)
            )
    return results


def tracker_description(
    config: dict[str, Any], tracker: str = "phd", preset: str = "default"
) -> dict[str, Any]:
    """What a run used, for the ``.config.json`` beside the results.

    Args:
        config: the full configuration (:data:`DEFAULT_CONFIG` with overrides).
        tracker: one of :data:`TRACKERS`.
        preset: the Kalman preset.

    Returns:
        ``{"tracker": "phd", **config}``, or for the Kalman tracker its preset, assignment
        cost, parameters and the configuration keys it uses.
    """
    if tracker != "kalman":
        return {"tracker": tracker, **config}
    chosen = KALMAN_PRESETS[preset]
    params = {name: _json_numbers(value) for name, value in chosen.params()._asdict().items()}
    return {
        "tracker": "kalman",
        "preset": preset,
        "cost": chosen.cost,
        **{key: config[key] for key in KALMAN_CONFIG_KEYS},
        "params": params,
    }


def _json_numbers(value) -> float | str | list:
    """Numbers of an array for JSON: rounded to 6 decimals, ``"inf"`` for infinity."""
    array = np.round(np.asarray(value, np.float64), 6)
    if array.ndim:
        return [_json_numbers(item) for item in array]
    return float(array) if np.isfinite(array) else str(float(array))


def build_filter(config: dict[str, Any], tracker: str = "phd", preset: str = "default") -> Filter:
    """The filter of a tracker configuration (one object per setting: compiles are shared).

    Args:
        config: a full tracker configuration (:data:`DEFAULT_CONFIG` keys).
        tracker: ``"phd"`` or ``"kalman"``.
        preset: the Kalman tracker's preset (:data:`KALMAN_PRESETS`).

    Raises:
        InputError: an unknown tracker or preset.
    """
    if tracker == "phd":
        return phd_filter(
            config["num_particles"],
            births_per_detection=config["births_per_detection"],
            extraction=config["extraction"],
        )
    if tracker != "kalman":
        raise InputError(f"unknown tracker {tracker!r}; known: {', '.join(TRACKERS)}")
    if preset not in KALMAN_PRESETS:
        raise InputError(f"unknown preset {preset!r}; known: {', '.join(KALMAN_PRESETS)}")
    return _kalman_filter(KALMAN_PRESETS[preset].cost)


@functools.lru_cache(maxsize=4)
def _kalman_filter(cost: str) -> Filter:
    return kalman_filter(cost=cost)


def pad_to(detections: Detections, num_frames: int, capacity: int) -> Detections:
    """Pads detections ``[T, D]`` with empty frames and empty slots to ``[num_frames, capacity]``.

    Raises:
        ValueError: the target shape is smaller than the detections.
    """
    frames, slots = detections.mask.shape
    if num_frames < frames or capacity < slots:
        raise ValueError(f"cannot pad [{frames}, {slots}] detections to [{num_frames}, {capacity}]")
    extra = ((0, num_frames - frames), (0, capacity - slots))
    boxes = np.asarray(detections.boxes)
    padded_boxes = np.tile(np.asarray(PAD_BOX, boxes.dtype), (num_frames, capacity, 1))
    padded_boxes[:frames, :slots] = boxes
    return Detections(
        boxes=padded_boxes,
        scores=np.pad(np.asarray(detections.scores), extra),
        mask=np.pad(np.asarray(detections.mask), extra),
    )


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
