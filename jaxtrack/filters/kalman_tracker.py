"""The Kalman data-association tracker's configuration (``jaxtrack track --tracker kalman``).

:class:`KalmanConfig` picks a preset of :data:`~jaxtrack.filters.kalman.KALMAN_PRESETS`
(``"default"``: Mahalanobis gate; ``"sort"``: SORT's IoU gate and ages) and the output
post-processing shared with every tracker; :func:`build_kalman` is the tracker's registry
entry (:mod:`jaxtrack.filters.registry`).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, ClassVar

import numpy as np

from jaxtrack.configs import MAX_GAP, OUTPUT, SMOOTHING, Rule, TrackerConfig, setting
from jaxtrack.errors import InputError
from jaxtrack.filters.base import Filter
from jaxtrack.filters.kalman import KALMAN_PRESETS, KalmanParams, kalman_filter
from jaxtrack.parameters import LOG, ParameterProperties, frozen_properties
from jaxtrack.resources import DETECTION_SLOT_BYTES, MemoryEstimate
from jaxtrack.types import SequenceInfo


@dataclasses.dataclass(frozen=True)
class KalmanConfig(TrackerConfig):
    """The Kalman DA tracker's configuration (``jaxtrack track --tracker kalman``)."""

    tracker: ClassVar[str] = "kalman"

    preset: str = setting(
        "default",
        Rule(
            "'default' (Mahalanobis gate, score >= 0.9) or 'sort' (SORT's IoU gate and ages)",
            str,
            choices=tuple(KALMAN_PRESETS),
        ),
    )
    output: str = setting("offline", OUTPUT)
    max_gap: int = setting(8, MAX_GAP)
    smoothing: str = setting("none", SMOOTHING)


def build_kalman(
    config: KalmanConfig, info: SequenceInfo, context: Any = None, variant: str = "GM"
) -> tuple[Filter, KalmanParams]:
    """The Kalman tracker of a configuration: ``(filter, params)`` (the filter is cached).

    Raises:
        InputError: a context was given (the Kalman tracker has no clutter or birth model).
    """
    del info, variant
    if context is not None:
        raise InputError("the Kalman tracker takes no context (--context is for the PHD tracker)")
    preset = KALMAN_PRESETS[config.preset]
    return _kalman_filter(preset.cost), preset.params()


#: Track-table slots of the Kalman tracker.
MAX_TRACKS = 64


@functools.lru_cache(maxsize=4)
def _kalman_filter(cost: str) -> Filter:
    return kalman_filter(max_tracks=MAX_TRACKS, cost=cost)


# Bytes of the Kalman tracker's chunk (:func:`kalman_memory_estimate`).
#: Per track slot of the state: identity, flags, counters (14), mean (24), covariance (144).
_TRACK_STATE = 186
#: Per track slot of the per-frame outputs: ``tracks`` and ``candidates`` (25 bytes each).
_TRACK_OUTPUT = 50
#: Temporaries per detection slot: the ``[max_tracks, max_detections]`` costs, gates and
#: assignment arrays (about 6 float32 per track).
_SLOT_TEMP = 26 * MAX_TRACKS
#: Small buffers, whatever the sizes, and the parameters.
_FIXED = 1 << 15


def kalman_memory_estimate(
    config: KalmanConfig, capacity: int, chunk_frames: int
) -> MemoryEstimate:
    """The Kalman tracker's memory for a detection capacity, from the sizes (no compile).

    A compiled chunk of ``K = chunk_frames`` frames and ``C = capacity`` slots holds the
    state twice (``186`` bytes per track slot), the chunk's padded detections (``21 K C``),
    its per-frame outputs (``50`` bytes per track slot and frame, whatever ``C``) and XLA's
    temporaries, ``26 max_tracks C`` bytes (``[max_tracks, max_detections]`` arrays) plus 32
    KB. Fitted to ``compiled.memory_analysis()`` (CPU) over 16 to 4096 slots for both presets:
    within 25% (``tests/filters/test_memory.py``).

    Args:
        config: the configuration (the estimate is the same for both presets).
        capacity: detection slots per frame.
        chunk_frames: frames per compiled call.

    Returns:
        The :class:`~jaxtrack.resources.MemoryEstimate`.
    """
    del config
    frame_output = _TRACK_OUTPUT * MAX_TRACKS + 1
    chunk = (
        2 * _TRACK_STATE * MAX_TRACKS
        + chunk_frames * (DETECTION_SLOT_BYTES * capacity + 12 + frame_output)
        + _SLOT_TEMP * capacity
        + _FIXED
    )
    return MemoryEstimate(chunk_bytes=int(chunk), frame_output_bytes=int(frame_output))


def kalman_properties(params: KalmanParams) -> KalmanParams:
    """The parameter-properties tree of :class:`~jaxtrack.filters.kalman.KalmanParams`.

    Named (log transform, all frozen by default): the SDV noise scales
    ``motion_noise_std``, ``measurement_noise_std`` and ``initial_velocity_std``.
    """
    props = frozen_properties(params)
    return props._replace(
        **{
            name: ParameterProperties(trainable=False, transform=LOG, name=name)
            for name in ("motion_noise_std", "measurement_noise_std", "initial_velocity_std")
        }
    )


def kalman_description(config: KalmanConfig) -> dict[str, Any]:
    """The preset's assignment cost and parameters, for the ``.config.json`` of a run."""
    chosen = KALMAN_PRESETS[config.preset]
    return {
        "cost": chosen.cost,
        "params": {name: _json_numbers(v) for name, v in chosen.params()._asdict().items()},
    }


def _json_numbers(value) -> float | str | list:
    """Numbers of an array for JSON: rounded to 6 decimals, ``"inf"`` for infinity."""
    array = np.round(np.asarray(value, np.float64), 6)
    if array.ndim:
        return [_json_numbers(item) for item in array]
    return float(array) if np.isfinite(array) else str(float(array))
