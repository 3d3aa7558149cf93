"""Feature ranking by variance ratio (Collins, Liu and Leordeanu 2005; Hierarchical Sec. 5.2-5.3).

For a feature with target histogram ``p`` and background histogram ``q``:

* ``L(k) = log(max(p(k), delta) / max(q(k), delta))`` (Hierarchical eq. 2): positive on target
  bins, negative on background bins, near 0 on shared ones;
* ``VR(L; p, q) = var(L; (p + q) / 2) / (var(L; p) + var(L; q))`` (eq. 3), with
  ``var(L; a) = sum_k a(k) L(k)^2 - (sum_k a(k) L(k))^2``: large when target and background
  bins are far apart in ``L`` (between-class spread) and each class is tight.

``delta`` keeps the logarithm finite (Collins et al. use a small constant; the Hierarchical
paper the smallest histogram value). The denominator gets ``+ 1e-6``, so a feature whose
target and background histograms are identical (``L = 0``) scores 0, and one that separates
them perfectly (each one-hot, on different bins: both variances 0) scores
``log(1 / delta)^2 / 1e-6``, above any imperfect one.

Selection (Hierarchical Sec. 5.3): the pool holds the ``M`` best features of the frame and the
``N`` best long-run ones, "those which have been at top of the feature rank more times": a
count of the frames in which a feature was among the ``M`` best (ties broken by the current
variance ratio), taken among the features not already in the ``M``, so the pool always holds
``M + N`` distinct features.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float, Int

from jaxtrack.errors import InputError

#: Added to ``var(L; p) + var(L; q)`` in eq. 3 so that equal histograms score 0, not 0/0.
VARIANCE_FLOOR = 1e-6


def log_likelihood_ratio(
    p: Float[Array, "*shape num_bins"], q: Float[Array, "*shape num_bins"], delta: float
) -> Float[Array, "*shape num_bins"]:
    """``L(k) = log(max(p(k), delta) / max(q(k), delta))`` (Hierarchical eq. 2)."""
    return jnp.log(jnp.maximum(p, delta)) - jnp.log(jnp.maximum(q, delta))


def _variance(values, weights):
    mean = jnp.sum(weights * values, axis=-1)
    return jnp.sum(weights * values**2, axis=-1) - mean**2


def variance_ratio(
    p: Float[Array, "*shape num_bins"], q: Float[Array, "*shape num_bins"], delta: float
) -> Float[Array, "*shape"]:
    """``VR = var(L; (p + q) / 2) / (var(L; p) + var(L; q) + 1e-6)`` (Hierarchical eq. 3).

    Args:
        p: normalised target histograms of each feature.
        q: normalised background histograms of the same features.
        delta: floor of the histogram values in ``L``, positive (e.g. 1e-3).
    """
    ratio = log_likelihood_ratio(p, q, delta)
    between = _variance(ratio, 0.5 * (p + q))
    within = _variance(ratio, p) + _variance(ratio, q)
    return jnp.maximum(between, 0.0) / (jnp.maximum(within, 0.0) + VARIANCE_FLOOR)


class FeaturePool(NamedTuple):
    """Long-run record of the feature ranking.

    Attributes:
        wins: number of frames in which each feature was among the ``M`` best.
    """

    wins: Float[Array, " num_features"]


def init_pool(num_features: int) -> FeaturePool:
    """A pool in which no feature has won yet."""
    return FeaturePool(jnp.zeros(num_features, jnp.float32))


def select_features(
    pool: FeaturePool, ratios: Float[Array, " num_features"], num_current: int, num_long_run: int
) -> tuple[FeaturePool, Int[Array, " num_selected"]]:
    """The ``M`` best features of this frame, then the ``N`` best long-run ones.

    Args:
        pool: the record so far.
        ratios: this frame's variance ratio of every feature.
        num_current: ``M``, static.
        num_long_run: ``N``, static; ``M + N <= num_features``.

    Returns:
        The updated pool (this frame's ``M`` best counted) and the ``M + N`` selected feature
        indices: the ``M`` best by decreasing ratio, then the ``N`` long-run ones by
        decreasing count.

    Raises:
        InputError: ``M < 1``, ``N < 0`` or ``M + N`` exceeds the number of features.
    """
    num_features = ratios.shape[-1]
    if num_current < 1 or num_long_run < 0 or num_current + num_long_run > num_features:
        raise InputError(
            f"cannot keep {num_current} current + {num_long_run} long-run features "
            f"of {num_features}"
        )
    _, current = jax.lax.top_k(ratios, num_current)
    in_current = jnp.zeros(num_features, bool).at[current].set(True)
    wins = pool.wins + in_current
    score = wins + 0.5 * ratios / (1.0 + ratios)
    _, long_run = jax.lax.top_k(jnp.where(in_current, -jnp.inf, score), num_long_run)
    return FeaturePool(wins), jnp.concatenate([current, long_run])
