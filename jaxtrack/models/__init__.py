"""Single-target models of the PHD filter: SDV / constant-noise dynamics and likelihood."""

from jaxtrack.models.dynamics import (
    MEASURED,
    POSITION,
    SIZE,
    STATE_DIM,
    VELOCITY,
    noise_gain,
    sample_constant_velocity,
    transition_matrix,
)
from jaxtrack.models.likelihood import MEAS_DIM, log_likelihood
from jaxtrack.models.noise import NoiseModel, constant_std, state_dependent_std
from jaxtrack.models.survival import SurvivalMap, survival_probability

__all__ = [
    "MEASURED",
    "MEAS_DIM",
    "POSITION",
    "SIZE",
    "STATE_DIM",
    "VELOCITY",
    "NoiseModel",
    "SurvivalMap",
    "constant_std",
    "log_likelihood",
    "noise_gain",
    "sample_constant_velocity",
    "state_dependent_std",
    "survival_probability",
    "transition_matrix",
]
