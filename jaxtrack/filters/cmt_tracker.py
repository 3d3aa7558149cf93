"""CMT's configuration and parameters: what ``jaxtrack track --tracker cmt`` runs.

* :class:`CMTConfig`: the variant of the ablation (``"mtb"``, ``"cpd"``, ``"cmt"``), the
  table's sizes and the output rules (a frozen, validated dataclass, :mod:`jaxtrack.configs`);
* :func:`cmt_params`: the :class:`~jaxtrack.filters.cmt.CMTParams` of a sequence, with the
  scene's entry/exit zones (:class:`~jaxtrack.context.zones.SceneZones`, ``--zones``);
* :func:`build_cmt`: the registry entry ``(config, info, zones, variant) -> (Filter,
  params)``; the filter is cached on the static settings (one compile per setting).

The defaults are the same for every sequence: sizes are relative to the boxes (the SDV noise
of :mod:`~jaxtrack.models.noise`; distances of the contextual proposal in box heights), so
they carry across image sizes. They were set from the papers' values and the synthetic video
scenes of seeds 0-2; the sequences of ``experiments/cmt_ablation.py`` were not used to pick
them, except as said below. ``max_misses`` 3 and ``reidentify_seconds`` 1 (session 40)
were the best IDF1 of the settings tried on the development scenes (synthetic video seeds
0-2 and 4-6), then checked on fresh scenes 141-143 and the MOT15 videos (README, CMT:
"Re-identification of deleted components"); ``max_misses`` 5 and ``reidentify_seconds`` 0
give the earlier tracker.
``free_blob_frames`` 2 (session 41) was chosen on the development scenes and the MOT15
videos among the settings tried, then run on fresh scenes 147-152 (README, CMT: "Free-blob
births"); 0 gives the session-40 tracker.
``confirm_quantile`` 0.75 and ``max_components`` 32 (session 46) were set on the development
scenes, then run once on fresh scenes and the MOT15 videos (README, CMT: "Confirmation by
the detector's own scores"); 1 and 16 give the session-41 tracker.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any, ClassVar

import jax.numpy as jnp
import numpy as np

from jaxtrack.configs import MAX_GAP, OUTPUT, SMOOTHING, Rule, TrackerConfig, setting
from jaxtrack.context.zones import SceneZones
from jaxtrack.errors import InputError
from jaxtrack.filters.base import Filter, frame_rate
from jaxtrack.filters.cmt import MAX_ZONES, VARIANTS, CMTParams, cmt_filter
from jaxtrack.filters.cmt_observation import NUM_VALUES, default_com_params, num_features
from jaxtrack.filters.cmt_proposal import default_cpd_params
from jaxtrack.filters.mixture_state import MixtureParams
from jaxtrack.filters.phd_defaults import DEFAULT_MEASUREMENT_NOISE_STD, DEFAULT_MOTION_NOISE_STD
from jaxtrack.parameters import LOG, ParameterProperties, frozen_properties
from jaxtrack.resources import DETECTION_SLOT_BYTES, MemoryEstimate
from jaxtrack.types import SequenceInfo

#: What a component's support is computed from (``CMTConfig.support``).
SUPPORTS = ("likelihood", "box")
#: Log-likelihood of a particle no blob explains (the floor of the box likelihood): about
#: 3.5 standard deviations off in each of the 4 box coordinates for a 50 x 100 box.
BACKGROUND_LOG_LIKELIHOOD = -38.0
#: A component whose log support ``log w_m`` falls below this is unsupported on the frame.
MIN_LOG_SUPPORT = -36.0
#: A blob no particle scores above this (log box likelihood) starts a component.
BIRTH_LOG_LIKELIHOOD = -24.0
#: A component whose mixture weight falls below this is deleted: 0, never (see
#: :mod:`jaxtrack.filters.cmt`: ``pi_m`` measures the box size as much as the evidence).
MIN_MIXTURE_WEIGHT = 0.0
#: Score of a blob that confirms a component (the PHD tracker's ``confirm_score``).
CONFIRM_SCORE = 0.97
#: IoU of two local decisions above which the younger component is a duplicate.
DUPLICATE_IOU = 0.5
#: Box heights from a zone within which a blob may enter (start a component) under the
#: contextual proposal: unbounded by default. Gating births to 1 box height of the learned
#: zones (the paper's enter bonus taken strictly) lost MOTA on the development scenes
#: (synthetic video seeds 0-2: 0.877 / 0.800 / 0.888 ungated vs 0.850 / 0.788 / 0.870 gated):
#: a target lost behind others cannot come back away from a zone.
ENTER_DISTANCE = math.inf


@dataclasses.dataclass(frozen=True)
class CMTConfig(TrackerConfig):
    """CMT's configuration (``jaxtrack track --tracker cmt``)."""

    tracker: ClassVar[str] = "cmt"

    variant: str = setting(
        "cmt",
        Rule(
            "'mtb' (plain mixture tracker), 'cpd' (+ contextual proposal) or 'cmt' (+ "
            "contextual observation model)",
            str,
            choices=VARIANTS,
        ),
    )
    max_components: int = setting(
        32,
        Rule(
            "local tracker slots: the most components alive at once (16 before session 46, "
            "when busy synthetic scenes filled them and new targets waited unborn)",
            int,
            1,
            1024,
        ),
    )
    particles_per_component: int = setting(40, Rule("particles per local tracker", int, 1, 4096))
    max_misses: int = setting(
        3, Rule("frames a component survives without a blob supporting it", int, 0, 1000)
    )
    appearance_weight: float = setting(
        3.0,
        Rule(
            "exponent of the appearance likelihood (0: box only; 3 since session 56, was 1)",
            float,
            0.0,
            100.0,
        ),
    )
    group_area_ratio: float = setting(
        0.0,
        Rule(
            "group blobs: one detection over two targets bounds both (0: off; e.g. 0.6, the "
            "largest share of the pair's box and the blob one target may cover)",
            float,
            0.0,
            1.0,
        ),
    )
    velocity_rate: float = setting(
        0.1,
        Rule(
            "merge velocity: rate of each component's long-run velocity average, held while "
            "one blob covers two components (cpd and cmt variants; 0: off, the paper's "
            "tracker)",
            float,
            0.0,
            1.0,
        ),
    )
    reidentify_seconds: float = setting(
        1.0,
        Rule(
            "seconds within which a new component takes back the identity of a deleted "
            "confirmed one nearby and alike in colour (0: off, the paper's tracker)",
            float,
            0.0,
            3600.0,
        ),
    )
    free_blob_frames: int = setting(
        2,
        Rule(
            "frames a blob must stay unowned before it starts a component even where "
            "another component's particles explain it; components are then confirmed only "
            "once apart from older ones, and an unconfirmed one may take over the identity of "
            "a confirmed one that died nearby (0: never, the paper's tracker)",
            int,
            0,
            1000,
        ),
    )
    confirm_quantile: float = setting(
        0.75,
        Rule(
            "a blob confirms a component when it scores 0.97 or at least this quantile of "
            "the scores of every blob seen so far, whichever is lower (the detector's "
            "confident boxes, whatever its score scale; 1: 0.97 alone, the earlier tracker)",
            float,
            0.0,
            1.0,
        ),
    )
    support: str = setting(
        "box",
        Rule(
            "what a component's support (deleted after max_misses frames below the "
            "threshold) is computed from: 'box' (the blobs' evidence alone, which "
            "appearance_weight then leaves alone; the default since session 56) or "
            "'likelihood' (box times appearance^appearance_weight, the paper's)",
            str,
            choices=SUPPORTS,
        ),
    )
    information_correction: float = setting(
        0.0,
        Rule(
            "COM: multiple of the chance-level mutual information (what sampling noise "
            "alone gives) taken off each feature's score before the weights are normalised "
            "(0: the paper's plug-in estimate, which favours the noisiest features when the "
            "targets look alike)",
            float,
            0.0,
            100.0,
        ),
    )
    exchange_margin: float = setting(
        0.1,
        Rule(
            "two components that collided exchange identities and appearance models when "
            "they separate if the observation model explains each one's blob by the other's "
            "model better by this many nats (cpd and cmt variants; "
            "jaxtrack.filters.cmt_exchanges; 0.1 since session 61; negative: never, the "
            "paper's tracker)",
            float,
            -1.0,
            100.0,
        ),
    )
    output: str = setting("offline", OUTPUT)
    max_gap: int = setting(8, MAX_GAP)
    smoothing: str = setting("none", SMOOTHING)


def zone_arrays(zones: SceneZones | None) -> tuple[jnp.ndarray, jnp.ndarray]:
    """The zones padded to :data:`~jaxtrack.filters.cmt.MAX_ZONES` slots, and their mask.

    Raises:
        InputError: more zones than slots.
    """
    boxes = np.zeros((MAX_ZONES, 4), np.float32)
    mask = np.zeros(MAX_ZONES, bool)
    if zones is not None:
        given = np.asarray(zones.boxes, np.float32).reshape(-1, 4)
        if len(given) > MAX_ZONES:
            raise InputError(f"{len(given)} zones; CMT takes at most {MAX_ZONES}")
        boxes[: len(given)] = given
        mask[: len(given)] = True
    return jnp.asarray(boxes), jnp.asarray(mask)


def cmt_params(config: CMTConfig, zones: SceneZones | None = None) -> CMTParams:
    """The default :class:`~jaxtrack.filters.cmt.CMTParams` with the scene's zones."""
    boxes, mask = zone_arrays(zones)
    return CMTParams(
        mixture=MixtureParams(
            motion_noise_std=jnp.array(DEFAULT_MOTION_NOISE_STD, jnp.float32),
            measurement_noise_std=jnp.array(DEFAULT_MEASUREMENT_NOISE_STD, jnp.float32),
            background_log_likelihood=jnp.float32(BACKGROUND_LOG_LIKELIHOOD),
            min_mixture_weight=jnp.float32(MIN_MIXTURE_WEIGHT),
            min_log_support=jnp.float32(MIN_LOG_SUPPORT),
            birth_log_likelihood=jnp.float32(BIRTH_LOG_LIKELIHOOD),
        ),
        proposal=default_cpd_params()._replace(
            group_area_ratio=jnp.float32(config.group_area_ratio)
        ),
        observation=default_com_params()._replace(
            information_correction=jnp.float32(config.information_correction)
        ),
        appearance_weight=jnp.float32(config.appearance_weight),
        duplicate_iou=jnp.float32(DUPLICATE_IOU),
        confirm_score=jnp.float32(CONFIRM_SCORE),
        confirm_quantile=jnp.float32(config.confirm_quantile),
        enter_distance=jnp.float32(ENTER_DISTANCE),
        zone_boxes=boxes,
        zone_mask=mask,
        velocity_rate=jnp.float32(config.velocity_rate),
        exchange_margin=jnp.float32(max(config.exchange_margin, 0.0)),
    )


def build_cmt(
    config: CMTConfig, info: SequenceInfo, context: Any = None, variant: str = "GM"
) -> tuple[Filter, CMTParams]:
    """CMT of a configuration: ``(filter, params)``; ``context`` is the scene's
    :class:`~jaxtrack.context.zones.SceneZones` (or None: no zones, no exits sampled).

    Raises:
        InputError: a context that is not zones, or a context variant other than GM.
    """
    if context is not None and not isinstance(context, SceneZones):
        raise InputError("CMT takes entry/exit zones (--zones), not a learned PHD context")
    if variant != "GM":
        raise InputError(f"context variant {variant!r} is for the PHD tracker")
    filt = _cmt_filter(
        config.variant,
        config.max_components,
        config.particles_per_component,
        config.max_misses,
        config.group_area_ratio > 0,
        config.velocity_rate > 0,
        reidentify_frames(config, info),
        config.free_blob_frames,
        config.support == "box",
        config.exchange_margin >= 0,
    )
    return filt, cmt_params(config, context)


def reidentify_frames(config: CMTConfig, info: SequenceInfo) -> int:
    """``reidentify_seconds`` in frames of the sequence (at least 1 when it is on;
    :func:`~jaxtrack.filters.base.frame_rate`)."""
    if config.reidentify_seconds <= 0:
        return 0
    return max(1, round(config.reidentify_seconds * frame_rate(info)))


@functools.lru_cache(maxsize=8)
def _cmt_filter(*settings) -> Filter:
    # Group blobs off (a ratio of 0): their code is compiled out (the ratio is a frozen
    # parameter, so no sweep or tuning can turn them on behind the configuration's back);
    # likewise the merge velocity at a rate of 0.
    return cmt_filter(*settings)


def cmt_memory_estimate(config: CMTConfig, capacity: int, chunk_frames: int) -> MemoryEstimate:
    """CMT's memory for a detection capacity, from the sizes (no compile; frames left out).

    The state holds each particle (6 floats + weight) twice, the appearance models and
    histograms (``F (V + 1)`` floats per slot); a step's temporaries are dominated by every
    particle's patch samples and features (about ``(4 x 128 + 4 F)`` bytes per particle,
    :data:`~jaxtrack.appearance.DEFAULT_PATCH_SHAPE`) and the ``[particles, detections]``
    likelihoods; the per-frame outputs are two track tables.
    """
    slots = config.max_components
    particles = slots * config.particles_per_component
    features = num_features()
    state = 2 * (28 * particles + 4 * slots * features * (NUM_VALUES + 1) + 64 * slots)
    temporaries = particles * (4 * 128 * 3 + 8 * features + 8 * capacity)
    frame_output = 2 * 25 * slots
    chunk = state + temporaries + chunk_frames * (DETECTION_SLOT_BYTES * capacity + frame_output)
    return MemoryEstimate(chunk_bytes=int(chunk + (1 << 16)), frame_output_bytes=frame_output)


def cmt_properties(params: CMTParams) -> CMTParams:
    """The parameter-properties tree of :class:`~jaxtrack.filters.cmt.CMTParams`: named (log
    transform, frozen by default) the SDV noise scales ``motion_noise_std`` and
    ``measurement_noise_std`` and the ``appearance_weight``."""
    props = frozen_properties(params)

    def named(name: str) -> ParameterProperties:
        return ParameterProperties(trainable=False, transform=LOG, name=name)

    return props._replace(
        mixture=props.mixture._replace(
            motion_noise_std=named("motion_noise_std"),
            measurement_noise_std=named("measurement_noise_std"),
        ),
        appearance_weight=named("appearance_weight"),
    )
