"""Where the time of one particle PHD step goes: its public stages timed one by one.

On the scene of ``benchmarks/phd_step.py`` (768x576 frame, 10 pedestrian-sized targets, the
detections of the targets then uniform clutter), for each ``particles x detections`` size it
times each stage on the inputs the previous stage produced, called ``--calls`` times inside
one jitted ``lax.scan`` (every call's floating-point inputs get ``0 * i`` added and its PRNG
keys ``i`` folded in, so that XLA cannot hoist the loop-invariant work out of the loop; the
per-call cost of a Python dispatch is spread over the calls): the median over ``--repeats``
runs after a compile run, divided by ``--calls``:

* ``predict``: :func:`jaxtrack.filters.phd.predict` (constant-velocity draws, survival);
* ``births``: :func:`~jaxtrack.filters.phd.phd_births` (draws around the detections, their
  proposal density and the birth intensity);
* ``update``: :func:`~jaxtrack.filters.phd.phd_update` (eq. 10, the log-likelihood and the
  extraction's reductions);
* ``resample``: :func:`~jaxtrack.filters.resampling.resample` of the particles and their
  expected scores (systematic);
* ``extract``: :func:`~jaxtrack.filters.phd.partition_estimates`;
* ``label``: :func:`~jaxtrack.association.labelling.label_step` (IoU gate and the Hungarian
  assignment against a table of live tracks);
* ``step``: the tracker's whole ``phd_filter(...).step``, and ``bookkeeping`` = ``step`` minus
  the stages' sum (the concatenations, key splits and outputs; negative when XLA fuses
  across stages what separate calls cannot).

The step keeps the tracker's default ``births_per_detection`` (32); the labelling sees the
table after three steps on the frame (its tracks live). Prints one table per size and one
JSON object on its last line. Usage: ``python benchmarks/phd_profile.py [--particles 2048
100000] [--detections 18] [--repeats 11] [--calls 20] [--cpu-threads N]`` (XLA's CPU thread
pool as the ``jaxtrack`` command sizes it, one thread, unless ``--cpu-threads`` says otherwise;
0: XLA's default, one per core).
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import platform
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from phd_step import FRAME_RATE, HEIGHT, NUM_TARGETS, WIDTH, scene, wall_times
from timing import add_cpu_threads_option, set_cpu_threads, set_cpu_vector_width

from jaxtrack.association.labelling import label_step
from jaxtrack.boxes import xywh_to_cxcywh
from jaxtrack.filters import default_phd_params, phd_filter, resample
from jaxtrack.filters.phd import (
    Posterior,
    partition_estimates,
    phd_births,
    phd_update,
    predict,
)
from jaxtrack.filters.phd_tracker import PHDConfig

STAGES = ("predict", "births", "update", "resample", "extract", "label")


def in_scan(function, args: tuple, calls: int):
    """A jitted ``() -> total`` calling ``function`` ``calls`` times inside one ``lax.scan``.

    Every call gets ``0 * i`` added to each floating-point leaf of ``args`` and ``i`` folded
    into each PRNG key (``i`` the iteration), so that XLA cannot hoist a loop-invariant
    computation out of the loop; the outputs' sum is carried so that no call is dropped.
    """
    leaves, treedef = jax.tree.flatten(args)

    def vary(leaf, i):
        if jnp.issubdtype(leaf.dtype, jax.dtypes.prng_key):
            return jax.random.fold_in(leaf, i.astype(jnp.int32))
        if jnp.issubdtype(leaf.dtype, jnp.floating):
            return leaf + 0.0 * i
        return leaf

    def body(total, i):
        out = function(*jax.tree.unflatten(treedef, [vary(leaf, i) for leaf in leaves]))
        floats = [x for x in jax.tree.leaves(out) if jnp.issubdtype(x.dtype, jnp.floating)]
        return total + sum(jnp.sum(x) for x in floats), None

    looped = jax.jit(lambda: jax.lax.scan(body, 0.0, jnp.arange(calls, dtype=jnp.float32))[0])
    return looped


def profile(num_particles: int, num_detections: int, repeats: int, calls: int) -> dict:
    """Seconds per stage, the whole step and the bookkeeping at one size."""
    births_per_detection = PHDConfig().births_per_detection
    params = default_phd_params(WIDTH, HEIGHT, FRAME_RATE)
    particles, log_weights, detections = scene(num_particles, num_detections)
    frame = jax.tree.map(lambda x: jnp.asarray(x[0]), detections)
    key = jax.random.key(0)
    filt = phd_filter(num_particles, births_per_detection=births_per_detection)
    state = filt.init(key, params)._replace(
        particles=jnp.asarray(particles),
        log_weights=jnp.asarray(log_weights),
        mass=jnp.asarray(float(NUM_TARGETS)),
    )
    step = jax.jit(filt.step)
    for warm in range(3):  # live tracks in the table for the labelling
        state, _ = step(jax.random.key(warm + 1), state, params, frame)
    state = state._replace(particles=jnp.asarray(particles), log_weights=jnp.asarray(log_weights))
    measurements = xywh_to_cxcywh(frame.boxes, jnp)

    stages = {
        "predict": (jax.jit(predict), (key, state.particles, state.log_weights, params)),
    }
    survivors, survivor_log_weights = stages["predict"][0](*stages["predict"][1])
    births = jax.jit(functools.partial(phd_births, births_per_detection=births_per_detection))
    stages["births"] = (births, (key, measurements, frame.mask, params, jnp.asarray(True)))
    born, birth_log_weights = births(*stages["births"][1])
    predicted = jnp.concatenate([survivors, born])
    predicted_log_weights = jnp.concatenate([survivor_log_weights, birth_log_weights])
    update_args = (
        params,
        measurements,
        frame.scores,
        frame.mask,
        predicted,
        predicted_log_weights,
    )
    stages["update"] = (jax.jit(phd_update), update_args)
    updated = phd_update(*update_args)
    resampler = jax.jit(functools.partial(resample, num_samples=num_particles))
    stages["resample"] = (
        resampler,
        (key, (predicted, updated.particle_scores), updated.log_weights),
    )
    (new_particles, new_scores), new_log_weights = resampler(*stages["resample"][1])
    posterior = Posterior(new_particles, new_log_weights, new_scores)
    stages["extract"] = (
        jax.jit(partition_estimates),
        (key, updated, posterior, frame, params),
    )
    estimates = partition_estimates(key, updated, posterior, frame, params)
    stages["label"] = (jax.jit(label_step), (state.labels, params.labelling, estimates))

    stages["step"] = (filt.step, (key, state, params, frame))
    seconds = {}
    for name, (function, args) in stages.items():
        looped = in_scan(function, args, calls)
        jax.block_until_ready(looped())  # compile
        seconds[name] = wall_times(lambda f=looped: jax.block_until_ready(f()), repeats)[0] / calls
    seconds["bookkeeping"] = seconds["step"] - sum(seconds[name] for name in STAGES)
    return {
        "num_particles": num_particles,
        "num_detections": num_detections,
        "births_per_detection": births_per_detection,
        "predicted_particles": int(predicted.shape[0]),
        "live_tracks": int(np.sum(np.asarray(state.labels.table.active))),
        "seconds": seconds,
    }


def table(result: dict) -> str:
    """A text table of one size's profile (ms and share of the step)."""
    seconds = result["seconds"]
    lines = [
        f"{result['num_particles']} particles x {result['num_detections']} detections "
        f"({result['predicted_particles']} predicted with births, "
        f"{result['live_tracks']} live tracks)"
    ]
    for name in (*STAGES, "bookkeeping", "step"):
        share = 100 * seconds[name] / seconds["step"]
        lines.append(f"  {name:<12} {1e3 * seconds[name]:9.3f} ms  {share:6.1f} %")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--particles", type=int, nargs="+", default=[2048, 100_000])
    parser.add_argument("--detections", type=int, nargs="+", default=[18])
    parser.add_argument("--repeats", type=int, default=11, help="timed runs (median)")
    parser.add_argument("--calls", type=int, default=20, help="calls of a stage per run")
    add_cpu_threads_option(parser)
    args = parser.parse_args()
    cpu_threads = set_cpu_threads(args.cpu_threads)
    vector_width = set_cpu_vector_width(args.vector_width)
    results = []
    for n in args.particles:
        for m in args.detections:
            results.append(profile(n, m, args.repeats, args.calls))
            print(table(results[-1]), flush=True)
    print(
        json.dumps(
            {
                "benchmark": "phd_profile",
                "results": results,
                "cpu_count": os.cpu_count(),
                "cpu_threads": cpu_threads,
                "cpu_vector_width": vector_width,
                "load_average": os.getloadavg(),
                "platform": platform.platform(),
                "jax_version": jax.__version__,
            }
        )
    )


if __name__ == "__main__":
    main()
