"""CMT's contextual observation model (COM, CMT Sec. V-VI, eqs. 11-17).

Each component ``m`` of the mixture keeps an appearance model: a model value ``mu_k`` of every
feature ``f_k`` of the pool (:func:`box_features`: the buckets of the top and bottom halves'
normalised per-channel RGB histograms and the shape, CMT Sec. VI) and the decayed histograms
``G_k(v, m)`` of its past feature values (eq. 15-16). A particle's appearance likelihood is the
mixture of one Gaussian observer per feature (eq. 11),

    p(z | x) = sum_k rho_k N(f_k(x); mu_k, sigma^2),

whose weights ``rho_k`` are, for COM, the features' normalised mutual information with the
identity of the targets in the component's field of context (eqs. 13-14, 17; features
scoring below ``min_feature_score / F`` dropped, Sec. VI), and for EWOM (the MTb and MTb+CPD
variants) uniform, ``1 / F``.

Shapes are fixed: ``max_components`` slots (``K``), ``num_features`` features (``F``),
``num_values`` value bins of a feature (``V``). Static settings (quantisation step, patch
shape, ``V``, quantisation levels) are bound by the caller; the defaults are the module
constants.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, UInt8

from jaxtrack.appearance import (
    DEFAULT_PATCH_SHAPE,
    band_histograms,
    decay_update,
    feature_values,
    feature_weights,
    field_of_context,
    halves,
    num_bins,
    quantise,
    quantise_values,
    sample_nearest,
)
from jaxtrack.appearance.patches import check_frame

#: Quantisation step ``lambda`` of the colour histograms: 8 bins per channel, 49 features.
STEP = 32.0
#: Value bins ``V`` of a feature's decayed histogram ``G_k`` (features lie in ``[0, 1]``).
NUM_VALUES = 16
#: Quantisation levels ``r = 0, 1, 2`` of eq. 17 (bins of width 1/16, 1/8, 1/4).
NUM_LEVELS = 3


class COMParams(NamedTuple):
    """Tunable parameters of the observation model (a PyTree: vmap to sweep).

    Attributes:
        feature_std: ``sigma`` of every feature's Gaussian observer (eq. 11), > 0.
        decay: ``alpha >= 0`` of the decayed histograms (eq. 15-16): a sample's weight is
            multiplied by ``e^-alpha`` per frame.
        min_feature_score: in ``[0, 1]``; features whose weight ``rho_k`` falls below
            ``min_feature_score / F`` are dropped and the others renormalised (Sec. VI).
        model_rate: rate ``beta`` in ``(0, 1]`` of the model's recursive mean,
            ``mu_k <- (1 - beta) mu_k + beta f_k``.
        information_correction: ``c >= 0``; each feature's mutual information is lowered by
            ``c`` times its chance level before eq. 14 (not in the paper;
            :func:`~jaxtrack.appearance.chance_information`; 0: the plug-in estimate).
    """

    feature_std: Float[Array, ""]
    decay: Float[Array, ""]
    min_feature_score: Float[Array, ""]
    model_rate: Float[Array, ""]
    information_correction: Float[Array, ""]


def default_com_params() -> COMParams:
    """Defaults (the paper gives no values).

    ``sigma = 0.1``: a bucket holding a share ``p`` of a half's 64 samples fluctuates by
    ``sqrt(p (1 - p) / 64) <= 0.06`` between frames; ``alpha = 0.05``: samples of the last
    ~20 frames dominate ``G``; ``min_feature_score = 0.5``: features below half the uniform
    weight are dropped; ``beta = 0.1``; ``information_correction = 0``: the paper's plug-in
    mutual information (the correction did not track better on held-out scenes, README).
    """
    return COMParams(
        feature_std=jnp.asarray(0.1, jnp.float32),
        decay=jnp.asarray(0.05, jnp.float32),
        min_feature_score=jnp.asarray(0.5, jnp.float32),
        model_rate=jnp.asarray(0.1, jnp.float32),
        information_correction=jnp.asarray(0.0, jnp.float32),
    )


class AppearanceState(NamedTuple):
    """Every component slot's appearance model (part of the CMT scan carry).

    Attributes:
        model: model value ``mu_k`` of every feature.
        counts: decayed histograms ``G_k(v, m)`` (eq. 16).
        initialised: True once the slot's model holds a sample; a slot that is not gives no
            appearance evidence.
    """

    model: Float[Array, "max_components num_features"]
    counts: Float[Array, "max_components num_features num_values"]
    initialised: Bool[Array, " max_components"]


def num_features(step: float = STEP) -> int:
    """``F = 2 x 3 x ceil(256 / lambda) + 1``: the colour buckets and the shape feature."""
    return 2 * 3 * num_bins(step) + 1


def init_appearance(
    max_components: int, num_features: int, num_values: int = NUM_VALUES
) -> AppearanceState:
    """Empty models: zero values, zero histograms, no slot initialised."""
    return AppearanceState(
        model=jnp.zeros((max_components, num_features), jnp.float32),
        counts=jnp.zeros((max_components, num_features, num_values), jnp.float32),
        initialised=jnp.zeros(max_components, bool),
    )


def box_features(
    frame: UInt8[Array, "height width 3"],
    box: Float[Array, " 4"],
    step: float = STEP,
    patch_shape: tuple[int, int] = DEFAULT_PATCH_SHAPE,
) -> Float[Array, " num_features"]:
    """CMT's feature pool of one box (Sec. VI), every feature in ``[0, 1]``.

    ``h_{k,c}(b) = (1 / n_k) #{valid samples s in half k: floor(c(s) / lambda) = b}``, the
    normalised histogram of channel ``c`` (R, G, B) in half ``k`` (top, bottom) over the
    ``ph x pw`` nearest-pixel samples of the box that lie inside the image (``n_k`` of them;
    a half with none has all-zero buckets), counted per channel (one scatter-add of
    ``3 ph pw`` samples; ``benchmarks/com_features.py`` measured it faster than a joint
    histogram and its marginals), then the shape ``w / (w + h)``
    (:func:`~jaxtrack.appearance.feature_values`). ``vmap`` over boxes with
    ``in_axes=(None, 0)``.

    Args:
        frame: RGB frame, uint8.
        box: ``(x, y, w, h)``, pixels, ``w, h > 0``.
        step: quantisation step ``lambda``, static.
        patch_shape: ``(ph, pw)`` samples, ``ph`` even, static.

    Returns:
        ``[2 x 3 x ceil(256 / lambda) + 1]`` features: top R, G, B buckets, bottom R, G, B
        buckets, shape.

    Raises:
        InputError: the frame is not uint8 ``H x W x 3``, the step is not in ``(0, 256]``,
            or ``ph`` is odd.
    """
    check_frame(frame)
    patch = sample_nearest(frame, box, patch_shape)
    channels = quantise(patch.values.astype(jnp.float32), step)
    histograms = band_histograms(channels, patch.valid, halves(patch_shape[0]), num_bins(step))
    return feature_values(histograms, box)


def drop_weak_features(
    weights: Float[Array, "*batch num_features"], min_feature_score: Float[Array, ""]
) -> Float[Array, "*batch num_features"]:
    """Drops the features with ``rho_k < min_feature_score / F`` and renormalises (Sec. VI).

    The largest weight is at least ``1 / F``, so with ``min_feature_score <= 1`` one feature
    at least is kept (the largest is kept whatever the score).
    """
    floor = min_feature_score / weights.shape[-1]
    floor = jnp.minimum(floor, jnp.max(weights, axis=-1, keepdims=True))
    kept = jnp.where(weights >= floor, weights, 0.0)
    return kept / jnp.sum(kept, axis=-1, keepdims=True)


def observation_weights(
    counts: Float[Array, "max_components num_features num_values"],
    positions: Float[Array, "max_components 2"],
    alive: Bool[Array, " max_components"],
    radius: Float[Array, "*radius"],
    params: COMParams,
    num_levels: int,
    contextual: bool,
) -> Float[Array, "max_components num_features"]:
    """The observers' weights ``rho_k`` of every component (eq. 14 / EWOM).

    COM (``contextual``): component ``m``'s field of context is itself and the living
    components ``u`` with ``|p_m - p_u| < r_m`` (Sec. V-A); ``rho`` is the normalised
    multiresolution mutual information of each feature with their identities (eqs. 13, 14,
    17, :func:`~jaxtrack.appearance.feature_weights`, uniform for a component alone), then
    :func:`drop_weak_features`. EWOM: ``rho_k = 1 / F`` for every component.

    Args:
        counts: decayed histograms ``G`` (:attr:`AppearanceState.counts`).
        positions: position of each component (e.g. its local decision's centre), pixels.
        alive: True for slots holding a component.
        radius: ``d_thr``, pixels: a scalar, or one per component (``[K]``, e.g. CPD's
            threshold times each box's height).
        params: ``min_feature_score`` is used.
        num_levels: quantisation levels of eq. 17, static.
        contextual: True for COM, False for EWOM, static.
    """
    num_components, num_pool = counts.shape[:2]
    if not contextual:
        return jnp.full((num_components, num_pool), 1.0 / num_pool, counts.dtype)
    radii = jnp.broadcast_to(radius, (num_components,))[:, None]
    context = field_of_context(positions, alive, radii)
    correction = params.information_correction
    weights = jax.lax.cond(  # the default (0) skips the chance levels' cost
        correction > 0,
        lambda: feature_weights(counts, context, num_levels, correction),
        lambda: feature_weights(counts, context, num_levels),
    )
    return drop_weak_features(weights, params.min_feature_score)


def appearance_log_likelihood(
    features: Float[Array, "max_components num_particles num_features"],
    state: AppearanceState,
    weights: Float[Array, "max_components num_features"],
    params: COMParams,
) -> Float[Array, "max_components num_particles"]:
    """``log sum_k rho_k N(f_k; mu_k, sigma^2)`` of every particle (eq. 11).

    ``N`` is the Gaussian density, so a perfect match scores ``-log(sigma sqrt(2 pi))``; a
    slot whose model is not initialised scores 0 (no appearance evidence). Computed by a
    log-sum-exp over the features; dropped features (``rho_k = 0``) do not count.

    Args:
        features: :func:`box_features` of each component's particles.
        state: the components' models.
        weights: ``rho`` (:func:`observation_weights`).
        params: ``feature_std`` is used.
    """
    sigma = params.feature_std
    z = (features - state.model[:, None, :]) / sigma
    log_density = -0.5 * z**2 - jnp.log(sigma) - 0.5 * math.log(2.0 * math.pi)
    log_likelihood = jax.nn.logsumexp(log_density, axis=-1, b=weights[:, None, :])
    return jnp.where(state.initialised[:, None], log_likelihood, 0.0)


def likelihood_gap(
    own_features: Float[Array, "max_components num_features"],
    other_features: Float[Array, "max_components num_features"],
    state: AppearanceState,
    weights: Float[Array, "max_components num_features"],
    params: COMParams,
) -> Float[Array, " max_components"]:
    """Discriminative power: ``log p(z_own | m) - log p(z_other | m)`` per component (eq. 11).

    The appearance log-likelihood of component ``m``'s own box minus that of another target's
    box (e.g. its nearest neighbour's) under ``m``'s model: the larger, the better ``m`` tells
    itself from that target (CMT Fig. 9 compares it between COM and EWOM).
    """
    both = jnp.stack([own_features, other_features], axis=1)
    log_likelihood = appearance_log_likelihood(both, state, weights, params)
    return log_likelihood[:, 0] - log_likelihood[:, 1]


def update_appearance(
    state: AppearanceState,
    features: Float[Array, "max_components num_features"],
    observed: Bool[Array, " max_components"],
    frozen: Bool[Array, " max_components"],
    born: Bool[Array, " max_components"],
    params: COMParams,
) -> AppearanceState:
    """The models after this frame's local decisions (eqs. 15-16 and the recursive mean).

    * ``born`` (a slot given to a new component): the model is reset to ``f`` and the
      histograms to zero before its first sample;
    * a slot *learns* when ``observed`` and, unless born, not ``frozen`` (CMT's merge
      condition freezes appearance): ``G_k <- e^-alpha G_k + delta(v(f_k) = v)`` with
      ``v(f) = floor(V f)`` (:func:`~jaxtrack.appearance.decay_update`) and
      ``mu_k <- (1 - beta) mu_k + beta f_k`` (its first learned sample sets ``mu = f``);
    * an unobserved slot's histograms only decay; a frozen slot is left unchanged.

    Args:
        state: the models before the frame.
        features: :func:`box_features` of every slot's local decision.
        observed: True for slots with a local decision this frame (living components).
        frozen: True for slots whose appearance is frozen (merge).
        born: True for slots given to a new component this frame.
        params: ``decay`` and ``model_rate`` are used.
    """
    learn = observed & (born | ~frozen)
    start = born | (learn & ~state.initialised)
    mean = state.model + params.model_rate * (features - state.model)
    model = jnp.where(start[:, None], features, jnp.where(learn[:, None], mean, state.model))
    counts = jnp.where(born[:, None, None], 0.0, state.counts)
    value_bins = quantise_values(features, counts.shape[-1])
    updated = decay_update(counts, value_bins, learn, params.decay)
    counts = jnp.where((frozen & ~born)[:, None, None], state.counts, updated)
    return AppearanceState(model, counts, state.initialised | start)
