"""The trainable parameters of a tuning run, in an unconstrained space.

Gradient-based tuning (DESIGN.md) optimises every constrained parameter through an explicit
bijection to the real line, so that any optax optimiser can take unconstrained steps. Which
leaves are tunable, their transforms (``log`` for rates and scales, ``logit`` for
probabilities) and their names come from the tracker's parameter-properties tree
(:mod:`jaxtrack.parameters`; for the PHD tracker
:func:`~jaxtrack.filters.phd_tracker.phd_properties`), the same tree the sweep uses, so a name
means the same leaf everywhere: ``birth_rate`` is ``lambda_s``, the birth intensity's
magnitude, and never the first frame's ``initial_rate``.

A :class:`ParameterSpace` is that tree with the trainable subset flagged; the others are
frozen at their values in the base parameters. :func:`to_config` writes tuned values into
the tracker configuration that ``jaxtrack track --config`` reads.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any, NamedTuple

import numpy as np
from jaxtyping import Array

from jaxtrack.configs import TrackerConfig
from jaxtrack.errors import InputError
from jaxtrack.filters.registry import properties_of
from jaxtrack.parameters import (
    check_names,
    constrained,
    from_unconstrained,
    leaf_values,
    named_leaves,
    to_unconstrained,
    trainable_names,
    with_trainable,
)

#: The parameters tuned by default.
DEFAULT_TRAINABLE = ("clutter_rate", "birth_rate", "detection_prob")


class ParameterSpace(NamedTuple):
    """The parameter-properties tree of a tracker's params, with the trainable leaves flagged.

    ``theta`` is a dict ``{name: unconstrained array}`` of the trainable parameters, the
    PyTree the optimiser updates.
    """

    properties: Any

    @property
    def trainable(self) -> tuple[str, ...]:
        """Names of the trainable parameters, in the params' tree order."""
        return trainable_names(self.properties)

    def to_unconstrained(self, params: Any) -> dict[str, Array]:
        """``theta`` of the trainable parameters at their values in ``params``.

        Raises:
            InputError: a value outside its domain (a rate <= 0, a probability outside
                ``(0, 1]``).
        """
        return to_unconstrained(params, self.properties)

    def to_params(self, theta: Mapping[str, Array], base: Any) -> Any:
        """``base`` with the trainable parameters set from ``theta`` (differentiable)."""
        return from_unconstrained(theta, base, self.properties)

    def values(self, theta: Mapping[str, Array]) -> dict[str, np.ndarray]:
        """The constrained values of ``theta`` as NumPy arrays (for histories and reports)."""
        return {name: np.asarray(v) for name, v in constrained(theta, self.properties).items()}


def tunable_names(params: Any) -> tuple[str, ...]:
    """Every named (tunable) parameter of a registered tracker's params."""
    return tuple(named_leaves(properties_of(params)))


def parameter_space(
    params: Any, trainable: Iterable[str] = DEFAULT_TRAINABLE, frozen: Iterable[str] = ()
) -> ParameterSpace:
    """A :class:`ParameterSpace` for ``params``: trainable names minus frozen ones.

    Args:
        params: the parameters of a registered tracker (their properties tree names them).
        trainable: names to tune.
        frozen: names to keep fixed even if listed in ``trainable``.

    Returns:
        The space.

    Raises:
        InputError: an unknown name, nothing left to tune, or a name whose leaf is not a
            plain array here (a survival map).
    """
    trainable, frozen = tuple(trainable), set(frozen)
    properties = properties_of(params)
    check_names(properties, (*trainable, *sorted(frozen)), "tunable parameter")
    names = tuple(name for name in trainable if name not in frozen)
    if not names:
        raise InputError("no parameter left to tune (all frozen)")
    return ParameterSpace(with_trainable(properties, names))


def to_config(
    params: Any, config: TrackerConfig, names: Iterable[str] | None = None
) -> TrackerConfig:
    """``config`` with the named parameters that it carries set from ``params``.

    Args:
        params: the (tuned) parameters.
        config: the configuration to update (e.g. the one the tuning started from).
        names: the parameters to write (those the configuration carries); default all.

    Returns:
        The updated configuration (values rounded by :func:`round_significant`).
    """
    names = tunable_names(params) if names is None else tuple(names)
    carried = tuple(name for name in names if name in config.rules())
    return config.replace(**parameter_values(params, carried))


def parameter_values(params: Any, names: tuple[str, ...]) -> dict[str, float | list]:
    """The named parameters' values in ``params``, rounded for JSON (:func:`round_significant`)."""
    values = leaf_values(params, properties_of(params), names)
    return {name: round_significant(value) for name, value in values.items()}


def round_significant(value: Any) -> float | list:
    """A scalar or array as floats (nested lists) rounded to 6 significant digits."""
    array = np.asarray(value, np.float64)
    if array.ndim:
        return [round_significant(v) for v in array]
    return float(f"{float(array):.6g}")
