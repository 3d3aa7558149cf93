"""Tunable PHD parameters in an unconstrained space, with a trainable/frozen flag each.

Gradient-based tuning (DESIGN.md) optimises every constrained parameter through an explicit
bijection to the real line, so that any optax optimiser can take unconstrained steps:

* rates and scales (``> 0``) through ``log``: ``theta = log(value)``, ``value = exp(theta)``;
* probabilities (``(0, 1)``) through ``logit``: ``theta = log(p / (1 - p))``,
  ``p = sigmoid(theta)``.

:data:`PARAMETERS` names the tunable parameters of :class:`~jaxtrack.filters.phd.PHDParams`:
the clutter and birth magnitudes ``lambda_r``, ``lambda_s`` (PHD-context eq. 19-20; the birth
rate sets both the birth and the first frame's initial intensity, as ``birth_rate`` of the
tracker configuration does), the detection and survival probabilities and the SDV motion and
measurement noise scales. A :class:`ParameterSpace` holds the trainable subset; the others
are frozen at their values in the base parameters. :func:`to_config` writes the tuned values
that the tracker configuration of ``jaxtrack track --config`` carries.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any, Literal, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

from jaxtrack.errors import InputError
from jaxtrack.filters.phd import PHDParams

#: Probabilities are clipped to ``[PROB_EPS, 1 - PROB_EPS]`` before the logit.
PROB_EPS = 1e-6


class Tunable(NamedTuple):
    """One tunable parameter.

    Attributes:
        paths: dotted leaf paths in :class:`~jaxtrack.filters.phd.PHDParams` that it sets
            (all to the same value).
        transform: ``"log"`` (positive values) or ``"logit"`` (probabilities).
        description: what it is, in words.
    """

    paths: tuple[str, ...]
    transform: Literal["log", "logit"]
    description: str


#: The tunable parameters, by name; each name is also the key of the tracker configuration
#: (:data:`~jaxtrack.filters.phd_tracker.DEFAULT_CONFIG`) that carries it.
PARAMETERS: dict[str, Tunable] = {
    "clutter_rate": Tunable(
        ("clutter_intensity.magnitude",),
        "log",
        "lambda_r, expected false detections per frame",
    ),
    "birth_rate": Tunable(
        ("birth_intensity.magnitude", "initial_intensity.magnitude"),
        "log",
        "lambda_s, expected births per frame (also the first frame's initial intensity)",
    ),
    "detection_prob": Tunable(("detection_prob",), "logit", "pD = 1 - pM"),
    "survival_prob": Tunable(("survival_prob",), "logit", "e(x), a constant"),
    "motion_noise_std": Tunable(
        ("motion_noise_std",),
        "log",
        "SDV dynamics noise (sigma_n1, sigma_n2, nw, nh)",
    ),
    "measurement_noise_std": Tunable(
        ("measurement_noise_std",),
        "log",
        "SDV likelihood noise (s_1, s_2, s_w, s_h)",
    ),
}

#: The parameters tuned by default.
DEFAULT_TRAINABLE = ("clutter_rate", "birth_rate", "detection_prob")


def get_path(tree: Any, path: str) -> Any:
    """The leaf of a NamedTuple PyTree at a dotted path (``"clutter_intensity.magnitude"``)."""
    for name in path.split("."):
        tree = getattr(tree, name)
    return tree


def set_path(tree: Any, path: str, value: Any) -> Any:
    """``tree`` with the leaf at a dotted path replaced by ``value`` (pure)."""
    head, _, rest = path.partition(".")
    child = value if not rest else set_path(getattr(tree, head), rest, value)
    return tree._replace(**{head: child})


def forward(transform: str, theta: Array) -> Array:
    """Unconstrained ``theta`` to the constrained value (``exp`` or ``sigmoid``)."""
    return jnp.exp(theta) if transform == "log" else jax.nn.sigmoid(theta)


def inverse(transform: str, value: Array) -> Array:
    """Constrained value to ``theta`` (``log`` or ``logit``; probabilities are clipped)."""
    value = jnp.asarray(value, jnp.float32)
    if transform == "log":
        return jnp.log(value)
    clipped = jnp.clip(value, PROB_EPS, 1 - PROB_EPS)
    return jnp.log(clipped) - jnp.log1p(-clipped)


class ParameterSpace(NamedTuple):
    """The trainable parameters (names of :data:`PARAMETERS`); all others are frozen.

    ``theta`` is a dict ``{name: unconstrained array}`` of the trainable parameters, the
    PyTree the optimiser updates.
    """

    trainable: tuple[str, ...]

    def to_unconstrained(self, params: PHDParams) -> dict[str, Array]:
        """``theta`` of the trainable parameters at their values in ``params``.

        Raises:
            InputError: a value outside its domain (a rate <= 0, a probability outside
                ``(0, 1]``), or a survival probability that is a map, not a constant.
        """
        theta = {}
        for name in self.trainable:
            spec = PARAMETERS[name]
            value = get_path(params, spec.paths[0])
            if not isinstance(value, jax.Array | np.ndarray | float | int):
                raise InputError(f"{name} is not a plain array here and cannot be tuned")
            value = np.asarray(value, np.float64)
            if spec.transform == "log" and not np.all(value > 0):
                raise InputError(f"{name} must be positive to be tuned, got {value}")
            if spec.transform == "logit" and not np.all((value > 0) & (value <= 1)):
                raise InputError(f"{name} must lie in (0, 1] to be tuned, got {value}")
            theta[name] = inverse(spec.transform, value)
        return theta

    def to_params(self, theta: Mapping[str, Array], base: PHDParams) -> PHDParams:
        """``base`` with the trainable parameters set from ``theta`` (differentiable)."""
        params = base
        for name in self.trainable:
            spec = PARAMETERS[name]
            value = forward(spec.transform, theta[name])
            for path in spec.paths:
                leaf = get_path(base, path)
                params = set_path(params, path, value.astype(jnp.asarray(leaf).dtype))
        return params

    def values(self, theta: Mapping[str, Array]) -> dict[str, np.ndarray]:
        """The constrained values of ``theta`` as NumPy arrays (for histories and reports)."""
        return {
            name: np.asarray(forward(PARAMETERS[name].transform, theta[name]))
            for name in self.trainable
        }


def parameter_space(
    trainable: Iterable[str] = DEFAULT_TRAINABLE, frozen: Iterable[str] = ()
) -> ParameterSpace:
    """A :class:`ParameterSpace` from trainable names minus frozen ones.

    Args:
        trainable: names of :data:`PARAMETERS` to tune.
        frozen: names to keep fixed even if listed in ``trainable``.

    Returns:
        The space, names in :data:`PARAMETERS` order.

    Raises:
        InputError: an unknown name, or nothing left to tune.
    """
    trainable, frozen = set(trainable), set(frozen)
    unknown = sorted((trainable | frozen) - set(PARAMETERS))
    if unknown:
        raise InputError(
            f"unknown tunable parameter(s) {', '.join(unknown)}; known: {', '.join(PARAMETERS)}"
        )
    names = tuple(name for name in PARAMETERS if name in trainable - frozen)
    if not names:
        raise InputError("no parameter left to tune (all frozen)")
    return ParameterSpace(names)


def to_config(params: PHDParams, config: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The tracker configuration overrides carrying the tuned parameters.

    Args:
        params: the (tuned) parameters.
        config: configuration overrides to keep (e.g. ``num_particles``); may be None.

    Returns:
        ``config`` with every parameter of :data:`PARAMETERS` (rates, probabilities, noise
        scales as lists) set from ``params`` (:func:`parameter_values`): a JSON object that
        ``jaxtrack track --config`` accepts.
    """
    return {**(config or {}), **parameter_values(params, tuple(PARAMETERS))}


def parameter_values(params: PHDParams, names: tuple[str, ...]) -> dict[str, float | list]:
    """The named parameters' values in ``params``, rounded for JSON (:func:`round_significant`)."""
    return {name: round_significant(get_path(params, PARAMETERS[name].paths[0])) for name in names}


def round_significant(value: Any) -> float | list:
    """A scalar or array as floats (nested lists) rounded to 6 significant digits."""
    array = np.asarray(value, np.float64)
    if array.ndim:
        return [round_significant(v) for v in array]
    return float(f"{float(array):.6g}")
