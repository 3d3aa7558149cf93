"""State extraction: multi-target estimates from the particle PHD (PHD-context Sec. III).

Two methods, both jit-compatible with a fixed number of estimate slots:

* :func:`gmm_clusters` -- the paper's: a Gaussian mixture is fitted to the weighted
  particles (weighted EM; components whose boxes overlap are merged) and the centres of the
  clusters whose mass exceeds a threshold (0.5 in the paper) are the estimates.
* :func:`measurement_partition` -- faster: the updated PHD splits into a missed-detection part
  and one part per detection ``z``, ``D_z(x) = psi_z(x) D(x) / (kappa(z) + C(z))`` (the terms
  of PHD-context eq. 10); each part whose mass ``C(z) / (kappa(z) + C(z))`` exceeds the
  threshold gives one estimate, its weighted mean. Targets missed in the frame give none.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from jaxtrack.association.estimates import Estimates
from jaxtrack.boxes import cxcywh_to_xywh, iou_matrix
from jaxtrack.filters.births import LOG_ZERO
from jaxtrack.models.dynamics import MEASURED, SIZE


def gmm_clusters(
    key: Array,
    particles: Float[Array, "num_particles 6"],
    log_weights: Float[Array, " num_particles"],
    particle_scores: Float[Array, " num_particles"],
    max_clusters: int,
    num_iterations: int,
    mass_threshold: Float[Array, ""],
    merge_iou: float = 0.5,
    min_relative_std: float = 0.05,
) -> Estimates:
    """Clusters the PHD particles with a weighted Gaussian mixture (PHD-context Sec. III).

    The mixture lives on ``(y1, y2, w, h)`` with diagonal covariances. The paper leaves the
    number of components open; a mixture with ``round(M)`` components (``M`` the PHD mass)
    merges a light cluster (e.g. clutter) into a nearby target. Here the mixture has
    ``2 round(M) + 1`` live components (at most ``max_clusters``), seeded by weighted
    k-means++ (D^2 sampling, distances in units of the particle's box size) and refined by
    ``num_iterations`` EM iterations on the particle weights; components describing one
    target are then merged greedily, heaviest first, when their boxes overlap by more than
    ``merge_iou``. The estimate of a cluster is the responsibility-weighted mean of the full
    states (velocities included) and its mass the PHD mass it owns; clusters heavier than
    ``mass_threshold`` are kept.

    Args:
        key: PRNG key for the seeding.
        particles: particle states.
        log_weights: particle log-weights (their sum is the PHD mass ``M``).
        particle_scores: expected score of the detections that updated each particle.
        max_clusters: mixture components / estimate slots (static).
        num_iterations: EM iterations (static).
        mass_threshold: clusters with mass above it become estimates (0.5 in the paper).
        merge_iou: components whose boxes overlap more than this are one cluster.
        min_relative_std: floor of the component standard deviations relative to the box
            size, which keeps components on duplicated particles from collapsing.

    Returns:
        ``max_clusters`` estimate slots.
    """
    log_mass = jax.nn.logsumexp(log_weights)
    probs = jnp.exp(log_weights - log_mass)
    mass = jnp.exp(log_mass)
    features = particles[:, MEASURED]
    scales = jnp.concatenate([particles[:, SIZE], particles[:, SIZE]], axis=-1)
    num_live = jnp.clip(2 * jnp.round(mass) + 1, 1, max_clusters).astype(jnp.int32)
    live = jnp.arange(max_clusters) < num_live

    def seed(k, carry):
        means, min_distance = carry
        seed_probs = jnp.where(k == 0, probs, probs * min_distance)
        seed_probs = jnp.where(jnp.sum(seed_probs) > 0, seed_probs, probs)
        index = jax.random.categorical(jax.random.fold_in(key, k), jnp.log(seed_probs))
        distance = jnp.sum(((features - features[index]) / scales) ** 2, axis=-1)
        return means.at[k].set(features[index]), jnp.minimum(min_distance, distance)

    means, _ = jax.lax.fori_loop(
        0,
        max_clusters,
        seed,
        (jnp.zeros((max_clusters, 4), features.dtype), jnp.full(probs.shape, jnp.inf)),
    )
    variance_floor = (min_relative_std * jnp.concatenate([means[:, 2:], means[:, 2:]], -1)) ** 2
    variances = 4 * variance_floor
    log_mixing = jnp.where(live, -jnp.log(num_live.astype(features.dtype)), LOG_ZERO)

    def responsibilities(means, variances, log_mixing):
        log_gauss = -0.5 * jnp.sum(
            (features[:, None] - means[None]) ** 2 / variances[None] + jnp.log(variances)[None],
            axis=-1,
        )
        log_joint = jnp.where(live[None], log_mixing[None] + log_gauss, LOG_ZERO)
        return jnp.exp(log_joint - jax.nn.logsumexp(log_joint, axis=-1, keepdims=True))

    def em_iteration(_, params):
        means, variances, log_mixing = params
        owned = probs[:, None] * responsibilities(means, variances, log_mixing)
        share = jnp.sum(owned, axis=0)
        safe_share = jnp.where(share > 0, share, 1.0)
        new_means = jnp.where((share > 0)[:, None], owned.T @ features / safe_share[:, None], means)
        spread = jnp.sum(owned[:, :, None] * (features[:, None] - new_means[None]) ** 2, axis=0)
        new_variances = jnp.where((share > 0)[:, None], spread / safe_share[:, None], variances)
        new_variances = jnp.maximum(new_variances, variance_floor)
        new_log_mixing = jnp.where(live & (share > 0), jnp.log(safe_share), LOG_ZERO)
        return new_means, new_variances, new_log_mixing

    means, variances, log_mixing = jax.lax.fori_loop(
        0, num_iterations, em_iteration, (means, variances, log_mixing)
    )
    owned = probs[:, None] * responsibilities(means, variances, log_mixing)
    share, state_sums, score_sums = _merge_overlapping(
        jnp.sum(owned, axis=0), owned.T @ particles, owned.T @ particle_scores, live, merge_iou
    )
    safe_share = jnp.where(share > 0, share, 1.0)
    masses = mass * share
    return Estimates(
        states=state_sums / safe_share[:, None],
        masses=masses,
        scores=score_sums / safe_share,
        mask=live & (masses > mass_threshold),
    )


def _merge_overlapping(share, state_sums, score_sums, live, merge_iou):
    """Greedy merge of components with overlapping boxes, heaviest first.

    Args:
        share: mass share of each component.
        state_sums: share-weighted sums of the states.
        score_sums: share-weighted sums of the scores.
        live: live components.
        merge_iou: overlap above which a lighter component joins a heavier one.

    Returns:
        ``share, state_sums, score_sums`` after merging (absorbed components have share 0).
    """
    num = share.shape[0]
    safe_share = jnp.where(share > 0, share, 1.0)
    boxes = cxcywh_to_xywh((state_sums / safe_share[:, None])[:, MEASURED], jnp)
    overlap = iou_matrix(boxes, boxes, xp=jnp)
    order = jnp.argsort(-jnp.where(live, share, -1.0))

    def absorb(rank, carry):
        share, state_sums, score_sums = carry
        i = order[rank]
        later = jnp.zeros(num, bool).at[order].set(jnp.arange(num) > rank)
        joins = later & live & (share > 0) & (overlap[i] > merge_iou) & (share[i] > 0)
        share = share.at[i].add(jnp.sum(jnp.where(joins, share, 0.0)))
        state_sums = state_sums.at[i].add(jnp.sum(jnp.where(joins[:, None], state_sums, 0.0), 0))
        score_sums = score_sums.at[i].add(jnp.sum(jnp.where(joins, score_sums, 0.0)))
        keep = ~joins
        return share * keep, state_sums * keep[:, None], score_sums * keep

    return jax.lax.fori_loop(0, num, absorb, (share, state_sums, score_sums))


def measurement_partition(
    detection_log_masses: Float[Array, " max_detections"],
    detection_states: Float[Array, "max_detections 6"],
    detection_scores: Float[Array, " max_detections"],
    detection_mask: Bool[Array, " max_detections"],
    mass_threshold: Float[Array, ""],
) -> Estimates:
    """One estimate per detection whose share of the updated PHD exceeds the threshold.

    The part of detection ``z``, ``D_z(x) = psi_z(x) D(x) / (kappa(z) + C(z))`` (a term of
    PHD-context eq. 10), has mass ``C(z) / (kappa(z) + C(z))`` and mean state
    ``sum_i psi_z(x_i) w_i x_i / C(z)``; both come from the update's blocked pass
    (:func:`~jaxtrack.filters.phd.phd_update`).

    Args:
        detection_log_masses: ``log(C(z) / (kappa(z) + C(z)))`` per detection.
        detection_states: mean state of each detection's part.
        detection_scores: detector confidences.
        detection_mask: True for real detections.
        mass_threshold: minimum share ``C(z) / (kappa(z) + C(z))`` of an estimate (0.5).

    Returns:
        ``max_detections`` estimate slots, slot ``j`` from detection ``j``.
    """
    shares = jnp.exp(detection_log_masses)
    return Estimates(
        states=detection_states,
        masses=shares,
        scores=detection_scores,
        mask=detection_mask & (shares > mass_threshold),
    )
