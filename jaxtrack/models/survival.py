"""Probability of survival ``e(x)``: a constant, or a map over the image plane.

PHD-context eq. 9 lets the survival probability depend on the state, e.g. lower near scene
exits. A :class:`SurvivalMap` holds one probability per cell of a regular grid over the box
centre ``(y1, y2)``; states outside the grid take the nearest border cell.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
from jaxtyping import Array, Float

from jaxtrack.models.dynamics import POSITION


class SurvivalMap(NamedTuple):
    """Survival probability per grid cell.

    Attributes:
        probs: ``[rows, cols]`` probabilities in ``(0, 1]``; row index follows ``y2``, column
            index ``y1``.
        lower: ``(y1, y2)`` of the grid's top-left corner, pixels.
        upper: ``(y1, y2)`` of the grid's bottom-right corner, pixels.
    """

    probs: Float[Array, "rows cols"]
    lower: Float[Array, " 2"]
    upper: Float[Array, " 2"]


def survival_probability(
    survival: Float[Array, ""] | SurvivalMap, states: Float[Array, "num_particles 6"]
) -> Float[Array, " num_particles"]:
    """``e(x)`` for every particle.

    Args:
        survival: a constant probability in ``(0, 1]`` or a :class:`SurvivalMap`.
        states: particle states ``(y1, vy1, y2, vy2, w, h)``.

    Returns:
        The survival probability of each particle.
    """
    if not isinstance(survival, SurvivalMap):
        return jnp.broadcast_to(jnp.asarray(survival, states.dtype), states.shape[:1])
    rows, cols = survival.probs.shape
    relative = (states[:, POSITION] - survival.lower) / (survival.upper - survival.lower)
    col = jnp.clip(jnp.floor(relative[:, 0] * cols), 0, cols - 1).astype(jnp.int32)
    row = jnp.clip(jnp.floor(relative[:, 1] * rows), 0, rows - 1).astype(jnp.int32)
    return survival.probs[row, col]
