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
from jaxtyping import Array, Float

from jaxtrack.linalg import cholesky, solve_lower


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


def log_density(intensity: Intensity, x: Float[Array, "*batch dim"]) -> Float[Array, "*batch"]:
    """``log p(x)`` of the normalised density (PHD-context eq. 21), for a batch of points."""
    log_uniform = jnp.log(intensity.uniform_weight) - log_volume(intensity)
    alive = intensity.weights > 0
    safe_weights = jnp.where(alive, intensity.weights, 1.0)
    log_gauss = jax.vmap(lambda mean, cov: log_normal(x, mean, cov), out_axes=-1)(
        intensity.means, intensity.covs
    )
    log_components = jnp.where(alive, jnp.log(safe_weights) + log_gauss, -jnp.inf)
    has_gaussian = jnp.any(alive) & (intensity.uniform_weight < 1)
    gaussian_share = jnp.where(has_gaussian, 1 - intensity.uniform_weight, 1.0)
    log_mixture = jnp.log(gaussian_share) + _logsumexp_or_neg_inf(log_components)
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
    dim = mean.shape[-1]
    chol = cholesky(cov)
    solved = solve_lower(chol, x - mean)
    log_det = 2 * jnp.sum(jnp.log(jnp.diagonal(chol)))
    return -0.5 * (jnp.sum(solved**2, axis=-1) + log_det + dim * jnp.log(2 * jnp.pi))


def _logsumexp_or_neg_inf(values):
    """logsumexp over the last axis that returns -inf (with zero gradient) when all are -inf."""
    finite = jnp.isfinite(values)
    top = jnp.max(jnp.where(finite, values, -1e30), axis=-1, keepdims=True)
    total = jnp.sum(jnp.where(finite, jnp.exp(values - top), 0.0), axis=-1)
    any_finite = jnp.any(finite, axis=-1)
    safe_total = jnp.where(any_finite, total, 1.0)
    return jnp.where(any_finite, jnp.log(safe_total) + top[..., 0], -jnp.inf)


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
