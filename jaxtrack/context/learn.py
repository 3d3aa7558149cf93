"""Learning a scene's birth and clutter intensities from a training span (PHD-context Sec. IV).

The math of ``jaxtrack learn-context`` (the pipeline itself, which runs a tracker and reads
files, is :func:`jaxtrack.pipelines.context.learn_context`):

1. **Events** (:mod:`jaxtrack.context.samples`): birth events from the trajectories of a
   tracker run with uniform (UM) intensities or from the
   ground truth; clutter events from the ground truth, from the tracker or from a file of
   interactive labels.
2. **Densities** by recursive MAP-EM (:mod:`jaxtrack.context.map_em`) from the paper's grid
   initialisations (births 12x10 in 6-D, clutter 16x14 in 4-D) centred on the events'
   mean box size.
3. **Held-out check** (:mod:`jaxtrack.context.heldout`, the default of
   :func:`~jaxtrack.pipelines.context.learn_context`): time-blocked cross-validation picks
   each density's learner setting and its fall-back shares (uniform ``pi_u`` and an
   evenly spread background ``pi_b``) by the log-likelihood of unseen events, so that a
   density learned from little or non-stationary evidence keeps mass where events were
   not (yet) seen.
4. **Intensities** ``gamma(x) = lambda_s p(x | b)``, ``kappa(z) = lambda_r p(z | c)``
   (PHD-context eq. 12-13) with the magnitudes estimated as events per frame, keeping only
   the live mixture components (:func:`live_components`).
5. **The first frame's intensity** ``gamma_0(x) = lambda_0 p(x | o)`` (not in the paper):
   where the targets *are*, learned like the births (same grid, background and held-out
   check) from occupancy events (the states of the trajectories in view, every
   :data:`~jaxtrack.context.samples.OCCUPANCY_STRIDE`-th box), with ``lambda_0`` the mean
   number of targets in view per training frame. The tracker's first frame meets the
   targets already in the scene; the birth density says where targets *enter*, and the
   uniform first-frame intensity of UM (magnitude ``initial_rate``, 0.2) spreads its mass
   over every size and velocity. A run that starts mid-scene (a test span, a stream picked
   up late) then starts the targets in view as fast as the birth density starts those
   entering.

**Magnitude and the volume.** Events happen inside the volume (the image), but the learned
Gaussians are not truncated to it: a component near the border, or a broad one, puts some
of its mass outside, and ``lambda p`` would then expect fewer than ``lambda`` events per
frame where events can happen. The intensity's magnitude is therefore
``lambda / P_p(V)``, with ``P_p(V) = pi_u + (1 - pi_u) P_GMM(V)`` estimated by Monte Carlo
(:func:`volume_mass`), so that ``int_V gamma = lambda_s`` and ``int_V kappa = lambda_r``
exactly as measured. The metadata holds both ``lambda`` (``magnitude``) and ``P_p(V)``
(``volume_mass``; typically above 0.95).

**Volumes.** The uniform components live on exactly the volumes of the tracker's UM
intensities (:func:`jaxtrack.filters.phd_defaults.default_phd_params`): the image times
``[1, W] x [1, H]`` box sizes, and for births also centre velocities in ``[-v, v]^2`` with
``v = 0.4 H / fps`` pixels/frame. So ``pi_u = 1`` reproduces UM's density exactly, and a
learned intensity can replace the UM one in the tracker's parameters.

**Learning schedule** (defaults measured on the synthetic scenes of
:mod:`jaxtrack.datasets.synthetic`, 400 training frames: about 25 births and 750 clutter
detections). The ``1/n`` learning rate of :func:`~jaxtrack.context.map_em.map_em_learner`
with ``prior_count = 1`` counts the 120-component birth grid as 120 pseudo-samples, so a few
dozen births move it little per pass: births get :data:`BIRTH_EPOCHS` passes, which lets
the Dirichlet prior prune the grid down to the entry zones. Clutter events are plentiful;
:data:`CLUTTER_EPOCHS` passes prune the 224-component grid to the clutter sources. Later
passes do not count samples as new evidence (see :func:`~jaxtrack.context.map_em.fit`), so
extra passes converge to the batch MAP estimate of the data rather than overfit. Samples are
learned in a seeded random order, so that the estimate does not depend on when in the span
an event happened.

**Snapshots** of the mixture after the first ``n`` samples of the first pass (for the
evolution figures, PHD-context Fig. 7 and 11) are taken at :data:`SNAPSHOT_FRACTIONS` of
the samples, plus the final estimate after all passes.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.context.intensity import (
    Intensity,
    birth_speed_limit,
    sample,
    uniform_birth_intensity,
    uniform_clutter_intensity,
)
from jaxtrack.context.map_em import (
    MapEMLearner,
    MixtureState,
    grid_init_birth,
    grid_init_clutter,
    jit_fit,
    map_em_learner,
)
from jaxtrack.context.samples import EventSamples

#: Default passes over the birth events.
BIRTH_EPOCHS = 15
#: Default passes over the clutter events.
CLUTTER_EPOCHS = 5
#: Fractions of the samples after which the first pass is snapshotted.
SNAPSHOT_FRACTIONS = (0.0, 0.05, 0.2, 0.5, 1.0)
#: The default learner: ``1/n`` learning rates, one pseudo-sample per grid component.
DEFAULT_LEARNER = map_em_learner()
#: Position axes of the birth state ``(y1, vy1, y2, vy2, w, h)`` and clutter ``(y1, y2, w, h)``.
BIRTH_POSITION_DIMS = (0, 2)
CLUTTER_POSITION_DIMS = (0, 1)


class Snapshot(NamedTuple):
    """The mixture after some samples.

    Attributes:
        num_samples: samples learned from (first pass), or the total after all passes.
        epochs: completed passes (0 while in the first pass, ``num_epochs`` at the end).
        state: the estimate.
        samples: ``[num_samples, dim]`` the samples learned so far, in the order learned.
    """

    num_samples: int
    epochs: int
    state: MixtureState
    samples: np.ndarray


class LearnedContext(NamedTuple):
    """Everything :func:`learn_context` produces.

    Attributes:
        birth: the learned birth intensity ``gamma(x)`` (6-D state space).
        clutter: the learned clutter intensity ``kappa(z)`` (4-D measurement space).
        metadata: JSON-serialisable summary (sequence, frames, sources, sample counts,
            measured magnitudes, volume masses, epochs, live components, seed), saved with
            the context.
        birth_samples: the birth events learned from.
        clutter_samples: the clutter events learned from.
        birth_snapshots: evolution of the birth mixture (see :data:`SNAPSHOT_FRACTIONS`).
        clutter_snapshots: evolution of the clutter mixture.
        initial: the learned first-frame intensity (6-D state space; the targets in view),
            None when not learned.
        initial_samples: the occupancy events it was learned from.
    """

    birth: Intensity
    clutter: Intensity
    metadata: dict
    birth_samples: EventSamples
    clutter_samples: EventSamples
    birth_snapshots: tuple[Snapshot, ...]
    clutter_snapshots: tuple[Snapshot, ...]
    initial: Intensity | None = None
    initial_samples: EventSamples | None = None


def uniform_volumes(
    im_width: float, im_height: float, frame_rate: float | None
) -> tuple[Intensity, Intensity]:
    """The tracker's UM birth and clutter intensities, whose volumes the learning reuses.

    Args:
        im_width: image width, pixels.
        im_height: image height, pixels.
        frame_rate: frames per second (None: the tracker's default).

    Returns:
        ``(birth, clutter)`` uniform intensities with the volumes of
        :func:`~jaxtrack.filters.phd_defaults.default_phd_params` (unit magnitudes).
    """
    max_speed = birth_speed_limit(im_height, frame_rate)
    return (
        uniform_birth_intensity(1.0, im_width, im_height, max_speed),
        uniform_clutter_intensity(1.0, im_width, im_height),
    )


def birth_grid(
    uniform: Intensity, mean_size: tuple[float, float], grid: tuple[int, int] = (12, 10)
) -> MixtureState:
    """The paper's 12x10 birth grid on the volume of a UM birth intensity.

    Args:
        uniform: a 6-D intensity over ``[0, W] x [-v, v] x [0, H] x [-v, v] x [w0, w1] x
            [h0, h1]``.
        mean_size: mean box ``(w, h)`` of the birth events.
        grid: components along the image columns and rows.

    Returns:
        The starting state (:func:`~jaxtrack.context.map_em.grid_init_birth`).
    """
    lower, upper = np.asarray(uniform.lower), np.asarray(uniform.upper)
    return grid_init_birth(
        float(upper[0]),
        float(upper[2]),
        mean_size,
        grid=grid,
        max_speed=float(upper[1]),
        size_range=((float(lower[4]), float(lower[5])), (float(upper[4]), float(upper[5]))),
    )


def clutter_grid(
    uniform: Intensity, mean_size: tuple[float, float], grid: tuple[int, int] = (16, 14)
) -> MixtureState:
    """The paper's 16x14 clutter grid on the volume of a UM clutter intensity.

    Args:
        uniform: a 4-D intensity over ``[0, W] x [0, H] x [w0, w1] x [h0, h1]``.
        mean_size: mean box ``(w, h)`` of the clutter events.
        grid: components along the image columns and rows.

    Returns:
        The starting state (:func:`~jaxtrack.context.map_em.grid_init_clutter`).
    """
    lower, upper = np.asarray(uniform.lower), np.asarray(uniform.upper)
    return grid_init_clutter(
        float(upper[0]),
        float(upper[1]),
        mean_size,
        grid=grid,
        size_range=((float(lower[2]), float(lower[3])), (float(upper[2]), float(upper[3]))),
    )


def learn_density(
    state: MixtureState,
    samples: np.ndarray,
    num_epochs: int,
    key: jax.Array,
    learner: MapEMLearner | None = None,
    snapshot_fractions: tuple[float, ...] = SNAPSHOT_FRACTIONS,
) -> tuple[MixtureState, tuple[Snapshot, ...]]:
    """Recursive MAP-EM over the samples in a random order, with snapshots of the first pass.

    Args:
        state: the starting estimate (a grid).
        samples: ``[num_samples, dim]`` events (at least one).
        num_epochs: passes over the samples.
        key: PRNG key of the sample order.
        learner: the update (default: ``map_em_learner()``, ``1/n`` rates).
        snapshot_fractions: fractions of the samples after which the first pass is
            snapshotted (0: the starting grid).

    Returns:
        ``(final_state, snapshots)``; the last snapshot is the final state.
    """
    learner = learner or DEFAULT_LEARNER
    samples = np.asarray(samples, np.float64)
    num = samples.shape[0]
    order = np.asarray(jax.random.permutation(key, num))
    shuffled = jnp.asarray(samples[order], state.weights.dtype)
    snapshots = []
    current, done = state, 0
    for fraction in snapshot_fractions:
        target = round(fraction * num)
        if target > done:
            mask = (np.arange(num) >= done) & (np.arange(num) < target)
            current = jit_fit(learner, current, shuffled, jnp.asarray(mask), 1)
            done = target
        snapshots.append(Snapshot(done, 0, current, samples[order[:done]]))
    final = jit_fit(learner, state, shuffled, jnp.ones(num, bool), num_epochs)
    snapshots.append(Snapshot(num, num_epochs, final, samples[order]))
    return final, tuple(snapshots)


def marginal(intensity: Intensity, dims: tuple[int, ...]) -> Intensity:
    """The intensity marginalised onto the axes ``dims`` (e.g. image positions).

    The uniform over a box marginalises to the uniform over the sub-box and a Gaussian to
    the Gaussian of the selected mean entries and covariance block, so the result is again
    an :class:`Intensity` with the same magnitude and weights.

    Args:
        intensity: the intensity.
        dims: the axes kept, in order.

    Returns:
        The marginal intensity over ``len(dims)`` axes.
    """
    index = jnp.asarray(dims)
    return intensity._replace(
        lower=intensity.lower[index],
        upper=intensity.upper[index],
        means=intensity.means[:, index],
        covs=intensity.covs[:, index][:, :, index],
    )


def live_components(intensity: Intensity) -> Intensity:
    """The intensity without its dead (weight 0) mixture components.

    The learned mixtures keep a handful of the grid's 120 or 224 slots alive; dropping the
    rest makes every evaluation (e.g. per particle in the PHD filter) proportionally
    cheaper. At least one slot is kept, so the arrays are never empty.

    Args:
        intensity: e.g. from :func:`~jaxtrack.context.map_em.to_intensity`.

    Returns:
        The same intensity over the live components only.
    """
    keep = np.flatnonzero(np.asarray(intensity.weights) > 0)
    keep = keep if keep.size else np.zeros(1, np.int64)
    return intensity._replace(
        weights=intensity.weights[keep], means=intensity.means[keep], covs=intensity.covs[keep]
    )


def volume_mass(intensity: Intensity, key: jax.Array, num_samples: int = 100_000) -> float:
    """``P_p(V)``: the share of the density inside its uniform's volume (Monte Carlo).

    ``P_p(V) = pi_u + (1 - pi_u) P_GMM(V)``; the mixture's share is the fraction of
    ``num_samples`` draws from it that fall inside ``[lower, upper]`` (standard error below
    ``0.5 / sqrt(num_samples)``).

    Args:
        intensity: the intensity (its magnitude is ignored).
        key: PRNG key of the draws.
        num_samples: number of draws.

    Returns:
        The mass in ``(0, 1]`` (1 for a purely uniform density).
    """
    uniform_weight = float(intensity.uniform_weight)
    if uniform_weight >= 1 or not np.any(np.asarray(intensity.weights) > 0):
        return 1.0
    mixture = intensity._replace(uniform_weight=jnp.zeros_like(intensity.uniform_weight))
    draws = sample(key, mixture, num_samples)
    inside = jnp.all((draws >= intensity.lower) & (draws <= intensity.upper), axis=-1)
    mixture_mass = max(float(jnp.mean(inside)), 1.0 / num_samples)
    return uniform_weight + (1 - uniform_weight) * mixture_mass
