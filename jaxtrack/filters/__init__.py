"""Filters: the particle PHD tracker, resampling, state extraction, the sequence runner."""

from jaxtrack.association.estimates import Estimates
from jaxtrack.filters.base import Filter, run
from jaxtrack.filters.extraction import gmm_clusters, measurement_partition
from jaxtrack.filters.phd import (
    PHDInfo,
    PHDParams,
    PHDState,
    phd_filter,
    phd_update,
    score_log_ratio,
)
from jaxtrack.filters.phd_defaults import (
    default_phd_params,
    uniform_birth_intensity,
    uniform_clutter_intensity,
)
from jaxtrack.filters.resampling import (
    multinomial,
    resample,
    residual,
    stratified,
    systematic,
)

__all__ = [
    "Estimates",
    "Filter",
    "PHDInfo",
    "PHDParams",
    "PHDState",
    "default_phd_params",
    "gmm_clusters",
    "measurement_partition",
    "multinomial",
    "phd_filter",
    "phd_update",
    "resample",
    "residual",
    "run",
    "score_log_ratio",
    "stratified",
    "systematic",
    "uniform_birth_intensity",
    "uniform_clutter_intensity",
]
