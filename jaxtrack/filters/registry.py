"""The tracker registry: every tracker plugs in the same way (``jaxtrack track --tracker NAME``).

A tracker is a :class:`TrackerEntry`: its frozen configuration type
(:class:`~jaxtrack.configs.TrackerConfig`), one function from (configuration, sequence info,
optional context, variant) to ``(Filter, params)``, and the parameter-properties tree of its
params (:mod:`jaxtrack.parameters`). Builders return the same filter object for the same
static setting, so compiled functions (cached per filter) are shared by every caller. A
tracker that looks at the images (``uses_frames``) steps on
:class:`~jaxtrack.types.FrameInputs` and is run with the frames streamed
(:mod:`jaxtrack.pipelines.stream`); the others step on :class:`~jaxtrack.types.Detections`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

from jaxtrack.configs import TrackerConfig
from jaxtrack.errors import InputError
from jaxtrack.filters.base import Filter
from jaxtrack.filters.cmt import VARIANTS as CMT_VARIANTS
from jaxtrack.filters.cmt import CMTParams
from jaxtrack.filters.cmt_tracker import (
    CMTConfig,
    build_cmt,
    cmt_memory_estimate,
    cmt_properties,
)
from jaxtrack.filters.fusion import FusionParams
from jaxtrack.filters.fusion_tracker import (
    FusionConfig,
    build_fusion,
    fusion_memory_estimate,
    fusion_properties,
)
from jaxtrack.filters.hierarchical import HierarchicalParams
from jaxtrack.filters.hierarchical_tracker import VARIANTS as HIERARCHICAL_VARIANTS
from jaxtrack.filters.hierarchical_tracker import (
    HierarchicalConfig,
    build_hierarchical,
    hierarchical_memory_estimate,
    hierarchical_properties,
)
from jaxtrack.filters.hierarchical_tracker import writes_events as hierarchical_events
from jaxtrack.filters.kalman import KalmanParams
from jaxtrack.filters.kalman_tracker import (
    KalmanConfig,
    build_kalman,
    kalman_memory_estimate,
    kalman_properties,
)
from jaxtrack.filters.phd import PHDParams
from jaxtrack.filters.phd_tracker import (
    PHDConfig,
    build_phd,
    phd_memory_estimate,
    phd_properties,
)
from jaxtrack.resources import MemoryEstimate
from jaxtrack.types import SequenceInfo


class TrackerEntry(NamedTuple):
    """One registered tracker.

    Attributes:
        config_type: its configuration dataclass.
        params_type: its parameter PyTree type (a tuple of types for a tracker whose
            variants have different parameters, as ``isinstance`` takes).
        build: ``(config, info, context=None, variant="GM") -> (Filter, params)``.
        properties: ``params -> properties tree``.
        takes_context: whether it uses a learned context (``--context``).
        memory: ``(config, capacity, chunk_frames) -> MemoryEstimate``, the memory of a run
            with ``capacity`` detection slots per frame, from the sizes (no compile; a
            tracker that uses frames leaves out the chunk's images, which the stream adds).
        uses_frames: whether its filter steps on :class:`~jaxtrack.types.FrameInputs`
            (detections and the frame) rather than on detections alone.
        takes_zones: whether it uses the scene's entry/exit zones (``--zones``; given to
            ``build`` as its context, a :class:`~jaxtrack.context.zones.SceneZones`).
        takes_background: whether it compares targets with the background model's image
            (given to ``build`` as its context by the pipelines,
            :func:`~jaxtrack.pipelines.background.median_background`).
        takes_training: whether it learns its context from a training span of the tracked
            sequence (``--train-frames``; the pipelines give ``build`` a
            :class:`~jaxtrack.filters.fusion_tracker.FusionContext`,
            :func:`~jaxtrack.pipelines.fusion_context.learn_fusion_context`).
        writes_events: ``config -> bool``, whether a run of that configuration has event
            states to write beside the results (``RES.events.csv``,
            :mod:`~jaxtrack.io.events`; its info has ``events`` and ``event_ids``).
        variants: the values of its configuration's ``variant`` (``--variant`` picks one),
            empty for a tracker without variants.
    """

    config_type: type[TrackerConfig]
    params_type: type | tuple[type, ...]
    build: Callable[..., tuple[Filter, Any]]
    properties: Callable[[Any], Any]
    takes_context: bool
    memory: Callable[[Any, int, int], MemoryEstimate]
    uses_frames: bool = False
    takes_zones: bool = False
    takes_background: bool = False
    takes_training: bool = False
    writes_events: Callable[[Any], bool] = lambda config: False
    variants: tuple[str, ...] = ()


#: The trackers, by name.
TRACKERS: dict[str, TrackerEntry] = {
    "phd": TrackerEntry(PHDConfig, PHDParams, build_phd, phd_properties, True, phd_memory_estimate),
    "kalman": TrackerEntry(
        KalmanConfig, KalmanParams, build_kalman, kalman_properties, False, kalman_memory_estimate
    ),
    "cmt": TrackerEntry(
        CMTConfig,
        CMTParams,
        build_cmt,
        cmt_properties,
        takes_context=False,
        memory=cmt_memory_estimate,
        uses_frames=True,
        takes_zones=True,
        variants=CMT_VARIANTS,
    ),
    "hierarchical": TrackerEntry(
        HierarchicalConfig,
        (HierarchicalParams, KalmanParams),
        build_hierarchical,
        hierarchical_properties,
        takes_context=False,
        memory=hierarchical_memory_estimate,
        uses_frames=True,
        takes_background=True,
        writes_events=hierarchical_events,
        variants=HIERARCHICAL_VARIANTS,
    ),
    "fusion": TrackerEntry(
        FusionConfig,
        FusionParams,
        build_fusion,
        fusion_properties,
        takes_context=False,
        memory=fusion_memory_estimate,
        uses_frames=True,
        takes_training=True,
    ),
}


def writes_events(config: TrackerConfig) -> bool:
    """Whether a run of ``config`` writes event states (``RES.events.csv``)."""
    return tracker_entry(config.tracker).writes_events(config)


def tracker_entry(name: str) -> TrackerEntry:
    """The registered tracker ``name``.

    Raises:
        InputError: an unknown name.
    """
    if name not in TRACKERS:
        raise InputError(f"unknown tracker {name!r}; known: {', '.join(TRACKERS)}")
    return TRACKERS[name]


def build_tracker(
    config: TrackerConfig, info: SequenceInfo, context: Any = None, variant: str = "GM"
) -> tuple[Filter, Any]:
    """``(Filter, params)`` of a configuration for a sequence (dispatch on the config type).

    Raises:
        InputError: a configuration of no registered tracker, a bad variant or context.
    """
    return tracker_entry(config.tracker).build(config, info, context, variant)


def properties_of(params: Any) -> Any:
    """The parameter-properties tree of a registered tracker's params (by their type).

    Raises:
        InputError: params of no registered tracker.
    """
    for entry in TRACKERS.values():
        if isinstance(params, entry.params_type):
            return entry.properties(params)
    raise InputError(f"{type(params).__name__} are not the parameters of a registered tracker")
