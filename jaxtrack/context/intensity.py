"""Birth and clutter intensities: a magnitude times a uniform + Gaussian-mixture density.

PHD-context eq. 19-21:
``gamma(x) = lambda_s p(x | b)`` (birth, 6-D state) and ``kappa(z) = lambda_r p(z | c)``
(clutter, 4-D measurement), with the density

    p(x) = pi_u u(x) + (1 - pi_u) sum_m pi_m N(x; mu_m, Sigma_m),

``u`` uniform over a box-shaped volume ``V = prod(upper - lower)``. The paper writes the
Gaussian share as ``pi_g``; here ``pi_g = 1 - pi_u``. The baseline "UM" is ``pi_u = 1``.

One PyTree, :class:`Intensity`, covers all cases (uniform, GMM, uniform + GMM) so that the
PHD filter has a single code path, ``jax.vmap`` can sweep magnitudes, and ``jax.grad`` can
flow into magnitudes and mixture parameters. Dead mixture components (weight 0, e.g. after
MAP-EM extinction) are skipped safely. The uniform term is ``1/V`` everywhere (no indicator
of the volume), which keeps the density smooth; states outside the volume are rare by
construction of the volume.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from jaxtrack.linalg import (
    cholesky,
    cholesky_loop,
    forward_substitution,
    solve_lower,
    solve_lower_loop,
)


class Intensity(NamedTuple):
    """``magnitude * [pi_u / V + (1 - pi_u) * sum_m w_m N(x; mu_m, Sigma_m)]``.

    Attributes:
        magnitude: expected number of events per frame (``lambda_s`` or ``lambda_r``).
        uniform_weight: ``pi_u`` in ``[0, 1]`` (0: a pure mixture, e.g. a known truth).
        lower: lower corner of the uniform's volume, ``[dim]``.
        upper: upper corner of the uniform's volume, ``[dim]``.
        weights: Gaussian mixture weights, ``[num_components]``; 0 marks a dead component;
            the live weights sum to 1 (ignored when ``uniform_weight == 1``).
        means: ``[num_components, dim]``.
        covs: ``[num_components, dim, dim]``, symmetric positive definite.
    """

    magnitude: Float[Array, ""]
    uniform_weight: Float[Array, ""]
    lower: Float[Array, " dim"]
    upper: Float[Array, " dim"]
    weights: Float[Array, " num_components"]
    means: Float[Array, "num_components dim"]
    covs: Float[Array, "num_components dim dim"]

    @property
    def dim(self) -> int:
        return self.lower.shape[-1]


def uniform_intensity(magnitude, lower, upper) -> Intensity:
    """The UM baseline: ``magnitude / V`` everywhere in the volume ``[lower, upper]``."""
    lower = jnp.asarray(lower, jnp.float32)
    upper = jnp.asarray(upper, jnp.float32)
    dim = lower.shape[-1]
    return Intensity(
        magnitude=jnp.asarray(magnitude, jnp.float32),
        uniform_weight=jnp.asarray(1.0, jnp.float32),
        lower=lower,
        upper=upper,
        weights=jnp.zeros((1,), jnp.float32),
        means=jnp.zeros((1, dim), jnp.float32),
        covs=jnp.eye(dim, dtype=jnp.float32)[None],
    )


def log_volume(intensity: Intensity) -> Float[Array, ""]:
    """``log V`` of the uniform component's box."""
    return jnp.sum(jnp.log(intensity.upper - intensity.lower))


#: Mixtures with at least this many component slots are evaluated by
#: :func:`log_normal_quadratic` (one matrix product of ``dim (dim + 3) / 2 + 1`` features
#: per point); smaller ones (UM's single dead slot) by :func:`log_normal_components`, whose
#: work and memory grow with the components, not with the features.
QUADRATIC_MIN_COMPONENTS = 8


def log_density(intensity: Intensity, x: Float[Array, "*batch dim"]) -> Float[Array, "*batch"]:
    """``log p(x)`` of the normalised density (PHD-context eq. 21), for a batch of points."""
    log_uniform = jnp.log(intensity.uniform_weight) - log_volume(intensity)
    alive = intensity.weights > 0
    safe_weights = jnp.where(alive, intensity.weights, 1.0)
    if intensity.means.shape[0] >= QUADRATIC_MIN_COMPONENTS:
        log_gauss = log_normal_quadratic(x, intensity.means, intensity.covs, alive)
    else:
        log_gauss = log_normal_components(x, intensity.means, intensity.covs)
    log_components = jnp.log(safe_weights) + log_gauss
    # Dead components are masked by `alive` (a per-component test), not by testing each
    # point x component value for finiteness: one pass fewer over the pairs.
    top = jnp.max(jnp.where(alive, log_components, -1e30), axis=-1, keepdims=True)
    # exp of -inf (not of a huge value masked afterwards) where a component is dead: the
    # masked branch then has a zero derivative instead of 0 * inf.
    total = jnp.sum(jnp.exp(jnp.where(alive, log_components - top, -jnp.inf)), axis=-1)
    has_gaussian = jnp.any(alive) & (intensity.uniform_weight < 1)
    gaussian_share = jnp.where(has_gaussian, 1 - intensity.uniform_weight, 1.0)
    safe_total = jnp.where(has_gaussian, total, 1.0)
    log_mixture = jnp.log(gaussian_share) + jnp.log(safe_total) + top[..., 0]
    return jnp.where(has_gaussian, jnp.logaddexp(log_uniform, log_mixture), log_uniform)


def log_intensity(intensity: Intensity, x: Float[Array, "*batch dim"]) -> Float[Array, "*batch"]:
    """``log(magnitude * p(x))``: the log birth or clutter intensity at ``x``."""
    return jnp.log(intensity.magnitude) + log_density(intensity, x)


def sample(key, intensity: Intensity, num_samples: int) -> Float[Array, "num_samples dim"]:
    """Draws points from the normalised density (uniform share + live Gaussians)."""
    key_choice, key_uniform, key_gauss = jax.random.split(key, 3)
    logits = jnp.concatenate(
        [
            jnp.log(intensity.uniform_weight)[None],
            jnp.where(
                intensity.weights > 0,
                jnp.log1p(-intensity.uniform_weight + 1e-30)
                + jnp.log(jnp.where(intensity.weights > 0, intensity.weights, 1.0)),
                -jnp.inf,
            ),
        ]
    )
    choice = jax.random.categorical(key_choice, logits, shape=(num_samples,))
    uniform = jax.random.uniform(
        key_uniform,
        (num_samples, intensity.dim),
        minval=intensity.lower,
        maxval=intensity.upper,
    )
    component = jnp.maximum(choice - 1, 0)
    chol = cholesky(intensity.covs)[component]
    noise = jax.random.normal(key_gauss, (num_samples, intensity.dim))
    gauss = intensity.means[component] + jnp.einsum("nij,nj->ni", chol, noise)
    return jnp.where((choice == 0)[:, None], uniform, gauss)


def log_normal(x, mean, cov):
    """``log N(x; mean, cov)`` for a point or a batch of points ``x[..., dim]``."""
    chol = cholesky(cov)
    return _log_gaussian(jnp.sum(solve_lower(chol, x - mean) ** 2, axis=-1), chol)


def _log_gaussian(squares: Array, chol: Array) -> Array:
    """``log N`` from the squared Mahalanobis distances and the covariance's Cholesky
    factor(s) ``[..., dim, dim]`` (one log-determinant per factor, broadcast on the last
    axis of ``squares``)."""
    dim = chol.shape[-1]
    log_det = 2 * jnp.sum(jnp.log(jnp.diagonal(chol, axis1=-2, axis2=-1)), axis=-1)
    return -0.5 * (squares + log_det + dim * jnp.log(2 * jnp.pi))


def log_normal_quadratic(
    x: Float[Array, "*batch dim"],
    means: Float[Array, "num_components dim"],
    covs: Float[Array, "num_components dim dim"],
    alive: Bool[Array, " num_components"] | None = None,
) -> Float[Array, "*batch num_components"]:
    """``log N(x; mean_m, cov_m)`` of every point under every component, by one matrix product.

    The Mahalanobis term is a quadratic form in the point, ``(y - m)^T P (y - m) = sum_{i<=j}
    c_ij P_ij y_i y_j - 2 y^T P m + m^T P m`` (``c_ii = 1``, ``c_ij = 2``, ``P = Sigma^-1 =
    L^-T L^-1``), so all point x component terms are ``features(y) @ coefficients^T`` with
    ``dim (dim + 3) / 2 + 1`` features per point (28 for the 6-D births, 15 for the 4-D
    clutter). ``y = x - c`` and ``m = mean - c`` are centred on the components' mean ``c`` to
    keep the cancellation small (``alive``: the components whose means count, default all).
    The cancellation still costs about ``eps (|L^-1 y| + |L^-1 m|)^2``: on PETS09-S2L1's
    learned densities (condition numbers up to 1.3e3) the result is within 6e-4 nats of a
    float64 evaluation where the log-density is above -60 (the forward substitution of
    :func:`log_normal_components`: 4e-5), and within 1e-5 relative below; a covariance of
    condition number 1e5 at pixel scale loses up to 1e-2 nats (tested). Rounding can make
    the form slightly negative at a component's mean; it is clipped at 0.

    Why: the point x component terms of a learned mixture (64 components at the 512 birth
    particles of a frame, times the configurations of a sweep) were the largest cost of the
    PHD step under a learned context; as a matrix product they run at the machine's matrix
    rate, and the mixture's logsumexp reads them from memory instead of recomputing the
    substitution in each of its passes (XLA fuses elementwise producers into every consumer).
    """
    dim = means.shape[-1]
    # The factors and coefficients depend on the parameters alone (computed once per run):
    # as loops, they compile to a few kernels instead of about a hundred.
    chol = cholesky_loop(covs)
    eye = jnp.eye(dim, dtype=covs.dtype)
    inverse_t = solve_lower_loop(chol[:, None], eye)  # [K, dim, dim]: row j is L^-1 e_j
    precision = jnp.einsum("kie,kle->kil", inverse_t, inverse_t)  # L^-T L^-1
    counted = jnp.ones(means.shape[0], bool) if alive is None else alive
    count = jnp.sum(counted)
    center = jnp.where(
        count > 0,
        jnp.sum(jnp.where(counted[:, None], means, 0.0), axis=0) / jnp.maximum(count, 1),
        jnp.mean(means, axis=0),
    )
    centred = means - center
    weighted = jnp.einsum("kij,kj->ki", precision, centred)
    rows, cols = np.triu_indices(dim)
    pair_factor = np.where(rows == cols, 1.0, 2.0).astype(np.float32)
    coefficients = jnp.concatenate(
        [
            precision[:, rows, cols] * pair_factor,
            -2.0 * weighted,
            jnp.sum(centred * weighted, axis=-1, keepdims=True),
        ],
        axis=-1,
    )
    y = x - center
    features = jnp.concatenate([y[..., rows] * y[..., cols], y, jnp.ones_like(y[..., :1])], -1)
    return _log_gaussian(jnp.maximum(features @ coefficients.T, 0.0), chol)


def log_normal_components(
    x: Float[Array, "*batch dim"],
    means: Float[Array, "num_components dim"],
    covs: Float[Array, "num_components dim dim"],
) -> Float[Array, "*batch num_components"]:
    """``log N(x; mean_m, cov_m)`` of every point under every component.

    The arithmetic of :func:`log_normal` vmapped over the components (the same forward
    substitution ``L_m s = x - mean_m`` and ``sum_d s_d^2``, term by term), written per state
    dimension on ``[*batch, num_components]`` arrays: XLA fuses the whole evaluation into
    one loop over the point x component pairs, where the vmapped form materialises (and
    re-lays out) a ``[num_components, *batch, dim]`` array of the solved differences. On the
    magnitude sweep's learned birth density (64 components at 512 birth particles, 28
    configurations under ``vmap``) that array was the largest single cost of the step.
    """
    chol = cholesky_loop(covs)  # of the parameters alone: computed once per run
    differences = [x[..., i, None] - means[:, i] for i in range(means.shape[-1])]
    solved = forward_substitution(chol, differences)
    return _log_gaussian(sum(s**2 for s in solved), chol)


#: Frame rate assumed when a sequence does not give one.
DEFAULT_FRAME_RATE = 25.0


def uniform_birth_intensity(
    birth_rate: float, im_width: float, im_height: float, max_speed: float
) -> Intensity:
    """UM birth intensity: ``birth_rate`` births per frame, uniform over the state volume.

    Args:
        birth_rate: ``lambda_s``, expected births per frame, > 0.
        im_width: image width, pixels.
        im_height: image height, pixels.
        max_speed: largest centre speed per axis, pixels per frame.

    Returns:
        A 6-D :class:`~jaxtrack.context.intensity.Intensity` over
        ``[0, W] x [-v, v] x [0, H] x [-v, v] x [1, W] x [1, H]``.
    """
    lower = [0.0, -max_speed, 0.0, -max_speed, 1.0, 1.0]
    upper = [im_width, max_speed, im_height, max_speed, im_width, im_height]
    return uniform_intensity(birth_rate, lower, upper)


def uniform_clutter_intensity(clutter_rate: float, im_width: float, im_height: float) -> Intensity:
    """UM clutter intensity: ``clutter_rate`` false detections per frame, uniform.

    Args:
        clutter_rate: ``lambda_r``, expected false detections per frame, > 0.
        im_width: image width, pixels.
        im_height: image height, pixels.

    Returns:
        A 4-D :class:`~jaxtrack.context.intensity.Intensity` over
        ``[0, W] x [0, H] x [1, W] x [1, H]``.
    """
    return uniform_intensity(
        clutter_rate, [0.0, 0.0, 1.0, 1.0], [im_width, im_height, im_width, im_height]
    )


def birth_speed_limit(im_height: float, frame_rate: float | None = None) -> float:
    """The birth intensity's largest centre speed per axis: ``0.4 * im_height / frame_rate``
    pixels per frame (``frame_rate`` default :data:`DEFAULT_FRAME_RATE`)."""
    frame_rate = DEFAULT_FRAME_RATE if frame_rate is None else frame_rate
    return 0.4 * im_height / frame_rate
