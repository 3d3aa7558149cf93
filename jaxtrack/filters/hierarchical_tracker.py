"""The Hierarchical tracker's configuration: what ``jaxtrack track --tracker hierarchical`` runs.

* :class:`HierarchicalConfig`: the variant (``"kalman"``: the Kalman bank of the baseline,
  :mod:`~jaxtrack.filters.kalman`; ``"managed"``: the low level with its ``|S_k|^1/2`` track
  management; ``"full"``: both levels, the default), the measurement (box or ellipse), the
  tables' sizes, how long a lost tracker waits, and the output rules;
* :func:`hierarchical_params`: the :class:`~jaxtrack.filters.hierarchical.HierarchicalParams`
  of a sequence (its frame rate turns the durations into frames) with its background image
  and the low level's noise estimated from the tracked detections (:func:`low_noise`,
  :mod:`~jaxtrack.filters.hier_low_noise`; ``noise="default"`` for the a priori one);
* :func:`build_hierarchical`: the registry entry ``(config, info, context, variant) ->
  (Filter, params)``; the pipelines give a :class:`HierarchicalContext`: the background
  model's image (:func:`~jaxtrack.pipelines.background.median_background`) and the low
  level's noise for the span (:func:`low_noise`).

Every variant steps on :class:`~jaxtrack.types.FrameInputs` (the ``"kalman"`` one ignores
the frame), so the three run through the same streamed pipeline and compare on the same
detections.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, ClassVar, NamedTuple

import jax.numpy as jnp
import numpy as np

from jaxtrack.configs import MAX_GAP, OUTPUT, SMOOTHING, Rule, TrackerConfig, setting
from jaxtrack.errors import InputError
from jaxtrack.filters.base import Filter, frame_rate
from jaxtrack.filters.hier_appearance import PATCH_SHAPE, bucket_sizes
from jaxtrack.filters.hier_appearance import default_params as default_appearance_params
from jaxtrack.filters.hier_events import default_event_params
from jaxtrack.filters.hier_exchanges import DEFAULT_MARGIN, margin_parameter
from jaxtrack.filters.hier_low_defaults import DEFAULT_NOISE, low_params
from jaxtrack.filters.hier_low_noise import estimate_box_noise
from jaxtrack.filters.hierarchical import HierarchicalParams, hierarchical_filter
from jaxtrack.filters.kalman import KALMAN_PRESETS, kalman_filter
from jaxtrack.filters.kalman_tracker import MAX_TRACKS as KALMAN_TRACKS
from jaxtrack.filters.kalman_tracker import kalman_memory_estimate
from jaxtrack.parameters import ParameterProperties, frozen_properties
from jaxtrack.resources import DETECTION_SLOT_BYTES, MemoryEstimate
from jaxtrack.types import Detections, SequenceInfo

#: Score of a detection that may confirm a low-level track (the PHD tracker's and CMT's
#: ``confirm_score``; not in the paper, whose blobs have no score).
CONFIRM_SCORE = 0.97
#: The low level's measurements (:mod:`~jaxtrack.filters.hier_low`).
MEASUREMENTS = ("box", "ellipse")
#: Default slots of both levels. 32 overflowed on the toolkit's blobs of the development
#: scenes (synthetic video seeds 0-2, 4-6, 168-173: on up to 20 frames of a scene every slot
#: was taken, mostly by lost trackers waiting for re-association and tentative tracks on
#: clutter, and a confirmed track then got no tracker); 64 never did there.
MAX_SLOTS = 64
#: Where the low level's noise comes from (``HierarchicalConfig.noise``).
NOISE_SOURCES = ("auto", "estimated", "default")
#: The variants, in the order of the paper's levels.
VARIANTS = ("kalman", "managed", "full")
#: Seconds a low-level track coasts without measurement before ``|S_k|^1/2`` removes it (the
#: low level's default, 12 frames at 25 fps: a person walks about a body width).
COAST_SECONDS = 0.48
#: How fast the radius within which a lost tracker looks for its target grows: box heights
#: per second lost (a walker covers about one body height in 2 s; the constant-velocity
#: propagation's error grows at a fraction of that).
SEARCH_HEIGHTS_PER_SECOND = 0.5
#: Seconds a new tracker is new-born: a lost tracker may take its track (and identity).
NEWBORN_SECONDS = 0.0
#: Seconds a track must have coasted for its next measurement to be checked against its
#: tracker's appearance (8 frames at 25 fps, two thirds of the coasting the low level allows:
#: time enough for one person to step out where another went behind something).
RESUME_SECONDS = 0.32
#: Default ``confirm_quantile``: a track is also confirmed by a detection scoring at least
#: the 75th percentile of the detector's scores seen so far, when that is below
#: :data:`CONFIRM_SCORE` (:mod:`~jaxtrack.filters.score_quantile`; CMT's value, not tuned).
CONFIRM_QUANTILE = 0.75
#: Seconds a new tracker is entering (the event module's default, 25 frames at 25 fps).
ENTERING_SECONDS = 1.0
#: Grey level of the background image when no background model is given (direct API use;
#: every pipeline gives the span's median image).
FLAT_BACKGROUND = 128


@dataclasses.dataclass(frozen=True)
class HierarchicalConfig(TrackerConfig):
    """The Hierarchical tracker's configuration (``jaxtrack track --tracker hierarchical``)."""

    tracker: ClassVar[str] = "hierarchical"

    variant: str = setting(
        "full",
        Rule(
            "'kalman' (the Kalman bank alone), 'managed' (+ |S|^1/2 track management) or "
            "'full' (+ appearance trackers and events)",
            str,
            choices=VARIANTS,
        ),
    )
    measurement: str = setting(
        "box",
        Rule("the low level's measurement, 'box' or 'ellipse'", str, choices=MEASUREMENTS),
    )
    max_tracks: int = setting(MAX_SLOTS, Rule("low-level track slots", int, 1, 1024))
    max_trackers: int = setting(MAX_SLOTS, Rule("high-level tracker slots", int, 1, 1024))
    lost_seconds: float = setting(
        4.0,
        Rule("seconds a lost tracker waits to be re-associated", float, 0.0, 3600.0),
    )
    resume_seconds: float = setting(
        RESUME_SECONDS,
        Rule(
            "a track that takes a measurement after coasting this long is checked against "
            "its tracker's appearance, and let go when the appearance gate refuses it "
            "(0: never checked, the paper's tracker)",
            float,
            0.0,
            3600.0,
        ),
    )
    noise: str = setting(
        "auto",
        Rule(
            "the low level's noise: 'estimated' from the tracked detections "
            "(jaxtrack.filters.hier_low_noise; box measurement only), 'default' (a priori, "
            "set for background-subtraction blobs) or 'auto' (estimated, except on the "
            "toolkit's own blobs)",
            str,
            choices=NOISE_SOURCES,
        ),
    )
    min_score: float = setting(
        0.0,
        Rule("detections scoring below this are ignored (0: every detection)", float, 0.0, 1e6),
    )
    confirm_score: float = setting(
        CONFIRM_SCORE,
        Rule(
            "a low-level track is confirmed only once it has held a detection scoring at "
            "least this (0: by |S|^1/2 and the MSD alone, the paper's rule)",
            float,
            0.0,
            1e6,
        ),
    )
    confirm_quantile: float = setting(
        CONFIRM_QUANTILE,
        Rule(
            "... or, when lower, at least this quantile of every detection score read so far "
            "(jaxtrack.filters.score_quantile; 1: off)",
            float,
            0.0,
            1.0,
        ),
    )
    exchange_margin: float = setting(
        DEFAULT_MARGIN,
        Rule(
            "two trackers that collided swap their tracks once both are single again when "
            "their appearance models are nearer each other's box by this much (sum of mean "
            "Bhattacharyya distances; jaxtrack.filters.hier_exchanges; negative: never)",
            float,
            -1.0,
            10.0,
        ),
    )
    drift_check: int = setting(
        0,
        Rule(
            "1: a tracker single again after colliding checks its track's box against its "
            "appearance, as after coasting, and lets the track go when the gate refuses it "
            "(0: only after coasting)",
            int,
            0,
            1,
        ),
    )
    fallback_appearance: int = setting(
        1,
        Rule(
            "1: a tracker that has never been single learns its appearance while colliding, "
            "a fallback used only to re-associate it when lost (no gap interpolated across "
            "such a re-association); its first single frame restarts the model (0: learned "
            "only while single, the issue's rule; 2: group trackers learn one too)",
            int,
            0,
            2,
        ),
    )
    score_weight: float = setting(
        1.0,
        Rule(
            "weight of the detections' score log-odds in the low level's association cost: "
            "the cost MSD + 2 log r_k falls by 2 w logit(score) (0: the paper's cost)",
            float,
            0.0,
            100.0,
        ),
    )
    output: str = setting("offline", OUTPUT)
    max_gap: int = setting(25, MAX_GAP)
    smoothing: str = setting("none", SMOOTHING)


class HierarchicalContext(NamedTuple):
    """What the pipelines give :func:`build_hierarchical` from the tracked span.

    Attributes:
        background: the background model's image, RGB ``uint8`` of the sequence's size
            (:func:`~jaxtrack.pipelines.background.median_background`).
        noise: the low level's ``(process_std, measurement_std, initial_std)`` for the span
            (:func:`low_noise`), or None (the a priori noise).
    """

    background: np.ndarray
    noise: tuple[tuple[float, ...], ...] | None = None


def low_noise(
    config: HierarchicalConfig, detections: Detections | None, blobs: bool = False
) -> tuple[tuple[tuple[float, ...], ...], str]:
    """The low level's ``(process_std, measurement_std, initial_std)`` for a configuration
    and the span's detections (``blobs``: the toolkit's background subtraction's), and a line
    saying where it came from.

    ``noise="auto"`` estimates it on a detector's boxes and keeps the a priori noise on the
    blobs it was set for: on the development scenes (synthetic video seeds 0-2, the blobs)
    the estimate lost 3 IDF1 points of the full tracker (0.50 -> 0.47 mean): the blobs'
    merges and splits make heavy tails that the gate calibration widens the gate for (x2.8-3),
    and the tracks then follow merged blobs.
    """
    default = DEFAULT_NOISE[config.measurement]
    if config.noise == "default" or detections is None:
        return default, "low-level noise a priori (DEFAULT_NOISE)"
    if config.noise == "auto" and blobs:
        return default, "low-level noise a priori (set for background-subtraction blobs)"
    if config.measurement != "box":
        return default, "low-level noise a priori (only the box measurement's is estimated)"
    mask = np.asarray(detections.mask) & (np.asarray(detections.scores) >= config.min_score)
    noise = estimate_box_noise(np.asarray(detections.boxes), mask, default)
    if not any(noise.samples):
        return default, "low-level noise a priori (too few linked detections to estimate it)"
    try:
        low_params(config.measurement, *noise[:3])
    except InputError as error:  # e.g. an initial state below the steady state
        return default, f"low-level noise a priori (the estimate was refused: {error})"
    rounded = [[round(v, 4) for v in part] for part in noise[:2]]
    return (noise.process_std, noise.measurement_std, noise.initial_std), (
        f"low-level noise estimated from {noise.samples[0]} linked detections: process "
        f"{rounded[0]}, "
        f"measurement {rounded[1]} (gate calibration x{noise.calibration:.2f})"
    )


def writes_events(config: HierarchicalConfig) -> bool:
    """Only the full tracker has events (its high-level trackers')."""
    return config.variant == "full"


def hierarchical_params(
    config: HierarchicalConfig,
    info: SequenceInfo,
    background: np.ndarray | None = None,
    noise: tuple[tuple[float, ...], ...] | None = None,
) -> HierarchicalParams:
    """The default parameters for a sequence: durations in frames at its frame rate, the
    low level's ``noise`` (:func:`low_noise`; None: the a priori noise).

    Raises:
        InputError: a background image of another size than the sequence's.
    """
    shape = (info.im_height, info.im_width, 3)
    if background is None:
        background = np.full(shape, FLAT_BACKGROUND, np.uint8)
    background = np.asarray(background)
    if background.shape != shape or background.dtype != np.uint8:
        raise InputError(
            f"the background image is {background.dtype} {background.shape}; {info.name} needs "
            f"uint8 {shape}"
        )
    fps = frame_rate(info)
    coast = max(round(COAST_SECONDS * fps), 1)
    noise = noise or DEFAULT_NOISE[config.measurement]
    low = low_params(config.measurement, *noise, coast_frames=coast)
    return HierarchicalParams(
        low=low,
        appearance=default_appearance_params(),
        events=default_event_params()._replace(
            entering_frames=jnp.int32(round(ENTERING_SECONDS * fps))
        ),
        max_lost=jnp.float32(round(config.lost_seconds * fps)),
        max_newborn=jnp.float32(round(NEWBORN_SECONDS * fps)),
        search_rate=jnp.float32(SEARCH_HEIGHTS_PER_SECOND / fps),
        background=jnp.asarray(background),
        min_score=jnp.float32(config.min_score),
        confirm_score=jnp.float32(config.confirm_score),
        confirm_quantile=jnp.float32(config.confirm_quantile),
        exchange_margin=margin_parameter(config.exchange_margin),
        score_weight=jnp.float32(config.score_weight),
        drift_check=jnp.float32(config.drift_check),
        fallback_appearance=jnp.float32(config.fallback_appearance),
        resume_frames=jnp.float32(
            max(round(config.resume_seconds * fps), 1) if config.resume_seconds > 0 else jnp.inf
        ),
    )


def build_hierarchical(
    config: HierarchicalConfig, info: SequenceInfo, context: Any = None, variant: str = "GM"
) -> tuple[Filter, Any]:
    """The Hierarchical tracker of a configuration: ``(filter, params)`` (cached filters).

    Args:
        config: the configuration.
        info: the sequence (image size, frame rate).
        context: a :class:`HierarchicalContext` (what the pipelines give), the background
            model's image alone (RGB ``uint8`` of the sequence's size; a priori noise), or
            None (a flat grey image: the features are then ranked against no background).
        variant: the PHD context's variant; only the default is accepted.

    Raises:
        InputError: a context that is not an image of the sequence's size, or a context
            variant.
    """
    if variant != "GM":
        raise InputError(f"context variant {variant!r} is for the PHD tracker")
    noise = None
    if isinstance(context, HierarchicalContext):
        context, noise = context
    if context is not None and not isinstance(context, np.ndarray | jnp.ndarray):
        raise InputError("the Hierarchical tracker takes a background image, not a context")
    if config.variant == "kalman":
        return _kalman_on_frames(), KALMAN_PRESETS["default"].params()
    filt = _hierarchical_filter(
        config.variant, config.max_tracks, config.max_trackers, config.measurement
    )
    return filt, hierarchical_params(config, info, context, noise)


@functools.lru_cache(maxsize=8)
def _hierarchical_filter(variant, max_tracks, max_trackers, measurement) -> Filter:
    return hierarchical_filter(variant, max_tracks, max_trackers, measurement, PATCH_SHAPE)


@functools.lru_cache(maxsize=1)
def _kalman_on_frames() -> Filter:
    """The baseline Kalman bank (default preset), stepping on frame inputs."""
    preset = KALMAN_PRESETS["default"]
    inner = kalman_filter(max_tracks=KALMAN_TRACKS, cost=preset.cost)

    def step(key, state, params, inputs):
        return inner.step(key, state, params, inputs.detections)

    return Filter(init=inner.init, step=step)


def hierarchical_memory_estimate(
    config: HierarchicalConfig, capacity: int, chunk_frames: int
) -> MemoryEstimate:
    """The tracker's memory for a detection capacity, from the sizes (frames left out).

    The state holds, per high-level slot, the 49 x 64 mean histograms and their statistics;
    a step's temporaries are the histograms of every low-level slot on the frame and on the
    background (``2 x T x 49 x 64`` floats, zero in free slots) and those of the live slots
    compacted into a bucket, with their patch samples
    (:func:`~jaxtrack.filters.hier_appearance.live_box_histograms`; counted for every bucket
    of :func:`~jaxtrack.filters.hier_appearance.bucket_sizes`, fewer than ``2 T`` boxes,
    whichever runs); the per-frame outputs are two track tables and the slots' events, pools
    and distances.
    """
    if config.variant == "kalman":
        return kalman_memory_estimate(config, capacity, chunk_frames)
    tracks, trackers = config.max_tracks, config.max_trackers
    state = 4 * trackers * 49 * (64 + 8) + 4 * tracks * 64 + 64 * trackers
    compacted = sum(bucket_sizes(tracks))
    temporaries = 4 * tracks * 2 * 49 * 64 + 4 * compacted * (2 * 49 * 64 + 4 * 256 * 3)
    temporaries += 4 * tracks * capacity * 8
    frame_output = 25 * (tracks + trackers) + 4 * trackers * (60 + 4 * 4) + 20 * tracks
    chunk = 2 * state + temporaries
    chunk += chunk_frames * (DETECTION_SLOT_BYTES * capacity + frame_output)
    return MemoryEstimate(chunk_bytes=int(chunk + (1 << 16)), frame_output_bytes=frame_output)


def hierarchical_properties(params: Any) -> Any:
    """The parameter-properties tree: every parameter frozen (the tracker is not tuned by
    gradient: its decisions are thresholds); named, for sweeps
    (:func:`~jaxtrack.pipelines.sweep.sweep_frames`): the low level's ``process_std``,
    ``measurement_std``, ``gate`` (MSD gate), ``recovery_gate``, ``confirm_ratio``,
    ``confirm_msd`` and ``remove_ratio``; the high level's ``gate_sigmas`` (appearance gate,
    Sec. 5.4), ``max_lost``, ``search_rate`` and ``resume_frames``; the event machine's
    ``min_overlap``
    (collision); and ``min_score``, ``confirm_score`` and ``score_weight`` (the
    configuration keys)."""
    props = frozen_properties(params)

    def named(name: str) -> ParameterProperties:
        return ParameterProperties(trainable=False, name=name)

    low = {
        name: named(name)
        for name in (
            "process_std",
            "measurement_std",
            "gate",
            "recovery_gate",
            "confirm_ratio",
            "confirm_msd",
            "remove_ratio",
        )
    }
    return props._replace(
        low=props.low._replace(**low),
        appearance=props.appearance._replace(gate_sigmas=named("gate_sigmas")),
        events=props.events._replace(min_overlap=named("min_overlap")),
        max_lost=named("max_lost"),
        search_rate=named("search_rate"),
        resume_frames=named("resume_frames"),
        min_score=named("min_score"),
        confirm_score=named("confirm_score"),
        confirm_quantile=named("confirm_quantile"),
        exchange_margin=named("exchange_margin"),
        drift_check=named("drift_check"),
        fallback_appearance=named("fallback_appearance"),
        score_weight=named("score_weight"),
    )
