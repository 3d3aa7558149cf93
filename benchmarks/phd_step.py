"""Speed of one particle PHD step: JAX (jit) versus a plain vectorised NumPy SMC-PHD step.

For each number of particles and of detections, times (median of repeats, after compile):

* ``jax_recursion``: prediction, measurement-driven births, the eq. 10 update and systematic
  resampling, composed from jaxtrack's building blocks (the same work as the NumPy step);
* ``jax_step``: the tracker's whole ``phd_filter(...).step`` (also state extraction by the
  measurement partition and labelling);
* ``numpy_recursion``: the same recursion written here in vectorised NumPy (float32).

Throughput is in particle x detection pairs per second (``num_particles * num_detections /
time``). Prints JSON. Usage: ``python benchmarks/phd_step.py [--quick]``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import time

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.boxes import xywh_to_cxcywh
from jaxtrack.context.intensity import log_intensity
from jaxtrack.filters import default_phd_params, phd_filter, phd_update, resample
from jaxtrack.filters.births import sample_births
from jaxtrack.models import sample_constant_velocity, survival_probability
from jaxtrack.types import Detections

WIDTH, HEIGHT = 1920.0, 1080.0
BIRTHS_PER_DETECTION = 16


def scene(num_particles: int, num_detections: int, seed: int = 0):
    """Particles spread over ``num_detections`` targets and one frame of their detections."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform([100, 100], [WIDTH - 100, HEIGHT - 100], (num_detections, 2))
    sizes = rng.uniform([30, 80], [80, 200], (num_detections, 2))
    owner = rng.integers(0, num_detections, num_particles)
    particles = np.zeros((num_particles, 6), np.float32)
    particles[:, [0, 2]] = centres[owner] + rng.normal(0, 5, (num_particles, 2))
    particles[:, [1, 3]] = rng.normal(0, 1, (num_particles, 2))
    particles[:, 4:] = sizes[owner] * rng.uniform(0.9, 1.1, (num_particles, 2))
    log_weights = np.full(num_particles, math.log(num_detections / num_particles), np.float32)
    boxes = np.concatenate([centres - sizes / 2 + rng.normal(0, 3, centres.shape), sizes], 1)
    detections = Detections(
        boxes=boxes.astype(np.float32)[None],
        scores=np.full((1, num_detections), 0.9, np.float32),
        mask=np.ones((1, num_detections), bool),
    )
    return particles, log_weights, detections


def jax_recursion(num_particles: int):
    """Predict, birth, update, resample: the PHD recursion from jaxtrack's building blocks."""

    def recursion(key, particles, log_weights, params, frame):
        key_motion, key_birth, key_resample = jax.random.split(key, 3)
        measurements = xywh_to_cxcywh(frame.boxes, jnp)
        survivors = sample_constant_velocity(key_motion, particles, params.motion_noise_std)
        survivor_log_weights = log_weights + jnp.log(
            survival_probability(params.survival_prob, particles)
        )
        births, birth_log_weights = sample_births(
            key_birth,
            measurements,
            frame.mask,
            BIRTHS_PER_DETECTION,
            params.birth_intensity,
            params.measurement_noise_std,
        )
        predicted = jnp.concatenate([survivors, births])
        _, log_likelihood, updated = phd_update(
            params,
            measurements,
            frame.scores,
            frame.mask,
            predicted,
            jnp.concatenate([survivor_log_weights, birth_log_weights]),
        )
        new_particles, new_log_weights = resample(key_resample, predicted, updated, num_particles)
        return new_particles, new_log_weights, log_likelihood

    return jax.jit(recursion)


def numpy_recursion(rng, particles, log_weights, params, boxes, scores):
    """The same recursion in vectorised NumPy (SDV models, uniform intensities)."""
    num = particles.shape[0]
    motion = np.asarray(params.motion_noise_std)
    meas_std = np.asarray(params.measurement_noise_std)
    pd = float(params.detection_prob)
    sizes = particles[:, 4:6]
    noise = rng.standard_normal((num, 4), np.float32) * motion * np.tile(sizes, 2)
    survivors = particles.copy()
    survivors[:, 0] += survivors[:, 1] + noise[:, 0] / 2
    survivors[:, 1] += noise[:, 0]
    survivors[:, 2] += survivors[:, 3] + noise[:, 1] / 2
    survivors[:, 3] += noise[:, 1]
    survivors[:, 4:6] = np.maximum(survivors[:, 4:6] + noise[:, 2:4], 1.0)
    survivor_log_weights = log_weights + math.log(float(params.survival_prob))

    z = np.concatenate([boxes[:, :2] + boxes[:, 2:] / 2, boxes[:, 2:]], 1)
    num_det = z.shape[0]
    birth = params.birth_intensity
    lower, upper = np.asarray(birth.lower), np.asarray(birth.upper)
    z_std = meas_std * np.concatenate([z[:, 2:], z[:, 2:]], 1)
    measured = (
        z[:, None] + z_std[:, None] * rng.standard_normal((num_det, BIRTHS_PER_DETECTION, 4))
    ).reshape(-1, 4)
    measured[:, 2:] = np.maximum(measured[:, 2:], 1.0)
    velocity = rng.uniform(lower[[1, 3]], upper[[1, 3]], (measured.shape[0], 2))
    births = np.stack(
        [
            measured[:, 0],
            velocity[:, 0],
            measured[:, 1],
            velocity[:, 1],
            measured[:, 2],
            measured[:, 3],
        ],
        1,
    ).astype(np.float32)
    log_q = (
        -0.5 * np.sum(((measured[:, None] - z[None]) / z_std[None]) ** 2, -1)
        - np.sum(np.log(z_std), -1)[None]
    )
    log_q = log_q - 2 * math.log(2 * math.pi)
    top = log_q.max(1, keepdims=True)
    log_mixture_sum = top[:, 0] + np.log(np.exp(log_q - top).sum(1))
    log_gamma = math.log(float(birth.magnitude)) - np.sum(np.log(upper - lower))
    birth_log_weights = (
        log_gamma
        - math.log(BIRTHS_PER_DETECTION)
        - log_mixture_sum
        + np.sum(np.log(upper[[1, 3]] - lower[[1, 3]]))
    )

    states = np.concatenate([survivors, births])
    lw = np.concatenate([survivor_log_weights, birth_log_weights]).astype(np.float32)
    std = meas_std * np.tile(states[:, 4:6], 2)
    predicted = states[:, [0, 2, 4, 5]]
    log_psi = np.empty((num_det, states.shape[0]), np.float32)
    log_norm = np.sum(np.log(std), 1) + 2 * math.log(2 * math.pi)
    for j in range(num_det):
        log_psi[j] = math.log(pd) - 0.5 * np.sum(((z[j] - predicted) / std) ** 2, 1) - log_norm
    terms = log_psi + lw[None]
    top = terms.max(1, keepdims=True)
    log_c = top[:, 0] + np.log(np.exp(terms - top).sum(1))
    clutter = params.clutter_intensity
    log_kappa = np.asarray(log_intensity(clutter, jnp.asarray(z)))
    log_denominator = np.logaddexp(log_kappa, log_c)
    factor = (1 - pd) + np.exp(log_psi - log_denominator[:, None]).sum(0)
    updated = lw + np.log(factor)
    log_likelihood = -pd * np.exp(lw).sum() - float(clutter.magnitude) + log_denominator.sum()

    top = updated.max()
    weights = np.exp(updated - top)
    cdf = np.cumsum(weights.astype(np.float64))
    mass = cdf[-1]
    ancestors = np.searchsorted(cdf / mass, (rng.random() + np.arange(num)) / num, side="right")
    ancestors = np.minimum(ancestors, states.shape[0] - 1)
    new_log_weights = np.full(num, top + math.log(mass) - math.log(num), np.float32)
    return states[ancestors], new_log_weights, log_likelihood


def median_time(function, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def bench(num_particles: int, num_detections: int, repeats: int) -> dict:
    params = default_phd_params(WIDTH, HEIGHT, 25.0)
    particles, log_weights, detections = scene(num_particles, num_detections)
    frame = jax.tree.map(lambda x: jnp.asarray(x[0]), detections)
    key = jax.random.key(0)

    recursion = jax_recursion(num_particles)
    args = (key, jnp.asarray(particles), jnp.asarray(log_weights), params, frame)
    start = time.perf_counter()
    jax.block_until_ready(recursion(*args))
    recursion_compile = time.perf_counter() - start
    jax_recursion_time = median_time(lambda: jax.block_until_ready(recursion(*args)), repeats)

    filt = phd_filter(
        num_particles, births_per_detection=BIRTHS_PER_DETECTION, extraction="partition"
    )
    state = filt.init(key, params)._replace(
        particles=jnp.asarray(particles),
        log_weights=jnp.asarray(log_weights),
        mass=jnp.asarray(float(num_detections)),
    )
    step = jax.jit(filt.step)
    jax.block_until_ready(step(key, state, params, frame))
    jax_step_time = median_time(
        lambda: jax.block_until_ready(step(key, state, params, frame)), repeats
    )

    rng = np.random.default_rng(0)
    numpy_time = median_time(
        lambda: numpy_recursion(
            rng, particles, log_weights, params, detections.boxes[0], detections.scores[0]
        ),
        repeats,
    )
    pairs = num_particles * num_detections
    return {
        "num_particles": num_particles,
        "num_detections": num_detections,
        "births_per_detection": BIRTHS_PER_DETECTION,
        "jax_recursion_s": jax_recursion_time,
        "jax_recursion_compile_s": recursion_compile,
        "jax_step_s": jax_step_time,
        "numpy_recursion_s": numpy_time,
        "jax_recursion_pairs_per_s": pairs / jax_recursion_time,
        "jax_step_pairs_per_s": pairs / jax_step_time,
        "numpy_recursion_pairs_per_s": pairs / numpy_time,
        "speedup_recursion_vs_numpy": numpy_time / jax_recursion_time,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--particles", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    parser.add_argument("--detections", type=int, nargs="+", default=[8, 32, 128])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--quick", action="store_true", help="1e4 particles, 8 detections only")
    args = parser.parse_args()
    if args.quick:
        args.particles, args.detections, args.repeats = [10_000], [8], 3
    results = [
        bench(n, m, args.repeats if n < 1_000_000 else max(2, args.repeats // 2))
        for n in args.particles
        for m in args.detections
    ]
    print(
        json.dumps(
            {
                "benchmark": "phd_step",
                "device": str(jax.devices()[0]),
                "cpu_count": os.cpu_count(),
                "platform": platform.platform(),
                "jax_version": jax.__version__,
                "results": results,
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
