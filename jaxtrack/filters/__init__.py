"""Filters: the particle PHD tracker, the Kalman DA baseline, resampling, state extraction,
the sequence runners."""

from jaxtrack.association.estimates import Estimates
from jaxtrack.filters.base import Filter, run, run_batch
from jaxtrack.filters.extraction import gmm_clusters, measurement_partition
from jaxtrack.filters.kalman import (
    KalmanInfo,
    KalmanParams,
    KalmanState,
    default_kalman_params,
    kalman_filter,
    sort_kalman_params,
)
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
    "KalmanInfo",
    "KalmanParams",
    "KalmanState",
    "PHDInfo",
    "PHDParams",
    "PHDState",
    "default_kalman_params",
    "default_phd_params",
    "gmm_clusters",
    "kalman_filter",
    "measurement_partition",
    "multinomial",
    "phd_filter",
    "phd_update",
    "resample",
    "residual",
    "run",
    "run_batch",
    "score_log_ratio",
    "sort_kalman_params",
    "stratified",
    "systematic",
    "uniform_birth_intensity",
    "uniform_clutter_intensity",
]
