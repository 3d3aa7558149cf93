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

from jaxtrack.configs import MAX_GAP, OUTPUT, Rule, TrackerConfig, setting
from jaxtrack.errors import InputError
from jaxtrack.filters.base import Filter
from jaxtrack.filters.kalman import KALMAN_PRESETS, KalmanParams, kalman_filter
from jaxtrack.parameters import LOG, ParameterProperties, frozen_properties
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


@functools.lru_cache(maxsize=4)
def _kalman_filter(cost: str) -> Filter:
    return kalman_filter(cost=cost)


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
