"""Differentiable filtering and gradient-based tuning of the PHD tracker (optax).

* :mod:`~jaxtrack.tuning.transforms`: the tunable parameters, their log / logit transforms,
  trainable / frozen flags, and the tracker configuration they map to.
* :mod:`~jaxtrack.tuning.objectives`: the unsupervised PHD log-likelihood and the supervised
  relaxed-GOSPA objectives over a sequence, with a choice of resampling gradient estimator.
The host loop that drives them, :func:`jaxtrack.pipelines.tuner.tune` (optax optimisation with
common random numbers, early stopping and a history), is in the pipelines layer.
"""

from jaxtrack.tuning.objectives import (
    ESTIMATORS,
    Objective,
    likelihood_objective,
    make_objective,
    relaxed_gospa,
    supervised_objective,
    tuning_filter,
)
from jaxtrack.tuning.transforms import (
    DEFAULT_TRAINABLE,
    ParameterSpace,
    parameter_space,
    to_config,
)

__all__ = [
    "DEFAULT_TRAINABLE",
    "ESTIMATORS",
    "Objective",
    "ParameterSpace",
    "likelihood_objective",
    "make_objective",
    "parameter_space",
    "relaxed_gospa",
    "supervised_objective",
    "to_config",
    "tuning_filter",
]
