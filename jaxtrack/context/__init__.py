"""jaxtrack.context: learned scene context (birth and clutter intensities, PHD-context Sec. IV).

:mod:`~jaxtrack.context.intensity` holds the :class:`Intensity` PyTree the PHD filter
consumes; :mod:`~jaxtrack.context.map_em` learns its density by recursive MAP-EM;
:mod:`~jaxtrack.context.io` saves and loads a learned context.
"""

from jaxtrack.context.intensity import (
    Intensity,
    log_density,
    log_intensity,
    uniform_intensity,
)
from jaxtrack.context.io import load_context, load_context_parts, save_context
from jaxtrack.context.map_em import (
    MapEMLearner,
    MixtureState,
    dirichlet_beta,
    estimate_magnitude,
    fit,
    grid_init_birth,
    grid_init_clutter,
    init_state,
    map_em_learner,
    num_free_parameters,
    to_intensity,
)

__all__ = [
    "Intensity",
    "MapEMLearner",
    "MixtureState",
    "dirichlet_beta",
    "estimate_magnitude",
    "fit",
    "grid_init_birth",
    "grid_init_clutter",
    "init_state",
    "load_context",
    "load_context_parts",
    "log_density",
    "log_intensity",
    "map_em_learner",
    "num_free_parameters",
    "save_context",
    "to_intensity",
    "uniform_intensity",
]
