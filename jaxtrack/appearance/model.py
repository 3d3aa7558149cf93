"""Appearance model of a target: recursive mean histograms and distance statistics for gating.

Hierarchical Sec. 5.3: the model histogram is a recursive mean of the observed histograms,
``m_t = m_(t-1) + r_n (p_t - m_(t-1))`` (eq. 4 with ``r_n = 1 / n``), and the Bhattacharyya
distance ``d_t = d(m_(t-1), p_t)`` between the model and each new histogram has a running
mean and variance (eq. 5-6, garbled in the paper's text) that parameterise a gate.

Here the rate is ``r_n = max(1 / n, beta)`` (``n`` = histograms averaged so far, the first
one included): ``beta = 0`` is the paper's cumulative mean, ``beta > 0`` turns into an
exponential forgetting ``h <- (1 - beta) h + beta p`` once ``n > 1 / beta`` (Fusion's
learning rates 0.15 / 0.35 are such betas). The distance statistics use the same rule with
``k`` = distances seen: ``mu <- mu + r e``, ``var <- (1 - r)(var + r e^2)``, ``e = d - mu``,
``r = max(1 / k, beta)``: Welford's exact mean and (population) variance while ``r = 1/k``,
the exponentially weighted ones after (Finch 2009, "Incremental calculation of weighted
mean and variance").

The model is frozen (returned unchanged) while the target is occluded (Fusion Sec. 2.2, CMT's
merge condition), and a histogram with no sample (an all-zero one, from a box outside the
image) is no observation. Every field broadcasts over leading axes: a model may hold several
histograms (top and bottom halves, the selected features), each with its own count and
statistics.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from jaxtrack.appearance.histograms import normalise
from jaxtrack.appearance.similarity import bhattacharyya_distance


class AppearanceModel(NamedTuple):
    """Mean histograms and the statistics of their distance to new observations.

    Attributes:
        histogram: normalised mean histograms.
        count: histograms averaged into each mean (``n``).
        distance_mean: running mean of ``d(m_(t-1), p_t)`` (0 before the second histogram).
        distance_var: running variance of the same distances.
    """

    histogram: Float[Array, "*shape num_bins"]
    count: Float[Array, "*shape"]
    distance_mean: Float[Array, "*shape"]
    distance_var: Float[Array, "*shape"]


def init_model(histogram: Float[Array, "*shape num_bins"]) -> AppearanceModel:
    """A model of one observed histogram (``n = 1``; an all-zero histogram gives ``n = 0``)."""
    seen = jnp.sum(histogram, axis=-1) > 0
    zeros = jnp.zeros(histogram.shape[:-1], jnp.float32)
    return AppearanceModel(normalise(histogram), seen.astype(jnp.float32), zeros, zeros)


def update_model(
    model: AppearanceModel,
    histogram: Float[Array, "*shape num_bins"],
    occluded: Bool[Array, ""],
    rate_floor: Float[Array, ""],
) -> AppearanceModel:
    """One recursive update (Hierarchical eq. 4-6 with the rate ``max(1 / n, beta)``).

    Args:
        model: the model so far.
        histogram: the new normalised histograms ``p_t`` (all zero: not observed).
        occluded: True freezes the whole model.
        rate_floor: ``beta`` in ``[0, 1]``.

    Returns:
        The updated model.
    """
    observed = (jnp.sum(histogram, axis=-1) > 0) & ~occluded
    count = model.count + 1.0
    rate = jnp.maximum(1.0 / count, rate_floor)
    mean_histogram = normalise(model.histogram + rate[..., None] * (histogram - model.histogram))

    # The k-th distance comes with the (k + 1)-th histogram: k = n before this update.
    distance = bhattacharyya_distance(model.histogram, histogram)
    distance_rate = jnp.maximum(1.0 / jnp.maximum(model.count, 1.0), rate_floor)
    error = distance - model.distance_mean
    distance_mean = model.distance_mean + distance_rate * error
    distance_var = (1.0 - distance_rate) * (model.distance_var + distance_rate * error**2)

    keep = ~observed
    stats = observed & (model.count > 0)
    return AppearanceModel(
        jnp.where(keep[..., None], model.histogram, mean_histogram),
        jnp.where(keep, model.count, count),
        jnp.where(stats, distance_mean, model.distance_mean),
        jnp.where(stats, distance_var, model.distance_var),
    )


def within_gate(
    model: AppearanceModel,
    histogram: Float[Array, "*shape num_bins"],
    num_std: Float[Array, ""],
    min_std: Float[Array, ""],
) -> Bool[Array, "*shape"]:
    """The gate ``d(m, p) <= mu + k max(sigma, sigma_min)`` (Hierarchical Sec. 5.4).

    ``sigma_min`` keeps the gate open while the statistics rest on few distances (``sigma``
    is 0 after one); an empty model or histogram is at distance 1.

    Args:
        model: the target's model.
        histogram: the candidate's normalised histograms.
        num_std: ``k``, standard deviations of the gate.
        min_std: ``sigma_min``, floor of the standard deviation.
    """
    distance = bhattacharyya_distance(model.histogram, histogram)
    spread = jnp.maximum(jnp.sqrt(jnp.maximum(model.distance_var, 0.0)), min_std)
    return distance <= model.distance_mean + num_std * spread
