"""A slow loop-based NumPy reference of one particle PHD step (SPEC section 1, eq. 10).

Written from the equations, not from the JAX code; it takes the JAX filter's random draws
(the same keys and draw layout) so that both compute the same realisation.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np


def _gauss(x, mean, std):
    return math.exp(-0.5 * ((x - mean) / std) ** 2) / (math.sqrt(2 * math.pi) * std)


def _likelihood(z, x, noise_std):
    w, h = x[4], x[5]
    std = noise_std * np.array([w, h, w, h])
    value = 1.0
    for d, (zd, xd) in enumerate(zip(z, (x[0], x[2], x[4], x[5]), strict=True)):
        value *= _gauss(zd, xd, std[d])
    return value


def reference_of_state(key, state, params, boxes, scores, mask, births_per_detection):
    """:func:`reference_step` from a filter state (its particles and log-weights)."""
    particles = np.asarray(state.particles)
    weights = np.exp(np.asarray(state.log_weights))
    return reference_step(
        key, particles, weights, params, boxes, scores, mask, births_per_detection
    )


def reference_step(key, particles, weights, params, boxes, scores, mask, births_per_detection):
    """One PHD step with SDV models and uniform intensities; float64 loops.

    Returns:
        dict with the updated (pre-resampling) particles and weights, the log-likelihood, the
        systematic-resampled particles and the detection shares ``C / (kappa / r + C)``.
    """
    key_motion, key_birth, key_resample, _ = jax.random.split(key, 4)
    num = particles.shape[0]
    normal = np.asarray(jax.random.normal(key_motion, (num, 4), jnp.float64))
    motion_std = np.asarray(params.motion_noise_std, np.float64)
    meas_std = np.asarray(params.measurement_noise_std, np.float64)
    pd = float(params.detection_prob)
    survival = float(params.survival_prob)

    predicted = []
    for i in range(num):
        y1, vy1, y2, vy2, w, h = particles[i]
        n1, n2, nw, nh = normal[i] * motion_std * np.array([w, h, w, h])
        predicted.append(
            [
                y1 + vy1 + n1 / 2,
                vy1 + n1,
                y2 + vy2 + n2 / 2,
                vy2 + n2,
                max(w + nw, 1),
                max(h + nh, 1),
            ]
        )
    new_weights = [weights[i] * survival for i in range(num)]

    centres = [(b[0] + b[2] / 2, b[1] + b[3] / 2, b[2], b[3]) for b in boxes]
    birth = params.birth_intensity
    lower, upper = np.asarray(birth.lower, np.float64), np.asarray(birth.upper, np.float64)
    key_gauss, key_velocity = jax.random.split(key_birth)
    num_slots = len(boxes)
    gauss = np.asarray(
        jax.random.normal(key_gauss, (num_slots, births_per_detection, 4), jnp.float64)
    )
    velocity = np.asarray(
        jax.random.uniform(
            key_velocity,
            (num_slots * births_per_detection, 2),
            jnp.float64,
            minval=jnp.asarray(lower[[1, 3]]),
            maxval=jnp.asarray(upper[[1, 3]]),
        )
    )
    gamma = float(birth.magnitude) / np.prod(upper - lower)
    velocity_density = 1 / np.prod(upper[[1, 3]] - lower[[1, 3]])
    valid = [j for j in range(num_slots) if mask[j]]
    for j in range(num_slots):
        z = centres[j]
        std_z = meas_std * np.array([z[2], z[3], z[2], z[3]])
        for b in range(births_per_detection):
            y1, y2, w, h = (z[d] + std_z[d] * gauss[j, b, d] for d in range(4))
            w, h = max(w, 1), max(h, 1)
            vy1, vy2 = velocity[j * births_per_detection + b]
            predicted.append([y1, vy1, y2, vy2, w, h])
            if not mask[j]:
                new_weights.append(0.0)
                continue
            proposal = 0.0
            for k in valid:
                zk = centres[k]
                std_k = meas_std * np.array([zk[2], zk[3], zk[2], zk[3]])
                proposal += np.prod(
                    [_gauss(v, zk[d], std_k[d]) for d, v in enumerate((y1, y2, w, h))]
                )
            proposal = proposal / len(valid) * velocity_density
            new_weights.append(gamma / (births_per_detection * len(valid) * proposal))

    clutter = params.clutter_intensity
    c_lower, c_upper = np.asarray(clutter.lower, np.float64), np.asarray(clutter.upper, np.float64)
    kappa = float(clutter.magnitude) / np.prod(c_upper - c_lower)
    beta = float(params.score_weight)
    updated = [w * (1 - pd) for w in new_weights]
    log_likelihood = -pd * sum(new_weights) - float(clutter.magnitude)
    shares = []
    for j in valid:
        ratio = (scores[j] / (1 - scores[j])) ** beta
        psi = [pd * _likelihood(centres[j], x, meas_std) for x in predicted]
        c = sum(p * w for p, w in zip(psi, new_weights, strict=True))
        for i in range(len(predicted)):
            updated[i] += psi[i] * new_weights[i] / (kappa / ratio + c)
        log_likelihood += math.log(kappa + ratio * c)
        shares.append(c / (kappa / ratio + c))

    predicted = np.array(predicted)
    updated = np.array(updated)
    mass = updated.sum()
    cdf = np.cumsum(updated) / mass
    offset = float(jax.random.uniform(key_resample, (), jnp.float64))
    ancestors = [int(np.searchsorted(cdf, (offset + i) / num, side="right")) for i in range(num)]
    return dict(
        predicted=predicted,
        updated_weights=updated,
        log_likelihood=log_likelihood,
        resampled=predicted[np.minimum(ancestors, len(predicted) - 1)],
        mass=mass,
        shares=np.array(shares),
        valid=valid,
    )
