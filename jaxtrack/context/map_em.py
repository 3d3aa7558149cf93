"""Recursive MAP-EM learning of a uniform + Gaussian-mixture density (PHD-context Sec. IV-B).

The learned density is the non-homogeneous mixture of PHD-context eq. 21 (SPEC §1),

    p(x) = pi_u u(x) + (1 - pi_u) sum_m pi_m N(x; mu_m, Sigma_m),

``u = 1/V`` over the box ``[lower, upper]``. It is learned one sample at a time by a pure
``init`` / ``update`` pair: :func:`init_state` (or a grid, :func:`grid_init_birth`,
:func:`grid_init_clutter`) builds a :class:`MixtureState`, the ``update`` of
:func:`map_em_learner` folds in one sample, and :func:`fit` scans it over a batch. Starting
from a grid of many components, the improper Dirichlet prior ``p(pi) ~ prod_m pi_m^-beta``,
``beta = N_par / 2`` (PHD-context eq. 16), drives unsupported components extinct, so the
grid only has to over-estimate the number of modes. :func:`to_intensity` turns the result
into the :class:`~jaxtrack.context.intensity.Intensity` the PHD filter consumes.

One update with a sample ``x`` and learning rate ``lam`` (PHD-context eq. 17-20; SPEC §1):

* Gaussian ownerships ``o_m = pi_m N(x; mu_m, Sigma_m) / g(x)``,
  ``g(x) = sum_j pi_j N(x; mu_j, Sigma_j)`` (eq. 17), in log space.
* Weights, with ``c = lam beta`` and ``M`` live components (eq. 18):
  ``pi_m <- pi_m + lam (o_m / (1 - M c) - pi_m - c / (1 - M c))``. The prior term sits
  inside the ``lam`` bracket as in the paper and in Zivkovic & van der Heijden (PAMI 2004),
  whose recursion this is: it keeps ``sum_m pi_m = 1`` and has the batch MAP estimate
  ``pi_m = (n_m - beta) / (n - M beta)`` as fixed point. (SPEC writes the last term without
  the factor ``lam``; that version neither preserves the sum nor has this fixed point.)
* Means and covariances with rate ``r_m = lam o_m / pi_m`` (old weight; eq. 19-20):
  ``mu_m <- mu_m + r_m (x - mu_m)``,
  ``Sigma_m <- Sigma_m + r_m ((x - mu_m)(x - mu_m)^T + F - Sigma_m)``.
* A component whose weight turns negative dies (``alive = False``, weight 0); the survivors
  are renormalised. Not all can die: the update keeps ``sum_m pi_m = 1``, so the largest
  new weight is at least ``1 / M``.
* Uniform share by plain recursive ML (eq. 17-18 with ``beta = 0``):
  ``o_u = pi_u u(x) / (pi_u u(x) + max(1 - pi_u, f) g(x))``,
  ``pi_u <- clip(pi_u + lam_u (o_u - pi_u), f, 1)``, floor ``f = 1e-3``.

Choices the paper leaves open (all documented where they act):

* **Hierarchical update and the escape from ``pi_u = 1``.** As in the paper, the Gaussian
  part is updated *independently* of ``pi_u``: every sample updates it with full weight (not
  weighted by its Gaussian ownership ``1 - o_u``). With ``pi_u = 1`` at the start a weighted
  update would leave the Gaussians frozen (``1 - o_u = 0``), and ``pi_u = 1`` is an absorbing
  fixed point of ML-EM (``o_u = 1`` whenever ``pi_g = 0``). So the Gaussians learn from the
  first sample, and the uniform's E-step uses ``pi_g`` floored at ``f``: once the Gaussians
  concentrate on the data, ``g(x) / u(x)`` grows, ``o_u`` falls below 1 and ``pi_u`` decays
  towards the ML share of samples the Gaussians do not explain. The price: isolated
  outliers pull on their nearest Gaussian (the Dirichlet prior still stops them from
  creating components of their own), and the split between the uniform and broad Gaussians
  is not identifiable: with a 30% uniform background in 2-D and ample data, broad Gaussians
  model part of the background and ``pi_u`` settles near 0.16, while the density itself is
  learned well. Weighting the Gaussian update by ``1 - o_u`` would not fix that (a broad
  Gaussian explains background as well as the uniform does) and would stall the start.
* **Learning rate.** ``"inverse"``: ``lam = max(1 / (n + n_0), min_rate)`` after ``n``
  samples, where ``n_0 = prior_count K`` counts the initial state as ``prior_count`` samples
  per component slot. It sets how fast the data override the arbitrary grid: the first
  sample a grid component owns moves it by ``min(K / (1 + n_0), 1)`` of the distance, and
  while the prior is capped (below) unsupported components die within about ``n_0`` samples.
  The default ``prior_count = 1`` prunes a 16x14 clutter grid within one pass over ~1500
  samples; 2 moves the grid more gently but prunes about twice as slowly. The uniform share
  uses ``n_0 = 1`` (its initial ``pi_u = 1`` is worth one sample). ``"constant"``:
  ``lam = lam_u = rate``. With ``1/n`` rates the estimate remembers its transient (e.g. the
  samples seen while ``pi_u`` was still near 1) with weight ``O(1/n)``; a few passes of
  :func:`fit` remove most of it.
* **Prior strength while evidence is scarce.** The update needs ``1 - M c > 0``, i.e. more
  (pseudo-)samples than ``M beta``; a 12x10 birth grid in 6-D needs 1620. Before that the
  prior is capped: ``c = min(lam beta, max_prior_mass / M)``, so ``1 - M c >=
  1 - max_prior_mass``. In that phase a component survives only if it owns more than about
  ``max_prior_mass / M`` of the samples: a grid cell that sees no data dies within the
  first ``n_0 (1 - max_prior_mass) / max_prior_mass`` samples (``n_0`` for the default
  0.5), and the exact eq. 18 takes over once ``M`` has dropped (or ``n`` grown) enough.
* **Numerical safety.** ``r_m`` is clipped to ``[0, 1]`` (a component with a tiny weight that
  owns a sample would otherwise overshoot and lose positive definiteness). With ``r_m <= 1``
  the covariance update is a convex combination of ``Sigma_m`` and ``(x - mu)(x - mu)^T + F``
  with ``F = diag(variance_floor)``, so a covariance that starts above ``F`` (which
  :func:`init_state` enforces) stays above ``F``: each sample acts as a tiny Gaussian blob of
  covariance ``F``, which floors the eigenvalues smoothly (no ``eigh``, finite gradients) at
  the cost of a bias ``F`` in the learned covariances. Dead components keep finite,
  positive-definite values in their slots and get ownership exactly 0.
* **Epochs.** :func:`fit` can revisit the samples; later passes do not count the samples as
  new evidence (``n`` stays at the number of distinct samples), so the prior keeps the
  strength it has for the batch MAP estimate of that data set instead of weakening with
  every pass.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from jaxtrack.context.intensity import Intensity, log_normal

#: Minimum value of the uniform weight ``pi_u`` (PHD-context Sec. IV-B).
UNIFORM_FLOOR = 1e-3


class MixtureState(NamedTuple):
    """State of the recursive MAP-EM learner (the ``lax.scan`` carry).

    Attributes:
        uniform_weight: ``pi_u`` in ``[1e-3, 1]``; the Gaussian share is ``1 - pi_u``.
        weights: Gaussian-part weights ``pi_m`` (sum 1 over live components; 0 when dead).
        means: component means; dead slots keep their last (finite) value.
        covs: component covariances, symmetric positive definite, all slots.
        alive: True for live components.
        count: number of distinct samples learned from, ``n``.
        lower: lower corner of the uniform's volume.
        upper: upper corner of the uniform's volume.
        variance_floor: ``diag(F)``, the smallest variance a covariance can reach per axis.
    """

    uniform_weight: Float[Array, ""]
    weights: Float[Array, " num_components"]
    means: Float[Array, "num_components dim"]
    covs: Float[Array, "num_components dim dim"]
    alive: Bool[Array, " num_components"]
    count: Int[Array, ""]
    lower: Float[Array, " dim"]
    upper: Float[Array, " dim"]
    variance_floor: Float[Array, " dim"]


class MapEMLearner(NamedTuple):
    """A recursive MAP-EM learner; its static settings live in closures (:func:`map_em_learner`).

    Attributes:
        update: ``(state, sample, valid=True, new_sample=True) -> state``: one recursive
            step; ``valid=False`` returns the state unchanged (padded samples);
            ``new_sample=False`` revisits a sample without counting it as new evidence.
        learning_rates: ``(state, count) -> (lam, lam_u)``: Gaussian-part and uniform
            learning rates after ``count`` samples.
    """

    update: Callable
    learning_rates: Callable


def num_free_parameters(dim: int) -> int:
    """``N_par``: mean plus full covariance of one ``dim``-D Gaussian (27 in 6-D, 14 in 4-D)."""
    return dim + dim * (dim + 1) // 2


def dirichlet_beta(dim: int) -> float:
    """``beta = N_par / 2``, the improper Dirichlet exponent (PHD-context eq. 16)."""
    return num_free_parameters(dim) / 2


def map_em_learner(
    schedule: str = "inverse",
    *,
    rate: float = 0.01,
    prior_count: float = 1.0,
    min_rate: float = 0.0,
    max_prior_mass: float = 0.5,
    uniform_floor: float = UNIFORM_FLOOR,
) -> MapEMLearner:
    """Builds the recursive MAP-EM update of PHD-context eq. 17-21 (see the module docstring).

    Args:
        schedule: ``"inverse"`` (``lam = max(1 / (n + prior_count K), min_rate)``, uniform
            share ``max(1 / (n + 1), min_rate)``) or ``"constant"`` (``lam = rate``).
        rate: the constant learning rate (``"constant"`` only), in ``(0, 1)``.
        prior_count: ``"inverse"`` only: pseudo-samples per component slot that the initial
            state is worth (the offset ``n_0 = prior_count K``).
        min_rate: ``"inverse"`` only: floor of the learning rates (0: pure ``1/n``; positive:
            the estimate keeps adapting, with an effective memory of ``1/min_rate`` samples).
        max_prior_mass: cap on ``M c`` while evidence is scarce, in ``(0, 1)``.
        uniform_floor: smallest uniform weight ``pi_u``.

    Returns:
        The learner (:class:`MapEMLearner`).

    Raises:
        ValueError: an unknown schedule or a setting out of range.
    """
    if schedule not in ("inverse", "constant"):
        raise ValueError(f"schedule must be 'inverse' or 'constant', got {schedule!r}")
    if schedule == "constant" and not 0 < rate < 1:
        raise ValueError(f"rate must lie in (0, 1), got {rate}")
    if not prior_count > 0:
        raise ValueError(f"prior_count must be positive, got {prior_count}")
    if not 0 <= min_rate < 1:
        raise ValueError(f"min_rate must lie in [0, 1), got {min_rate}")
    if not 0 < max_prior_mass < 1:
        raise ValueError(f"max_prior_mass must lie in (0, 1), got {max_prior_mass}")
    if not 0 < uniform_floor < 1:
        raise ValueError(f"uniform_floor must lie in (0, 1), got {uniform_floor}")

    def learning_rates(state: MixtureState, count) -> tuple[Array, Array]:
        dtype = state.weights.dtype
        if schedule == "constant":
            lam = jnp.asarray(rate, dtype)
            return lam, lam
        n = jnp.asarray(count, dtype)
        offset = prior_count * state.weights.shape[-1]
        lam = jnp.maximum(1 / (n + offset), min_rate)
        lam_u = jnp.maximum(1 / (n + 1), min_rate)
        return lam, lam_u

    def update(
        state: MixtureState,
        sample: Float[Array, " dim"],
        valid: Bool[Array, ""] | bool = True,
        new_sample: Bool[Array, ""] | bool = True,
    ) -> MixtureState:
        """One recursive MAP-EM step (PHD-context eq. 17-21) with one sample.

        Args:
            state: the current estimate.
            sample: the new sample ``x``.
            valid: False for a padded sample: the state is returned unchanged.
            new_sample: False when revisiting a sample (later epochs): ``n`` does not grow.

        Returns:
            The updated state.
        """
        valid = jnp.asarray(valid)
        dtype = state.weights.dtype
        x = jnp.where(valid, jnp.asarray(sample, dtype), 0.5 * (state.lower + state.upper))
        count = state.count + (valid & jnp.asarray(new_sample)).astype(state.count.dtype)
        lam, lam_u = learning_rates(state, jnp.maximum(count, 1))
        dim = x.shape[-1]
        beta = dirichlet_beta(dim)

        alive = state.alive
        weights = jnp.where(alive, state.weights, 0.0)
        safe_weights = jnp.where(alive, weights, 1.0)
        # eq. 17: ownerships of the Gaussian part, in log space
        log_components = jax.vmap(lambda m, c: log_normal(x, m, c))(state.means, state.covs)
        log_joint = jnp.where(alive, jnp.log(safe_weights) + log_components, -jnp.inf)
        log_gauss = jax.nn.logsumexp(log_joint)
        ownership = jnp.where(alive, jnp.exp(log_joint - log_gauss), 0.0)

        # uniform share: recursive ML with pi_g floored in the E-step (escape from pi_u = 1)
        pi_u = state.uniform_weight
        log_volume = jnp.sum(jnp.log(state.upper - state.lower))
        gaussian_share = jnp.maximum(1 - pi_u, uniform_floor)
        own_uniform = jax.nn.sigmoid(
            jnp.log(pi_u) - log_volume - jnp.log(gaussian_share) - log_gauss
        )
        new_pi_u = jnp.clip(pi_u + lam_u * (own_uniform - pi_u), uniform_floor, 1.0)

        # eq. 18: MAP weights with the improper Dirichlet prior (capped while evidence is scarce)
        num_alive = jnp.sum(alive).astype(dtype)
        prior = jnp.minimum(lam * beta, max_prior_mass / num_alive)
        denominator = 1 - num_alive * prior
        new_weights = weights + lam * (ownership / denominator - weights - prior / denominator)
        new_weights = jnp.where(alive, new_weights, 0.0)

        # eq. 19-20: means and covariances, rate lam o_m / pi_m (old weight) clipped to [0, 1]
        step = jnp.minimum(lam * ownership / safe_weights, 1.0)[:, None]
        diff = x - state.means
        new_means = state.means + step * diff
        scatter = diff[:, :, None] * diff[:, None, :] + jnp.diag(state.variance_floor)
        new_covs = state.covs + step[:, :, None] * (scatter - state.covs)
        new_covs = 0.5 * (new_covs + jnp.swapaxes(new_covs, -1, -2))

        # extinction of components whose weight turned negative, then renormalisation; the
        # update preserves sum_m pi_m = 1, so the largest weight stays >= 1 / M > 0
        survive = alive & (new_weights > 0)
        kept = jnp.where(survive, new_weights, 0.0)
        kept = kept / jnp.sum(kept)

        new_state = state._replace(
            uniform_weight=new_pi_u,
            weights=kept.astype(dtype),
            means=new_means,
            covs=new_covs,
            alive=survive,
            count=count,
        )
        return jax.tree_util.tree_map(lambda a, b: jnp.where(valid, a, b), new_state, state)

    return MapEMLearner(update=update, learning_rates=learning_rates)


def fit(
    learner: MapEMLearner,
    state: MixtureState,
    samples: Float[Array, "num_samples dim"],
    mask: Bool[Array, " num_samples"] | None = None,
    num_epochs: int = 1,
) -> MixtureState:
    """Learns from a batch of samples: ``lax.scan`` of ``learner.update`` over them.

    Args:
        learner: from :func:`map_em_learner` (static under ``jax.jit``).
        state: the starting estimate (e.g. a grid from :func:`grid_init_birth`).
        samples: the samples, in the order they are learned.
        mask: False for padded samples (skipped); default: all valid.
        num_epochs: passes over the samples (static); passes after the first revisit the
            samples without counting them as new evidence (see the module docstring).

    Returns:
        The estimate after the last sample of the last pass.

    Raises:
        ValueError: ``num_epochs < 1``.
    """
    if num_epochs < 1:
        raise ValueError(f"num_epochs must be >= 1, got {num_epochs}")
    samples = jnp.asarray(samples, state.weights.dtype)
    if mask is None:
        mask = jnp.ones(samples.shape[0], bool)

    def run_pass(state, new_sample):
        def body(state, inputs):
            sample, valid = inputs
            return learner.update(state, sample, valid, new_sample), None

        state, _ = jax.lax.scan(body, state, (samples, jnp.asarray(mask)))
        return state

    for epoch in range(num_epochs):
        state = run_pass(state, epoch == 0)
    return state


#: :func:`fit` compiled once per learner, shapes and pass count (the learner and the pass
#: count are static): the one compiled fit that the learning and its held-out check share.
jit_fit = jax.jit(fit, static_argnums=(0, 4))


def to_intensity(state: MixtureState, magnitude: Float[Array, ""] | float) -> Intensity:
    """The learned intensity ``magnitude * p(x)`` (PHD-context eq. 12-13 with eq. 21).

    Args:
        state: the learned density.
        magnitude: expected events per frame (``lambda_s`` or ``lambda_r``), e.g. from
            :func:`estimate_magnitude`.

    Returns:
        The :class:`~jaxtrack.context.intensity.Intensity` (weight 0 marks dead components).
    """
    return Intensity(
        magnitude=jnp.asarray(magnitude, state.weights.dtype),
        uniform_weight=state.uniform_weight,
        lower=state.lower,
        upper=state.upper,
        weights=jnp.where(state.alive, state.weights, 0.0),
        means=state.means,
        covs=state.covs,
    )


def estimate_magnitude(num_events: int | float, num_frames: int) -> float:
    """Average number of events per frame, ``lambda = num_events / num_frames`` (Sec. IV-B).

    Args:
        num_events: birth or clutter events counted over the training frames.
        num_frames: number of training frames (> 0).

    Returns:
        The magnitude ``lambda_s`` or ``lambda_r``.

    Raises:
        ValueError: ``num_frames`` is not positive or ``num_events`` is negative.
    """
    if num_frames <= 0:
        raise ValueError(f"num_frames must be positive, got {num_frames}")
    if num_events < 0:
        raise ValueError(f"num_events must be >= 0, got {num_events}")
    return float(num_events) / float(num_frames)


def init_state(
    means,
    covs,
    lower,
    upper,
    *,
    weights=None,
    variance_floor=None,
    uniform_weight: float = 1.0,
    capacity: int | None = None,
    dtype=jnp.float32,
) -> MixtureState:
    """Builds a starting state (host-side) with ``pi_u`` and the components given.

    Covariances are symmetrised and their eigenvalues floored at ``F = diag(variance_floor)``
    (in the ``F``-whitened space: ``Sigma <- F^1/2 V max(D, 1) V^T F^1/2``), which the update
    then preserves.

    Args:
        means: ``[M, dim]`` initial means.
        covs: ``[M, dim, dim]`` initial covariances.
        lower: ``[dim]`` lower corner of the volume.
        upper: ``[dim]`` upper corner (above ``lower``).
        weights: ``[M]`` initial Gaussian weights; default equal.
        variance_floor: ``[dim]`` smallest variance per axis; default
            ``(1e-3 (upper - lower))^2``.
        uniform_weight: initial ``pi_u`` (1 in the paper).
        capacity: number of slots ``K >= M``; extra slots are dead. Default ``M``.
        dtype: floating dtype of the state.

    Returns:
        The state with ``count = 0``.
    """
    means = np.asarray(means, np.float64)
    covs = np.asarray(covs, np.float64)
    lower = np.asarray(lower, np.float64)
    upper = np.asarray(upper, np.float64)
    num, dim = means.shape
    if covs.shape != (num, dim, dim) or lower.shape != (dim,) or upper.shape != (dim,):
        raise ValueError(
            f"shapes do not match: means {means.shape}, covs {covs.shape}, "
            f"lower {lower.shape}, upper {upper.shape}"
        )
    if not np.all(upper > lower):
        raise ValueError("upper must exceed lower on every axis")
    weights = np.full(num, 1.0 / num) if weights is None else np.asarray(weights, np.float64)
    if weights.shape != (num,) or np.any(weights <= 0):
        raise ValueError("weights must be positive, one per component")
    if variance_floor is None:
        variance_floor = (1e-3 * (upper - lower)) ** 2
    floor = np.broadcast_to(np.asarray(variance_floor, np.float64), (dim,))
    if np.any(floor <= 0):
        raise ValueError("variance_floor must be positive")
    if not 0 < uniform_weight <= 1:
        raise ValueError(f"uniform_weight must lie in (0, 1], got {uniform_weight}")
    capacity = num if capacity is None else capacity
    if capacity < num:
        raise ValueError(f"capacity {capacity} is below the number of components {num}")

    scale = np.sqrt(floor)
    whitened = 0.5 * (covs + np.swapaxes(covs, -1, -2)) / np.outer(scale, scale)
    values, vectors = np.linalg.eigh(whitened)
    whitened = np.einsum("mij,mj,mkj->mik", vectors, np.maximum(values, 1.0), vectors)
    covs = whitened * np.outer(scale, scale)
    covs = 0.5 * (covs + np.swapaxes(covs, -1, -2))

    pad = capacity - num
    pad_means = np.broadcast_to(0.5 * (lower + upper), (pad, dim))
    pad_covs = np.broadcast_to(np.diag((upper - lower) ** 2), (pad, dim, dim))
    return MixtureState(
        uniform_weight=jnp.asarray(uniform_weight, dtype),
        weights=jnp.asarray(np.concatenate([weights / weights.sum(), np.zeros(pad)]), dtype),
        means=jnp.asarray(np.concatenate([means, pad_means]), dtype),
        covs=jnp.asarray(np.concatenate([covs, pad_covs]), dtype),
        alive=jnp.asarray(np.arange(capacity) < num),
        count=jnp.asarray(0, jnp.int32),
        lower=jnp.asarray(lower, dtype),
        upper=jnp.asarray(upper, dtype),
        variance_floor=jnp.asarray(floor, dtype),
    )


def grid_init_birth(
    image_width: float,
    image_height: float,
    mean_size: tuple[float, float],
    *,
    grid: tuple[int, int] = (12, 10),
    max_speed: float = 8.0,
    size_range: tuple[tuple[float, float], tuple[float, float]] | None = None,
    dtype=jnp.float32,
) -> MixtureState:
    """Initial birth density: a grid of 6-D Gaussians and ``pi_u = 1`` (PHD-context Sec. IV-B).

    State order ``(y1, vy1, y2, vy2, w, h)``. Component ``(i, j)`` has mean
    ``((i + 1/2) W / g1, 0, (j + 1/2) H / g2, 0, w_bar, h_bar)`` (zero velocity, mean object
    size) and diagonal covariance with standard deviations: the grid spacing ``(W / g1,
    H / g2)`` on positions (neighbours overlap, so the grid covers the image evenly),
    ``max_speed / 2`` on velocities and half the mean size on sizes. The uniform's volume is
    the image times ``[-max_speed, max_speed]^2`` times the size range.

    Args:
        image_width: ``W``, pixels.
        image_height: ``H``, pixels.
        mean_size: ``(w_bar, h_bar)``, mean object size, pixels.
        grid: ``(g1, g2)`` components along the image columns and rows (12 x 10 in the paper).
        max_speed: bound of the volume's velocity range, pixels/frame.
        size_range: ``((w_min, h_min), (w_max, h_max))``; default ``(mean_size / 4,
            4 mean_size)``.
        dtype: floating dtype of the state.

    Returns:
        The starting :class:`MixtureState` (``g1 g2`` live components).
    """
    (w_bar, h_bar) = mean_size
    (w_min, h_min), (w_max, h_max) = size_range or ((w_bar / 4, h_bar / 4), (4 * w_bar, 4 * h_bar))
    cols, rows, (step1, step2) = _grid_centres(image_width, image_height, grid)
    num = cols.size
    zeros = np.zeros(num)
    means = np.stack([cols, zeros, rows, zeros, zeros + w_bar, zeros + h_bar], axis=-1)
    stds = np.array([step1, max_speed / 2, step2, max_speed / 2, w_bar / 2, h_bar / 2])
    covs = np.broadcast_to(np.diag(stds**2), (num, 6, 6))
    lower = [0.0, -max_speed, 0.0, -max_speed, w_min, h_min]
    upper = [image_width, max_speed, image_height, max_speed, w_max, h_max]
    return init_state(means, covs, lower, upper, dtype=dtype)


def grid_init_clutter(
    image_width: float,
    image_height: float,
    mean_size: tuple[float, float],
    *,
    grid: tuple[int, int] = (16, 14),
    size_range: tuple[tuple[float, float], tuple[float, float]] | None = None,
    dtype=jnp.float32,
) -> MixtureState:
    """Initial clutter density: a grid of 4-D Gaussians and ``pi_u = 1`` (PHD-context Sec. IV-B).

    Measurement order ``(y1, y2, w, h)`` (box centre and size). Component ``(i, j)`` has mean
    ``((i + 1/2) W / g1, (j + 1/2) H / g2, w_bar, h_bar)`` and diagonal covariance with
    standard deviations ``(W / g1, H / g2, w_bar / 2, h_bar / 2)``. The uniform's volume is
    the image times the size range.

    Args:
        image_width: ``W``, pixels.
        image_height: ``H``, pixels.
        mean_size: ``(w_bar, h_bar)``, mean detection size, pixels.
        grid: ``(g1, g2)`` components along the image columns and rows (16 x 14 in the paper).
        size_range: ``((w_min, h_min), (w_max, h_max))``; default ``(mean_size / 4,
            4 mean_size)``.
        dtype: floating dtype of the state.

    Returns:
        The starting :class:`MixtureState` (``g1 g2`` live components).
    """
    (w_bar, h_bar) = mean_size
    (w_min, h_min), (w_max, h_max) = size_range or ((w_bar / 4, h_bar / 4), (4 * w_bar, 4 * h_bar))
    cols, rows, (step1, step2) = _grid_centres(image_width, image_height, grid)
    num = cols.size
    means = np.stack([cols, rows, np.full(num, w_bar), np.full(num, h_bar)], axis=-1)
    stds = np.array([step1, step2, w_bar / 2, h_bar / 2])
    covs = np.broadcast_to(np.diag(stds**2), (num, 4, 4))
    lower = [0.0, 0.0, w_min, h_min]
    upper = [image_width, image_height, w_max, h_max]
    return init_state(means, covs, lower, upper, dtype=dtype)


def _grid_centres(width, height, grid):
    """Cell centres of a ``g1 x g2`` grid over ``[0, width] x [0, height]`` and the spacing."""
    g1, g2 = grid
    if g1 < 1 or g2 < 1 or width <= 0 or height <= 0:
        raise ValueError(f"need a positive grid and image size, got {grid}, {width}x{height}")
    step1, step2 = width / g1, height / g2
    cols, rows = np.meshgrid((np.arange(g1) + 0.5) * step1, (np.arange(g2) + 0.5) * step2)
    return cols.ravel(), rows.ravel(), (step1, step2)
