"""CMT feature weights: mutual information of feature value and identity in the field of context.

CMT Sec. V: each feature ``f_k`` of the pool is a scalar per target and frame (a bucket of a
normalised per-channel histogram of the top or bottom half, or the box's shape, Sec. VI). Its
values are quantised into ``V`` value bins and accumulated per target ``u`` in a decayed
2-D histogram ``G_k(v, u)`` (eq. 15-16). For a target ``m``, the classes are the targets of
its field of context (itself and every target closer than ``d_thr``, Sec. V-A), and

* ``I_r(F_k, Y) = sum_{v, u} P(v, u) log(P(v, u) / (P(v) P(u)))`` (eq. 13), ``P(v, u)``
  proportional to ``G_k(v, u)`` over those classes (frequency counting: the class prior
  ``P(u)`` is each target's share of the decayed sample mass), at quantisation level ``r``
  whose bins merge ``2^r`` value bins;
* ``I(F_k, Y) = sum_r 2^-r I_r(F_k, Y)`` (eq. 17);
* ``rho_k = I(F_k, Y) / sum_j I(F_j, Y)`` (eq. 14), one weight vector per target.

Mutual information is in nats (the base cancels in ``rho``). A target alone in its field of
context (or whose classes have no samples) has ``I = 0`` for every feature; its weights are
then uniform, ``1 / num_features``. The paper's threshold that drops low-scoring features is
left to the tracker.

*Chance level* (not in the paper; ``correction`` > 0): the plug-in estimate of eq. 13 is
biased upwards, by about ``(B - 1)(C - 1) / (2N)`` nats when feature and identity are
independent (Miller-Madow; ``B`` value bins in use, ``C`` classes, ``N`` samples), and more for
a feature spread over more bins. Among look-alike targets, eq. 14 then gives most of the
weight to the noisiest feature. :func:`chance_information` estimates that level from the
counts (``B`` the perplexity of the pooled values, ``N`` the decayed sample mass, which
overstates the bias a little: decayed samples weigh less than one);
:func:`multiresolution_mutual_information` lowers each level's ``I_r`` by ``correction`` times
it, floored at 0.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from jaxtrack.errors import InputError

#: Total information (nats) below which a target's weights are uniform: float32 rounding
#: leaves about 1e-8 per feature where the exact value is 0 (e.g. a target alone).
MIN_INFORMATION = 1e-6


def feature_values(
    channel_histograms: Float[Array, "2 3 bins_per_channel"], box: Float[Array, " 4"]
) -> Float[Array, " num_features"]:
    """CMT's feature pool of one box, every feature in ``[0, 1]`` (CMT Sec. VI).

    The ``2 x 3 x n`` buckets of the top and bottom halves' normalised per-channel RGB
    histograms (``marginals`` of :func:`~jaxtrack.appearance.features.top_bottom_histograms`),
    then the shape ``w / h`` mapped monotonically onto ``[0, 1)`` as ``w / (w + h)``.
    """
    shape = box[2] / (box[2] + box[3])
    return jnp.concatenate([channel_histograms.ravel(), shape[None]])


def quantise_values(values: Float[Array, "*shape"], num_values: int) -> Int[Array, "*shape"]:
    """Value bin ``floor(V f)`` of features ``f`` in ``[0, 1]`` (1 falls in the last bin)."""
    return jnp.clip(jnp.floor(values * num_values), 0, num_values - 1).astype(jnp.int32)


def decay_update(
    counts: Float[Array, "max_targets num_features num_values"],
    value_bins: Int[Array, "max_targets num_features"],
    observed: Bool[Array, " max_targets"],
    decay: Float[Array, ""],
) -> Float[Array, "max_targets num_features num_values"]:
    """``G_k^t(v, u) = e^-alpha G_k^(t-1)(v, u) + delta(f_k(s_t^(u)) = v)`` (CMT eq. 16).

    Every sample's weight decays by ``e^-alpha`` per frame (eq. 15), so a target that is not
    observed (``observed`` False: occluded, or a padded slot) only decays. A slot given to a
    new target must be zeroed by the caller.

    Args:
        counts: decayed histograms ``G`` of every target, feature and value bin.
        value_bins: this frame's value bin of every target's features.
        observed: True for targets with a sample this frame.
        decay: ``alpha >= 0``.
    """
    num_values = counts.shape[-1]
    new = jax.nn.one_hot(value_bins, num_values, dtype=counts.dtype) * observed[:, None, None]
    return jnp.exp(-decay) * counts + new


def field_of_context(
    positions: Float[Array, "max_targets 2"],
    active: Bool[Array, " max_targets"],
    radius: Float[Array, "*radius"],
) -> Bool[Array, "max_targets max_targets"]:
    """``context[m, u]``: target ``u`` is in target ``m``'s field of context (CMT Sec. V-A).

    ``u = m`` or ``d_O(m, u) < d_thr``, ``d_O`` the Euclidean distance of the positions (e.g.
    box centres); both targets active. An inactive target's row is all False. ``radius`` is
    ``d_thr``: a scalar, or ``[max_targets, 1]`` for one threshold per target ``m`` (row).
    """
    gaps = positions[:, None, :] - positions[None, :, :]
    close = jnp.sum(gaps**2, axis=-1) < radius**2
    near = close | jnp.eye(positions.shape[0], dtype=bool)
    return near & active[:, None] & active[None, :]


def mutual_information(
    counts: Float[Array, "num_classes num_values"], classes: Bool[Array, " num_classes"]
) -> Float[Array, ""]:
    """``I(F, Y)`` of eq. 13 from counts ``G(v, u)``, over the classes ``u`` marked True."""
    kept = counts * classes[:, None]
    total = jnp.sum(kept)
    joint = kept / jnp.where(total > 0, total, 1.0)
    class_prob = jnp.sum(joint, axis=1, keepdims=True)
    value_prob = jnp.sum(joint, axis=0, keepdims=True)
    positive = joint > 0
    safe = jnp.where(positive, joint, 1.0)
    ratio = safe / jnp.where(positive, class_prob * value_prob, 1.0)
    return jnp.sum(jnp.where(positive, joint * jnp.log(ratio), 0.0))


def chance_information(
    counts: Float[Array, "num_classes num_values"], classes: Bool[Array, " num_classes"]
) -> Float[Array, ""]:
    """The plug-in ``I`` that sampling noise alone gives (module docstring, *chance level*).

    ``(B - 1)(C - 1) / (2 N)`` nats: ``N`` the decayed sample mass of the classes marked True,
    ``C`` how many of them hold samples, ``B = exp(H(V))`` the perplexity of their pooled value
    distribution (the value bins in use). 0 when no class holds samples.
    """
    kept = counts * classes[:, None]
    total = jnp.sum(kept)
    mass = jnp.where(total > 0, total, 1.0)
    value_prob = jnp.sum(kept, axis=0) / mass
    positive = value_prob > 0
    entropy = -jnp.sum(
        jnp.where(positive, value_prob * jnp.log(jnp.where(positive, value_prob, 1.0)), 0.0)
    )
    present = jnp.sum(jnp.sum(kept, axis=1) > 0)
    chance = (jnp.exp(entropy) - 1.0) * (present - 1) / (2.0 * mass)
    return jnp.maximum(chance, 0.0)


def multiresolution_mutual_information(
    counts: Float[Array, "num_classes num_values"],
    classes: Bool[Array, " num_classes"],
    num_levels: int,
    correction: Float[Array, ""] | float = 0.0,
) -> Float[Array, ""]:
    """``I = sum_{r < num_levels} 2^-r I_r`` (CMT eq. 17), level ``r`` merging ``2^r`` bins.

    With ``correction`` ``c > 0``, each level's ``I_r`` is first lowered by ``c`` times its
    :func:`chance_information` and floored at 0 (module docstring, *chance level*; ``c = 0``:
    the paper's plug-in estimate).

    Raises:
        InputError: ``num_values`` is not divisible by ``2^(num_levels - 1)``.
    """
    num_classes, num_values = counts.shape
    if num_levels < 1 or num_values % 2 ** (num_levels - 1):
        raise InputError(
            f"{num_values} value bins cannot be merged over {num_levels} levels "
            f"(need a multiple of 2^(levels - 1) and levels >= 1)"
        )
    total = jnp.zeros((), counts.dtype)
    for level in range(num_levels):
        merged = counts.reshape(num_classes, num_values >> level, 2**level).sum(axis=-1)
        information = mutual_information(merged, classes)
        if not (isinstance(correction, (int, float)) and correction == 0):
            lowered = information - correction * chance_information(merged, classes)
            information = jnp.where(correction > 0, jnp.maximum(lowered, 0.0), information)
        total = total + information / 2**level
    return total


def feature_weights(
    counts: Float[Array, "max_targets num_features num_values"],
    context: Bool[Array, "max_targets max_targets"],
    num_levels: int,
    correction: Float[Array, ""] | float = 0.0,
) -> Float[Array, "max_targets num_features"]:
    """``rho_k`` of every target (CMT eq. 14), uniform where every ``I`` is 0.

    "Every ``I`` is 0" means: fewer than two targets in the field of context, or a total
    below ``MIN_INFORMATION`` (rounding noise).

    Args:
        counts: decayed histograms ``G`` (:func:`decay_update`).
        context: fields of context (:func:`field_of_context`).
        num_levels: quantisation levels of eq. 17, static.
        correction: multiple of the chance level taken off each feature's ``I``
            (:func:`multiresolution_mutual_information`; 0: the paper's plug-in estimate).
    """
    per_feature = jnp.swapaxes(counts, 0, 1)

    def weights(classes):
        information = jax.vmap(
            lambda feature_counts: multiresolution_mutual_information(
                feature_counts, classes, num_levels, correction
            )
        )(per_feature)
        information = jnp.maximum(information, 0.0)  # rounding can leave -1e-9 for I = 0
        total = jnp.sum(information)
        informative = (jnp.sum(classes) > 1) & (total > MIN_INFORMATION)
        uniform = jnp.full_like(information, 1.0 / information.shape[0])
        return jnp.where(informative, information / jnp.where(informative, total, 1.0), uniform)

    return jax.vmap(weights)(context)
