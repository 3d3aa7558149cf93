"""CMT contextual proposal: ESS of one frame vs the bootstrap proposal, and time.

One component of 40 particles at x' = (200, 2, 150, 0, 40, 100); one detection/blob whose
centre is `offset` px right of the CV prediction; weights p(z|x) p(x|x') / q(x) with
p(z|x) = nearest_detection_log_likelihood (floor -38); noise settings in SETTINGS.
ESS/N averaged over 20 keys. Time: jitted contextual_proposal, K=20 components x 40
particles, 30 blobs, 2 zones, CPU. Prints one JSON object.
Usage: ``python benchmarks/cpd_proposal.py``
"""

import json
import time

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.filters.cmt_conditions import default_cpd_params
from jaxtrack.filters.cmt_proposal import contextual_proposal, log_constant_velocity
from jaxtrack.filters.mixture_models import bootstrap_proposal, nearest_detection_log_likelihood
from jaxtrack.filters.mixture_state import MixtureParams
from jaxtrack.types import Detections

STATE = jnp.array([200.0, 2.0, 150.0, 0.0, 40.0, 100.0])
NO_ZONE = (jnp.zeros((1, 4)), jnp.zeros(1, bool))


def mixture_params(motion, measurement):
    return MixtureParams(
        motion, measurement, jnp.array(-38.0), jnp.array(1e-3), jnp.array(-25.0), jnp.array(-12.0)
    )


def ess(log_w):
    w = jax.nn.softmax(log_w)
    return float(1.0 / jnp.sum(w * w)) / log_w.shape[0]


#: (name, motion noise, measurement noise, CPD blob spreads compared)
SETTINGS = [
    (
        "isotropic_v0.05",
        (0.05, 0.05, 0.01, 0.01),
        (0.05,) * 4,
        {"0.05": (0.05,) * 4, "0.1": (0.1,) * 4},
    ),
    (
        "isotropic_v0.2",
        (0.2, 0.2, 0.01, 0.01),
        (0.05,) * 4,
        {"0.05": (0.05,) * 4, "0.1": (0.1,) * 4},
    ),
    (
        "toolkit_defaults",
        (0.05, 0.02, 0.05, 0.05),
        (0.15, 0.08, 0.25, 0.15),
        {"default": tuple(float(v) for v in default_cpd_params().blob_spread), "0.1": (0.1,) * 4},
    ),
]


def ess_table():
    table = {}
    old = jnp.broadcast_to(STATE, (1, 40, 6))
    for name, motion, measurement, spreads in SETTINGS:
        motion = jnp.array(motion)
        mp = mixture_params(motion, jnp.array(measurement))
        for offset in (0.0, 4.0, 10.0):
            det = Detections(
                jnp.array([[202.0 + offset - 20.0, 100.0, 40.0, 100.0]]),
                jnp.ones(1),
                jnp.ones(1, bool),
            )
            row = {"bootstrap": []}
            for seed in range(20):
                key = jax.random.key(seed)
                new, _ = bootstrap_proposal(key, old, mp, det)
                row["bootstrap"].append(ess(nearest_detection_log_likelihood(new, mp, det)[0]))
                for label, spread in spreads.items():
                    cpd = default_cpd_params()._replace(blob_spread=jnp.array(spread))
                    d = contextual_proposal(
                        key, old, STATE[None], jnp.array([True]), cpd, motion, det, *NO_ZONE
                    )
                    log_w = (
                        nearest_detection_log_likelihood(d.particles, mp, det)
                        + log_constant_velocity(d.particles, old, motion)
                        - d.log_q
                    )
                    log_w = jnp.where(d.exited, -jnp.inf, log_w)[0]
                    row.setdefault(f"cpd_spread_{label}", []).append(ess(log_w))
            table[f"{name}_offset_{offset:g}px"] = {
                k: round(float(np.mean(v)), 3) for k, v in row.items()
            }
    return table


def time_per_frame(reps=300):
    k, n, d = 20, 40, 30
    rng = np.random.default_rng(0)
    est = jnp.asarray(
        np.c_[
            rng.uniform(0, 700, k),
            np.zeros(k),
            rng.uniform(0, 500, k),
            np.zeros(k),
            np.full(k, 40.0),
            np.full(k, 100.0),
        ],
        jnp.float32,
    )
    parts = est[:, None] + jnp.asarray(rng.normal(size=(k, n, 6)), jnp.float32)
    blobs = Detections(
        jnp.asarray(
            np.c_[
                rng.uniform(0, 700, d), rng.uniform(0, 500, d), np.full(d, 40.0), np.full(d, 100.0)
            ],
            jnp.float32,
        ),
        jnp.ones(d),
        jnp.ones(d, bool),
    )
    zones = jnp.asarray([[0.0, 400.0, 100.0, 100.0], [600.0, 0.0, 100.0, 100.0]])
    motion = jnp.array([0.05, 0.05, 0.01, 0.01])
    step = jax.jit(
        lambda key: contextual_proposal(
            key,
            parts,
            est,
            jnp.ones(k, bool),
            default_cpd_params(),
            motion,
            blobs,
            zones,
            jnp.ones(2, bool),
        )
    )
    jax.block_until_ready(step(jax.random.key(0)))
    times = []
    for i in range(reps):
        t = time.perf_counter()
        jax.block_until_ready(step(jax.random.key(i)))
        times.append(time.perf_counter() - t)
    return round(float(np.median(times)) * 1e3, 3)


print(json.dumps({"ess_over_n": ess_table(), "median_ms_per_frame_K20_N40_D30": time_per_frame()}))
