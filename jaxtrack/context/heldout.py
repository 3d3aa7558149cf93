"""How much a training span says: held-out likelihood, the uniform share and model selection.

A density learned from 20 births or from clutter that is spread evenly over the image can be
*worse* than the uniform one on frames it has not seen, while its in-sample fit looks
excellent (the recursive MAP-EM of :mod:`jaxtrack.context.map_em` drives ``pi_u`` to its
floor as soon as the Gaussians explain the training events better than ``u``, which they
always do in sample). This module measures what the events say about *unseen* events and
sets the uniform share and the learner's settings from that.

**Folds.** The training events are cut by time into ``K`` contiguous blocks of (nearly)
equal counts (:func:`time_folds`; :data:`NUM_FOLDS` by default). Time blocks, not a random
split, because the question is whether what happened earlier predicts what happens later (a
zone used only late in the span, a clutter source that switches on).

**Out-of-fold densities.** For fold ``k`` the mixture's Gaussian part ``g_{-k}`` is learned
from the other folds with the candidate settings, and every event ``x_i`` of fold ``k`` is
scored under it: ``l_i = log g_{-k(i)}(x_i)``; the uniform scores ``log u = -log V``. The
learner's Gaussian update does not depend on ``pi_u`` (the hierarchical update of
:mod:`~jaxtrack.context.map_em`), so ``g`` is learned once per fold and candidate.

**Why a background mixture.** The uniform ``u`` of the paper (eq. 21) spreads over the UM
volume, which includes every box size from 1 pixel to the image and, for births, every
velocity up to the speed limit. Events have typical sizes, so a learned Gaussian beats ``u``
by a factor of ~1000 (about 7 nats per event) on sizes alone: the held-out check then never
keeps a useful uniform share, and a context whose clutter is learned (size-concentrated) but
whose births in an unseen zone fall to the diluted uniform stops starting tracks there. The
fall-back therefore has two parts: ``u`` (exactly UM's density) and a *background* ``b``, a
coarse, equally weighted grid of broad Gaussians (:data:`BIRTH_BACKGROUND_GRID`,
:data:`CLUTTER_BACKGROUND_GRID`; position spread = grid spacing, so nearly flat over the
image; sizes around the events' mean size, velocities around 0 with half the speed limit
as spread, as in the learner's initial grid). ``b`` is "an event can happen anywhere, with
the typical size", and does not depend on where events were seen.

**Shares.** The density is ``p = pi_u u + pi_b b + (1 - pi_u - pi_b) g`` and its shares are
chosen by the held-out log-likelihood per event with a prior worth ``a`` pseudo-events on
the fall-back mass (:data:`UNIFORM_PRIOR_EVENTS`):

    L(pi_u, pi_b) = (1 / (n + a)) [ sum_i log(pi_u u + pi_b b(x_i)
                      + (1 - pi_u - pi_b) g_{-k(i)}(x_i)) + a log(pi_u + pi_b) ],

``(pi_u, pi_b) = argmax L`` over ``pi_u in [f, 1]``, ``pi_b >= 0``, ``pi_u + pi_b <= 1``
(:func:`select_shares`; ``L`` is concave, a log-spaced grid finds the maximum to within its
spacing). When the learned Gaussians do not predict unseen events better than the fall-back,
their share goes to 0; when neither they nor ``b`` beat ``u``, ``pi_u = 1``: the density *is*
UM's. With plentiful, stationary evidence (``n >> a``, out-of-fold densities close to the
in-sample ones, no event left unexplained) the fall-back shares go to their floors and the
density is the paper's MAP-EM estimate (PHD-context eq. 17-21).

**Model selection.** Each candidate setting of the learner (passes and prior count,
:data:`BIRTH_CANDIDATES`, :data:`CLUTTER_CANDIDATES`) is scored by its ``max L``; the best is
refitted on all events and combined with its shares (:func:`select_density`,
:func:`combine`). The reported held-out log-likelihoods (nats per event) are ``L`` without
the prior term for the selected candidate and ``log u`` for the uniform density: ``gain =
learned - uniform`` is how many nats per unseen event the context beats UM's density (0 when
it fell back). ``L`` uses the same out-of-fold scores that chose the two shares, so the
reported gain is slightly optimistic; the candidate choice adds a little more.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.context.intensity import log_density, log_volume
from jaxtrack.context.map_em import (
    UNIFORM_FLOOR,
    MapEMLearner,
    MixtureState,
    jit_fit,
    map_em_learner,
    to_intensity,
)

#: Grid (columns, rows) of the birth background mixture ``b``.
BIRTH_BACKGROUND_GRID = (6, 5)
#: Grid (columns, rows) of the clutter background mixture ``b``.
CLUTTER_BACKGROUND_GRID = (8, 7)
#: Time blocks of the cross-validation.
NUM_FOLDS = 4
#: Fewest events for which the held-out check runs (fewer: the density is the background).
MIN_EVENTS = 2 * NUM_FOLDS
#: Prior strength ``a``: the uniform density is worth this many pseudo-events.
UNIFORM_PRIOR_EVENTS = 2.0
#: Points per axis of the grid of shares searched (log-spaced from the floor to 1).
SHARE_GRID_SIZE = 60


class Candidate(NamedTuple):
    """One setting of the learner scored by held-out likelihood.

    Attributes:
        epochs: passes over the events.
        prior_count: pseudo-samples per grid component (the learning-rate offset of
            :func:`~jaxtrack.context.map_em.map_em_learner`).
    """

    epochs: int
    prior_count: float


#: Candidate settings for births (few events: more passes, gentler or stronger grid prior).
BIRTH_CANDIDATES = (Candidate(15, 1.0), Candidate(5, 1.0), Candidate(15, 4.0))
#: Candidate settings for clutter (many events).
CLUTTER_CANDIDATES = (Candidate(5, 1.0), Candidate(2, 1.0), Candidate(5, 4.0))


class HeldOut(NamedTuple):
    """The held-out check of one density.

    Attributes:
        uniform_weight: the selected ``pi_u`` (1: fell back to uniform).
        background_weight: the selected ``pi_b``.
        learned: held-out log-likelihood per event of ``pi_u u + pi_b b + (1 - pi_u -
            pi_b) g``, nats.
        uniform: held-out log-likelihood per event of ``u``, nats (``-log V``).
        candidate: index of the selected candidate.
        scores: ``max L`` of every candidate (nats per event, prior included).
        num_folds: folds used (0: too few events, no check; the density is uniform).
    """

    uniform_weight: float
    background_weight: float
    learned: float
    uniform: float
    candidate: int
    scores: tuple[float, ...]
    num_folds: int

    @property
    def gain(self) -> float:
        """Nats per held-out event by which the learned density beats the uniform one."""
        return self.learned - self.uniform

    def as_dict(self) -> dict:
        """JSON-serialisable summary (saved in a context's metadata)."""
        return {
            "uniform_weight": self.uniform_weight,
            "background_weight": self.background_weight,
            "heldout_loglik": self.learned,
            "heldout_loglik_uniform": self.uniform,
            "heldout_gain": self.gain,
            "candidate": self.candidate,
            "candidate_scores": list(self.scores),
            "num_folds": self.num_folds,
        }


def time_folds(frames: np.ndarray, num_folds: int = NUM_FOLDS) -> np.ndarray:
    """Fold index of each event: ``num_folds`` contiguous time blocks of nearly equal counts.

    Args:
        frames: ``[n]`` frame of each event (any order).
        num_folds: number of blocks (>= 2, <= n).

    Returns:
        ``[n]`` integer fold of each event; events of one frame share a fold.
    """
    frames = np.asarray(frames)
    n = frames.size
    if not 2 <= num_folds <= n:
        raise ValueError(f"need 2 <= num_folds <= {n} events, got {num_folds}")
    order = np.argsort(frames, kind="stable")
    folds = np.empty(n, np.int64)
    folds[order] = np.minimum(np.arange(n) * num_folds // n, num_folds - 1)
    # events of the same frame go to the fold of the frame's first event
    for frame in np.unique(frames):
        same = frames == frame
        folds[same] = folds[same].min()
    return folds


def log_gaussian_part(state: MixtureState, x: jax.Array) -> jax.Array:
    """``log g(x)`` of the Gaussian part of a mixture state for a batch ``[n, dim]``."""
    gaussians = to_intensity(
        state._replace(uniform_weight=jnp.zeros_like(state.uniform_weight)), 1.0
    )
    return log_density(gaussians, x)


def log_uniform(state: MixtureState) -> float:
    """``log u = -log V`` of a mixture state's volume."""
    return -float(log_volume(to_intensity(state, 1.0)))


def select_shares(
    log_g: np.ndarray,
    log_b: np.ndarray,
    log_u: float,
    prior_events: float = UNIFORM_PRIOR_EVENTS,
    floor: float = UNIFORM_FLOOR,
    grid_size: int = SHARE_GRID_SIZE,
) -> tuple[float, float, float, float]:
    """``(pi_u, pi_b) = argmax L`` over ``pi_u >= f``, ``pi_b >= 0``, ``pi_u + pi_b <= 1``.

    Args:
        log_g: ``[n]`` out-of-fold ``log g(x_i)`` of the learned Gaussians.
        log_b: ``[n]`` ``log b(x_i)`` of the background mixture.
        log_u: ``log u``.
        prior_events: the prior strength ``a`` (pseudo-events for the fall-back shares).
        floor: smallest ``pi_u``.
        grid_size: points per axis of the log-spaced search grid.

    Returns:
        ``(pi_u, pi_b, L, held-out log-likelihood per event without the prior)``.
    """
    log_g = np.asarray(log_g, np.float64)
    log_b = np.asarray(log_b, np.float64)
    axis = np.geomspace(floor, 1.0, grid_size)
    pi_u, pi_b = np.meshgrid(axis, np.concatenate([[0.0], axis]), indexing="ij")
    keep = pi_u + pi_b <= 1 + 1e-12
    pi_u, pi_b = pi_u[keep], np.minimum(pi_b[keep], 1 - pi_u[keep])
    pi_g = np.clip(1 - pi_u - pi_b, 0.0, 1.0)
    with np.errstate(divide="ignore"):
        terms = np.stack(
            [
                np.broadcast_to((np.log(pi_u) + log_u)[:, None], (pi_u.size, log_g.size)),
                np.log(pi_b)[:, None] + log_b[None, :],
                np.log(pi_g)[:, None] + log_g[None, :],
            ]
        )
    per_event = np.logaddexp.reduce(terms, axis=0)
    loglik = per_event.mean(axis=1)
    n = log_g.size
    objective = (n * loglik + prior_events * np.log(pi_u + pi_b)) / (n + prior_events)
    best = int(np.argmax(objective))
    return float(pi_u[best]), float(pi_b[best]), float(objective[best]), float(loglik[best])


@functools.cache
def candidate_learner(prior_count: float) -> MapEMLearner:
    """The learner of a candidate's prior count, one object per value (compiled once)."""
    return map_em_learner(prior_count=prior_count)


_jit_log_g = jax.jit(log_gaussian_part)


def out_of_fold_log_g(
    grid: MixtureState,
    samples: np.ndarray,
    folds: np.ndarray,
    candidate: Candidate,
    key: jax.Array,
) -> np.ndarray:
    """``log g_{-k(i)}(x_i)`` of every event: each fold scored by a fit on the others.

    Args:
        grid: the starting state.
        samples: ``[n, dim]`` events.
        folds: ``[n]`` fold of each event (:func:`time_folds`).
        candidate: the learner's setting.
        key: PRNG key of the learning order.

    Returns:
        ``[n]`` out-of-fold log densities of the Gaussian part.
    """
    learner = candidate_learner(candidate.prior_count)
    n = samples.shape[0]
    order = np.asarray(jax.random.permutation(key, n))
    shuffled = jnp.asarray(samples[order], grid.weights.dtype)
    points = jnp.asarray(samples, grid.weights.dtype)
    result = np.empty(n)
    for fold in np.unique(folds):
        train = jnp.asarray(folds[order] != fold)
        state = jit_fit(learner, grid, shuffled, train, candidate.epochs)
        held = folds == fold
        result[held] = np.asarray(_jit_log_g(state, points))[held]
    return result


def select_density(
    grid: MixtureState,
    background: MixtureState,
    samples: np.ndarray,
    frames: np.ndarray,
    key: jax.Array,
    candidates: tuple[Candidate, ...],
    *,
    num_folds: int = NUM_FOLDS,
    prior_events: float = UNIFORM_PRIOR_EVENTS,
    floor: float = UNIFORM_FLOOR,
) -> tuple[Candidate, HeldOut]:
    """The candidate setting and the shares ``(pi_u, pi_b)`` that predict unseen events best.

    Args:
        grid: the starting state (e.g. :func:`~jaxtrack.context.learn.birth_grid`).
        background: the background mixture ``b`` (:func:`~jaxtrack.context.learn.background`).
        samples: ``[n, dim]`` events (n >= 1).
        frames: ``[n]`` frame of each event (the time folds).
        key: PRNG key of the learning order (that of the final fit too).
        candidates: the learner settings compared.
        num_folds: time blocks; fewer than :data:`MIN_EVENTS` events skip the check: the
            first candidate with ``pi_u = f``, ``pi_b = 1 - f`` (the background: events
            anywhere in the image with their mean size; not the uniform ``u``, whose sizes
            and velocities would not match a learned other part of the context).
        prior_events: prior strength ``a`` of :func:`select_shares`.
        floor: smallest ``pi_u``.

    Returns:
        ``(candidate, held_out)``; the density is then learned on all events with the
        candidate's setting and combined with the selected shares (:func:`combine`).
    """
    samples = np.asarray(samples, np.float64)
    log_u = log_uniform(grid)
    if samples.shape[0] < max(MIN_EVENTS, 2 * num_folds):
        # too few events to check anything: "anywhere, with the events' typical size"
        return candidates[0], HeldOut(floor, 1.0 - floor, log_u, log_u, 0, (), 0)
    folds = time_folds(frames, num_folds)
    log_b = np.asarray(_jit_log_g(background, jnp.asarray(samples, grid.weights.dtype)))
    results = []
    for candidate in candidates:
        log_g = out_of_fold_log_g(grid, samples, folds, candidate, key)
        results.append(select_shares(log_g, log_b, log_u, prior_events, floor))
    scores = tuple(result[2] for result in results)
    best = int(np.argmax(scores))
    pi_u, pi_b, _, loglik = results[best]
    return candidates[best], HeldOut(pi_u, pi_b, loglik, log_u, best, scores, num_folds)


def combine(state: MixtureState, background: MixtureState, held: HeldOut) -> MixtureState:
    """``pi_u u + pi_b b + (1 - pi_u - pi_b) g`` as one state (the background's slots appended).

    Args:
        state: the learned density (its Gaussian part ``g``).
        background: the background mixture ``b``.
        held: the selected shares.

    Returns:
        A state with ``K + K_b`` slots and uniform weight ``pi_u``.
    """
    pi_u, pi_b = held.uniform_weight, held.background_weight
    gaussian = max(1.0 - pi_u, 0.0)
    dtype = state.weights.dtype
    if gaussian <= 0:
        weights_g, weights_b = state.weights * 0, background.weights * 0
    else:
        share_b = min(pi_b / gaussian, 1.0)
        weights_g = jnp.where(state.alive, state.weights, 0.0) * (1 - share_b)
        weights_b = background.weights * share_b
    weights = jnp.concatenate([weights_g, weights_b]).astype(dtype)
    return state._replace(
        uniform_weight=jnp.asarray(pi_u, dtype),
        weights=weights,
        means=jnp.concatenate([state.means, background.means]),
        covs=jnp.concatenate([state.covs, background.covs]),
        alive=weights > 0,
    )
