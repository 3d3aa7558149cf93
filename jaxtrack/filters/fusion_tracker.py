"""The Fusion tracker's configuration: what ``jaxtrack track --tracker fusion`` runs.

* :class:`FusionConfig`: the pool (``--pool``), the fusion rule (``--fusion``), the share of
  the tracked span it trains on when no ``--train-frames`` is given, the calibration share,
  the classifier's learning rate, the table size and the output rules;
* :class:`FusionContext`: what the tracker learns from a training span (entry/exit zones and
  activity mask, local motion models, voting thresholds per region), built by
  :func:`~jaxtrack.pipelines.fusion_context.learn_fusion_context`;
* :func:`fusion_params` and :func:`build_fusion`, the registry entry ``(config, info,
  context, variant) -> (Filter, params)``.

Without a context (direct API use) the tracker runs on no scene knowledge: no zones, the
whole image active, constant-velocity motion, and the paper's thresholds for PETS 2009
(:data:`PAPER_TH_INIT`, :data:`PAPER_TH_TERM`).
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
from typing import Any, ClassVar, NamedTuple

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
from jaxtrack.context.activity import ACTIVITY_CELL, grid_shape
from jaxtrack.context.motion_models import MotionModels, Tracklets, fit_motion_models
from jaxtrack.context.zones import SceneZones
from jaxtrack.errors import InputError
from jaxtrack.filters.base import Filter
from jaxtrack.filters.fusion import FUSIONS, MEMBERS, SIGNATURE_PATCH, FusionParams, fusion_filter
from jaxtrack.filters.fusion_classifier import CLASSIFIER_PATCH_SHAPE, classifier_params
from jaxtrack.filters.fusion_voting import SHARE, Thresholds
from jaxtrack.filters.hier_exchanges import margin_parameter
from jaxtrack.filters.kalman import CHI2_4DOF, default_kalman_params
from jaxtrack.parameters import ParameterProperties, frozen_properties
from jaxtrack.resources import DETECTION_SLOT_BYTES, MemoryEstimate
from jaxtrack.types import SequenceInfo

#: Every pool: the non-empty subsets of the members, written in :data:`MEMBERS` order.
POOLS = tuple(
    ",".join(subset)
    for size in range(1, len(MEMBERS) + 1)
    for subset in itertools.combinations(MEMBERS, size)
)
#: The rules calibrating th_init (``FusionConfig.init_rule``): the paper's share of the
#: false-positive runs, or the fewest errors on the training span
#: (:func:`~jaxtrack.filters.fusion_voting.calibrate_init_cost`).
INIT_RULES = ("share", "cost")
#: The rule of ``FusionConfig.init_rule`` (also checked by the Fusion experiment's option).
INIT_RULE = Rule(
    "how th_init is calibrated: 'share' (the paper: the smallest rejecting `share` of the "
    "false-positive runs) or 'cost' (the fewest false-target and late-start frames on the "
    "training span)",
    str,
    choices=INIT_RULES,
)
#: The paper's thresholds for PETS 2009 (its Table 2), used without a calibration.
PAPER_TH_INIT, PAPER_TH_TERM = 3, 8
#: Smallest IoU of a detection with a slot's predicted box (the link IoU of the
#: false-positive runs the initiation threshold is calibrated on).
GATE = 0.3
#: Largest squared Mahalanobis distance of a detection from a slot's predicted box: the 0.99
#: chi-square quantile with 4 degrees of freedom (the Kalman baseline's 0.95 gave IDF1 55.1
#: against 53.7 on PETS09-S2L1 1:397 and 79.4 against 80.7 / 50.9 against 50.7 on the
#: development scenes' detections / blobs, seeds 0-2; session 43).
CHI2_GATE = CHI2_4DOF[0.99]
#: Smallest peak-to-sidelobe ratio of a classifier response (Bolme et al.: 20-60 when
#: tracking well, below about 7 on failure or occlusion).
PSR_MIN = 20.0
#: ``Q`` of an occlusion (paper: 0.3 of the boxes' area).
OCCLUSION_Q = 0.3
#: Learning-rate floor of the signature models.
SIGNATURE_RATE = 0.1
#: Re-identification vicinity (new-box heights) and largest signature distance.
REID_RADIUS, REID_GATE = 2.0, 0.35
#: Weight of a target's signature distance to a detection in the assignment cost (beside
#: ``d^2 + log |S|``; session 48). Chosen among 0, 3, 10, 30, 60 and 150 on development data
#: only (PETS09-S2L1 1:397 and synthetic video seeds 0-2, 4-6 with their detections; IDF1
#: rose from 30 to 150 alike on the scenes, 60 was best on PETS), then confirmed on the
#: same data's blobs.
APPEARANCE_WEIGHT = 60.0
#: The offline output's hypothesis rules (``FusionConfig.hypothesis_rows``).
HYPOTHESIS_ROWS = ("voted", "chained")
#: Margin of the exchange check (``FusionConfig.exchange_margin``; session 53). Chosen among
#: 0.1, 0.2 and 0.3 on development data only (PETS09-S2L1 1:397 and synthetic video seeds
#: 0-2, 4-6, their detections and blobs): 0.1 made one wrong swap on PETS09-S2L1's
#: detections (IDF1 -7), 0.2 and 0.3 none there, 0.2 gained most on the scenes' blobs.
EXCHANGE_MARGIN = 0.2
#: The offline output's smoothing when the configuration names none (``FusionConfig.
#: smoothing``; session 63): the Rauch-Tung-Striebel smoother of
#: :mod:`jaxtrack.association.smoothing`, beyond the paper. Made the default by a rule written
#: before its held-out run (fresh synthetic video seeds 291-293, TUD-Campus, TUD-Stadtmitte,
#: PETS09-S2L1 399:795; README, "The offline output smoothed by default"); the online output
#: has nothing to smooth and gets ``"none"``.
DEFAULT_SMOOTHING = "rts"


def _default_smoothing(output: str) -> str:
    """``FusionConfig.smoothing`` when none is given: :data:`DEFAULT_SMOOTHING` for the
    offline output, ``"none"`` for the online one."""
    return DEFAULT_SMOOTHING if output == "offline" else "none"


#: ``FusionConfig.smoothing``'s rule: the shared one, whose default depends on the output.
FUSION_SMOOTHING = dataclasses.replace(
    SMOOTHING,
    doc=SMOOTHING.doc
    + f" (default: {DEFAULT_SMOOTHING!r} with the offline output, 'none' with the online one)",
)


@dataclasses.dataclass(frozen=True)
class FusionConfig(TrackerConfig):
    """The Fusion tracker's configuration (``jaxtrack track --tracker fusion``)."""

    tracker: ClassVar[str] = "fusion"
    trims_tails: ClassVar[bool] = True
    #: Overlap of a retrodicted detection with the walked box: the detection member's own
    #: support gate (the MOT15 detector's boxes change size from frame to frame too much
    #: for IoU 0.5 between consecutive ones).
    retrodiction_iou: ClassVar[float] = GATE

    pool: str = setting(
        "detection,classifier,predictor",
        Rule(
            "the pool's members, comma-separated in the order detection, classifier, "
            "predictor (one member: that tracker alone)",
            str,
            choices=POOLS,
        ),
    )
    fusion: str = setting(
        "proposed",
        Rule(
            "'proposed' (confidence and accordance, the paper's eq. 6) or 'naive' (the mean "
            "of the responses)",
            str,
            choices=FUSIONS,
        ),
    )
    train_fraction: float = setting(
        0.5,
        Rule(
            "share of the tracked span, from its first frame, trained on when no training "
            "span is given (--train-frames)",
            float,
            0.0,
            1.0,
            lower_open=True,
        ),
    )
    share: float = setting(
        SHARE,
        Rule(
            "share of the false-positive runs th_init rejects, and of the detection gaps "
            "th_term survives (the paper: 0.99)",
            float,
            0.0,
            1.0,
            lower_open=True,
        ),
    )
    init_rule: str = setting("share", INIT_RULE)
    learning_rate: float = setting(
        0.35, Rule("the classifier's learning rate lambda (paper: 0.35 on PETS)", float, 0, 1)
    )
    appearance_weight: float = setting(
        APPEARANCE_WEIGHT,
        Rule(
            "weight of a target's signature distance (in [0, 1]) to a detection in the "
            "detection member's assignment cost, beside the Mahalanobis distance (0: motion "
            "alone)",
            float,
            0.0,
            1000.0,
        ),
    )
    exchange_margin: float = setting(
        EXCHANGE_MARGIN,
        Rule(
            "two targets that met in an occlusion group swap their identities once both are "
            "apart and re-detected when each one's signature model is nearer the other's "
            "detection by this much (sum of two signature distances; negative: never)",
            float,
            -1.0,
            10.0,
        ),
    )
    max_targets: int = setting(32, Rule("slots for targets and hypotheses", int, 1, 1024))
    output: str = setting("offline", OUTPUT)
    max_gap: int = setting(25, MAX_GAP)
    retrodiction: int = setting(0, RETRODICTION)
    hypothesis_rows: str = setting(
        "chained",
        Rule(
            "offline output: 'chained', the hypotheses dropped just before a target's "
            "voted-in one at its walked-back place (within max_gap frames, IoU >= 0.3) are "
            "its rows too; 'voted', its rows start with the hypothesis voted in",
            str,
            choices=HYPOTHESIS_ROWS,
        ),
    )
    #: None: :data:`DEFAULT_SMOOTHING` for the offline output, ``"none"`` for the online one
    #: (resolved on construction; a given value is kept and checked as every tracker's is).
    smoothing: str = setting(None, FUSION_SMOOTHING)

    def __post_init__(self) -> None:
        if self.smoothing is None:
            object.__setattr__(self, "smoothing", _default_smoothing(self.output))
        super().__post_init__()
        check_retrodiction(self)

    def replace(self, **changes: Any) -> FusionConfig:
        """A copy with some keys changed (validated). A change of ``output`` alone takes the
        new output's default smoothing when this one has its output's default, so that
        ``FusionConfig().replace(output="online")`` is not refused for a smoothing nobody
        asked for."""
        default = self.smoothing == _default_smoothing(self.output)
        if "output" in changes and "smoothing" not in changes and default:
            changes = {**changes, "smoothing": None}
        return super().replace(**changes)

    @property
    def chain_iou(self) -> float:
        """The IoU of :func:`~jaxtrack.association.offline.chain_candidates` (0: off). Like
        ``max_gap``, a rule of the offline output (the online output has no rows before a
        target's vote)."""
        return GATE if self.hypothesis_rows == "chained" else 0.0


class FusionContext(NamedTuple):
    """What the Fusion tracker learns from a training span.

    Attributes:
        scene: entry/exit zones and activity mask.
        motion: the local motion models.
        thresholds: ``th_init`` / ``th_term`` per region.
        description: how each was obtained, in words (for the user and ``.config.json``).
    """

    scene: SceneZones
    motion: MotionModels
    thresholds: Thresholds
    description: str


def pool_members(config: FusionConfig) -> tuple[str, ...]:
    """The configuration's pool as a tuple of member names."""
    return tuple(config.pool.split(","))


def default_context(info: SequenceInfo) -> FusionContext:
    """No scene knowledge: no zones, the whole image active, constant velocity everywhere,
    the paper's PETS thresholds in every region."""
    rows, columns = grid_shape(info.im_width, info.im_height, ACTIVITY_CELL)
    scene = SceneZones(np.zeros((0, 4), np.float32), np.ones((rows, columns), bool), ACTIVITY_CELL)
    empty = Tracklets(np.zeros((0, 5, 2)), np.zeros((0, 2)))
    motion = fit_motion_models(empty, info.im_width, info.im_height)
    thresholds = Thresholds(
        init=np.full(3, PAPER_TH_INIT, np.int64), term=np.full(3, PAPER_TH_TERM, np.int64)
    )
    return FusionContext(scene, motion, thresholds, "no training: the paper's thresholds")


def fusion_params(
    config: FusionConfig, info: SequenceInfo, context: FusionContext | None = None
) -> FusionParams:
    """The parameters for a sequence with a learned context (default: :func:`default_context`).

    Raises:
        InputError: a context that is not a :class:`FusionContext`, or one without an
            activity mask.
    """
    if context is None:
        context = default_context(info)
    if not isinstance(context, FusionContext):
        raise InputError("the Fusion tracker takes a FusionContext (learn_fusion_context)")
    scene = context.scene
    if scene.activity is None:
        raise InputError("the Fusion tracker's scene needs an activity mask")
    boxes = np.asarray(scene.boxes, np.float32).reshape(-1, 4)
    kalman = default_kalman_params()
    return FusionParams(
        classifier=classifier_params(learning_rate=config.learning_rate),
        motion=context.motion,
        zone_boxes=jnp.asarray(boxes),
        activity=jnp.asarray(scene.activity, bool),
        activity_cell=jnp.float32(scene.cell_size),
        th_init=jnp.asarray(context.thresholds.init, jnp.int32),
        th_term=jnp.asarray(context.thresholds.term, jnp.int32),
        motion_noise_std=kalman.motion_noise_std,
        measurement_noise_std=kalman.measurement_noise_std,
        initial_velocity_std=kalman.initial_velocity_std,
        chi2_gate=jnp.float32(CHI2_GATE),
        gate=jnp.float32(GATE),
        psr_min=jnp.float32(PSR_MIN),
        occlusion_q=jnp.float32(OCCLUSION_Q),
        signature_rate=jnp.float32(SIGNATURE_RATE),
        reid_radius=jnp.float32(REID_RADIUS),
        reid_gate=jnp.float32(REID_GATE),
        appearance_weight=jnp.float32(config.appearance_weight),
        exchange_margin=margin_parameter(config.exchange_margin),
    )


def build_fusion(
    config: FusionConfig, info: SequenceInfo, context: Any = None, variant: str = "GM"
) -> tuple[Filter, Any]:
    """The Fusion tracker of a configuration: ``(filter, params)`` (cached filters).

    Args:
        config: the configuration.
        info: the sequence (image size).
        context: a :class:`FusionContext` (:func:`~jaxtrack.pipelines.fusion_context.
            learn_fusion_context`), or None (:func:`default_context`).
        variant: the PHD context's variant; only the default is accepted.

    Raises:
        InputError: a context of another kind, or a context variant.
    """
    if variant != "GM":
        raise InputError(f"context variant {variant!r} is for the PHD tracker")
    filt = _fusion_filter(pool_members(config), config.fusion, config.max_targets)
    return filt, fusion_params(config, info, context)


@functools.lru_cache(maxsize=16)
def _fusion_filter(pool: tuple[str, ...], fusion: str, max_targets: int) -> Filter:
    return fusion_filter(pool, fusion, max_targets)


def fusion_memory_estimate(
    config: FusionConfig, capacity: int, chunk_frames: int
) -> MemoryEstimate:
    """The tracker's memory for a detection capacity, from the sizes (frames left out).

    Per slot the state holds two correlation-filter planes (complex and real), the
    signature model (two 512-bin histograms), a Kalman filter (6 + 36 floats) and a row of
    the pair table of the exchange check (a byte per slot); a step's
    temporaries are the filters' search windows and FFTs and the signatures of four boxes
    per slot.
    """
    slots = config.max_targets
    rows, cols = CLASSIFIER_PATCH_SHAPE
    samples = SIGNATURE_PATCH[0] * SIGNATURE_PATCH[1]
    state = slots * (12 * rows * cols + 4 * 2 * 512 + 4 * 64 + 4 * 42 + 256 + slots)
    temporaries = slots * (6 * 8 * rows * cols + 4 * (2 * 512 + 16 * samples) * 4)
    temporaries += 4 * slots * capacity * 4
    temporaries += capacity * (2 * 512 + 16 * samples) * 4  # the detections' signatures
    frame_output = slots * (2 * 25 + 3 * 16 + 3 + 12 + 4)
    chunk = 2 * state + temporaries
    chunk += chunk_frames * (DETECTION_SLOT_BYTES * capacity + frame_output)
    return MemoryEstimate(chunk_bytes=int(chunk + (1 << 16)), frame_output_bytes=frame_output)


def fusion_properties(params: Any) -> Any:
    """The parameter-properties tree: every parameter frozen (thresholds and learned
    models); named, for sweeps (:func:`~jaxtrack.pipelines.sweep.sweep_frames`):
    ``chi2_gate`` and ``gate`` (detection assignment), ``psr_min`` (classifier response),
    ``occlusion_q``, ``signature_rate``, ``reid_radius``, ``reid_gate``, ``appearance_weight``
    (the assignment's signature term), ``exchange_margin`` (the exchange check), ``th_init`` and
    ``th_term`` (``[3]``: active, inactive and zone regions; a sweep overrides the
    calibrated values) and the classifier's ``learning_rate`` (the configuration key)."""
    props = frozen_properties(params)
    names = (
        "chi2_gate",
        "gate",
        "psr_min",
        "occlusion_q",
        "signature_rate",
        "reid_radius",
        "reid_gate",
        "appearance_weight",
        "exchange_margin",
        "th_init",
        "th_term",
    )
    return props._replace(
        **{name: ParameterProperties(trainable=False, name=name) for name in names},
        classifier=props.classifier._replace(
            learning_rate=ParameterProperties(trainable=False, name="learning_rate")
        ),
    )
