"""Parameter properties: which leaves of a parameter PyTree are tunable, and how (base layer).

In the style of dynamax's ``ParameterProperties``: for a tracker's parameter PyTree
(e.g. :class:`~jaxtrack.filters.phd.PHDParams`) a *properties tree* of the same structure
holds one :class:`ParameterProperties` per leaf, saying whether it is trainable, through
which bijection it is optimised, and its display name (the configuration key that carries
it). The sweep (:mod:`jaxtrack.sweep`) and the tuner (:mod:`jaxtrack.tuning`) both address
parameters through this one tree; no table of dotted paths exists elsewhere.

Transforms map the unconstrained real line to the parameter's domain:

* ``LOG``: rates and scales ``> 0``, ``value = exp(theta)``;
* ``LOGIT``: probabilities in ``(0, 1)``, ``value = sigmoid(theta)``;
* ``SHARE``: a mixture's share in ``[0, 1)`` (the uniform share of a learned density),
  ``value = sigmoid(theta)``; 1 is refused: the density is then uniform and its share
  means nothing;
* ``IDENTITY``: unconstrained values.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

from jaxtrack.errors import InputError

#: Probabilities are clipped to ``[PROB_EPS, 1 - PROB_EPS]`` before the logit.
PROB_EPS = 1e-6


@dataclasses.dataclass(frozen=True)
class Transform:
    """A bijection from the real line to a parameter's domain.

    Attributes:
        name: ``"log"``, ``"logit"`` or ``"identity"``.
        forward: unconstrained ``theta`` to the constrained value.
        inverse: constrained value to ``theta``.
        domain: the domain in words (for errors).
        contains: True where a value lies in the domain.
    """

    name: str
    forward: Callable[[Array], Array]
    inverse: Callable[[Array], Array]
    domain: str
    contains: Callable[[np.ndarray], np.ndarray]


def _logit(value: Array) -> Array:
    clipped = jnp.clip(value, PROB_EPS, 1 - PROB_EPS)
    return jnp.log(clipped) - jnp.log1p(-clipped)


LOG = Transform("log", jnp.exp, jnp.log, "> 0", lambda v: v > 0)
LOGIT = Transform("logit", jax.nn.sigmoid, _logit, "(0, 1]", lambda v: (v > 0) & (v <= 1))
SHARE = Transform(
    "logit",
    jax.nn.sigmoid,
    _logit,
    "in [0, 1) (1 is a uniform density, with no learned part to share with)",
    lambda v: (v >= 0) & (v < 1),
)
IDENTITY = Transform("identity", lambda t: t, lambda v: v, "finite", np.isfinite)


@dataclasses.dataclass(frozen=True)
class ParameterProperties:
    """How one leaf of a parameter PyTree is treated (a leaf of the properties tree).

    Attributes:
        trainable: tuned by :func:`~jaxtrack.pipelines.tuner.tune` (and sweepable); frozen
            leaves keep their values.
        transform: the bijection it is optimised through.
        name: display name (the configuration key carrying it); empty for internal leaves.
    """

    trainable: bool = False
    transform: Transform = IDENTITY
    name: str = ""


#: The properties of a leaf nobody tunes or sweeps.
FROZEN = ParameterProperties()


def frozen_properties(params: Any) -> Any:
    """A properties tree mirroring ``params`` with every leaf :data:`FROZEN`."""
    return jax.tree.map(lambda _: FROZEN, params)


def _is_props(node: Any) -> bool:
    return isinstance(node, ParameterProperties)


def named_leaves(properties: Any) -> dict[str, ParameterProperties]:
    """The named leaves' properties, by name (tree order).

    Raises:
        ValueError: two leaves with the same name.
    """
    named: dict[str, ParameterProperties] = {}
    for prop in jax.tree.leaves(properties, is_leaf=_is_props):
        if prop.name:
            if prop.name in named:
                raise ValueError(f"two parameter leaves are named {prop.name!r}")
            named[prop.name] = prop
    return named


def leaf_values(params: Any, properties: Any, names: tuple[str, ...]) -> dict[str, Any]:
    """The values of the named leaves in ``params``, by name.

    Raises:
        InputError: a name no leaf has.
    """
    check_names(properties, names)
    props, treedef = jax.tree.flatten(properties, is_leaf=_is_props)
    values = {
        prop.name: leaf
        for prop, leaf in zip(props, treedef.flatten_up_to(params), strict=True)
        if prop.name in names
    }
    return {name: values[name] for name in names}


def replace_leaves(params: Any, properties: Any, values: Mapping[str, Any]) -> Any:
    """``params`` with the named leaves replaced by ``values`` (cast to the leaf's dtype).

    Pure and differentiable in ``values``; the values may carry leading batch axes (sweeps).

    Raises:
        InputError: a name no leaf has.
    """
    check_names(properties, tuple(values))

    def replace(prop: ParameterProperties, leaf: Any) -> Any:
        if prop.name not in values:
            return leaf
        return jnp.asarray(values[prop.name]).astype(jnp.asarray(leaf).dtype)

    return jax.tree.map(replace, properties, params, is_leaf=_is_props)


def check_names(properties: Any, names: tuple[str, ...], kind: str = "parameter") -> None:
    """Raises :class:`~jaxtrack.errors.InputError` for a name no leaf of ``properties`` has
    (the message calls the names ``kind``)."""
    known = named_leaves(properties)
    unknown = [name for name in names if name not in known]
    if unknown:
        raise InputError(
            f"unknown {kind}(s) {', '.join(unknown)}; known: {', '.join(known) or 'none'}"
        )


def trainable_names(properties: Any) -> tuple[str, ...]:
    """Names of the trainable leaves, in tree order."""
    return tuple(name for name, prop in named_leaves(properties).items() if prop.trainable)


def with_trainable(properties: Any, names: tuple[str, ...]) -> Any:
    """The properties tree with exactly the named leaves trainable.

    Raises:
        InputError: a name no leaf has.
    """
    check_names(properties, names)
    return jax.tree.map(
        lambda p: dataclasses.replace(p, trainable=bool(p.name) and p.name in names),
        properties,
        is_leaf=_is_props,
    )


def to_unconstrained(params: Any, properties: Any) -> dict[str, Array]:
    """``theta``: the trainable leaves mapped to the real line, by name.

    Raises:
        InputError: a trainable value outside its transform's domain.
    """
    names = trainable_names(properties)
    props = named_leaves(properties)
    theta = {}
    for name, value in leaf_values(params, properties, names).items():
        host = np.asarray(value, np.float64)
        transform = props[name].transform
        if not np.all(transform.contains(host)):
            raise InputError(f"{name} must be {transform.domain} to be tuned, got {host}")
        theta[name] = transform.inverse(jnp.asarray(host, jnp.float32))
    return theta


def from_unconstrained(theta: Mapping[str, Array], params: Any, properties: Any) -> Any:
    """``params`` with the trainable leaves set from ``theta`` (differentiable)."""
    return replace_leaves(params, properties, constrained(theta, properties))


def constrained(theta: Mapping[str, Array], properties: Any) -> dict[str, Array]:
    """The constrained values of ``theta``, by name."""
    props = named_leaves(properties)
    return {name: props[name].transform.forward(value) for name, value in theta.items()}
