"""Speed of CMT's feature pool (``jaxtrack.filters.cmt_observation.box_features``).

On ``--frames`` PETS09-S2L1 frames (768x576, decoded once from vtest.avi, uint8 RGB), a jitted
``lax.scan`` computes per frame the 49 features (lambda = 32, patch 16 x 8) of 16 components x
40 particles = 640 boxes (pedestrian-sized boxes at seeded random places, some straddling the
border), reducing each box's features to one number so that XLA computes them all but the
scan writes nothing out. Two ways of counting the colour buckets:

* ``per_channel`` (the package's): one scatter-add of the ``3 ph pw`` channel bins;
* ``joint_marginals``: the joint 512-bin histograms of the halves
  (:func:`jaxtrack.appearance.top_bottom_histograms`), then their per-channel marginals.

``com_frame``: everything the observation model costs a CMT frame: the per-channel features
of the 640 particle boxes, the COM weights of the 16 components (all alive, all in each
other's field of context: the most mutual information to compute), the particles'
appearance log-likelihoods, and the update of the models at 16 local decisions (the
appearance state carried through the scan).

Times are per frame after compilation (``block_until_ready``), the minimum and median of
``--repeats`` interleaved runs. Goal: about 3 ms per frame on 2 CPU cores (the CMT tracker
aims at 25 frames/s). Prints one JSON object on its last line.
Usage: ``python benchmarks/com_features.py [--frames 20] [--repeats 7]``.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import statistics
import time
from pathlib import Path

import cv2
import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.appearance import (
    DEFAULT_PATCH_SHAPE,
    feature_values,
    marginals,
    top_bottom_histograms,
)
from jaxtrack.filters.cmt_observation import (
    NUM_LEVELS,
    NUM_VALUES,
    STEP,
    appearance_log_likelihood,
    box_features,
    default_com_params,
    init_appearance,
    num_features,
    observation_weights,
    update_appearance,
)

VIDEO = Path(__file__).resolve().parents[2] / "shared" / "data" / "video" / "vtest.avi"
COMPONENTS, PARTICLES = 16, 40


def joint_marginal_features(frame, box, step, patch_shape):
    """The same 49 features through the joint histograms and their marginals."""
    joint = top_bottom_histograms(frame, box, patch_shape, step)
    return feature_values(marginals(joint, 3), box)


def read_frames(count: int) -> np.ndarray:
    capture = cv2.VideoCapture(str(VIDEO))
    frames = []
    while len(frames) < count:
        ok, bgr = capture.read()
        if not ok:
            raise SystemExit(f"{VIDEO}: only {len(frames)} frames")
        frames.append(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
    return np.stack(frames)


def random_boxes(rng, count, height, width) -> np.ndarray:
    h = rng.uniform(50, 120, count)
    w = h * rng.uniform(0.3, 0.5, count)
    x = rng.uniform(-0.2 * w, width - 0.8 * w)
    y = rng.uniform(-0.2 * h, height - 0.8 * h)
    return np.stack([x, y, w, h], axis=1).astype(np.float32)


def scan_timer(features_fn, frames, boxes):
    per_box = jax.vmap(features_fn, in_axes=(None, 0))
    weights = jnp.linspace(0.5, 1.5, 49)

    @jax.jit
    def run(frames, boxes):
        def step(carry, inputs):
            frame, frame_boxes = inputs
            return carry, per_box(frame, frame_boxes) @ weights

        return jax.lax.scan(step, 0.0, (frames, boxes))[1]

    run(frames, boxes).block_until_ready()

    def timed():
        start = time.perf_counter()
        run(frames, boxes).block_until_ready()
        return (time.perf_counter() - start) / frames.shape[0] * 1e3

    return timed


def com_frame_timer(frames, boxes):
    """Per-frame time of features, COM weights, likelihoods and model update (``com_frame``)."""
    per_box = jax.vmap(box_features, in_axes=(None, 0, None, None))
    params = default_com_params()
    alive = jnp.ones(COMPONENTS, bool)
    none = jnp.zeros(COMPONENTS, bool)

    @jax.jit
    def run(frames, boxes):
        def step(state, inputs):
            frame, frame_boxes = inputs
            features = per_box(frame, frame_boxes, STEP, DEFAULT_PATCH_SHAPE)
            features = features.reshape(COMPONENTS, PARTICLES, -1)
            centres = frame_boxes[::PARTICLES, :2] + frame_boxes[::PARTICLES, 2:] / 2
            rho = observation_weights(state.counts, centres, alive, 1e4, params, NUM_LEVELS, True)
            log_likelihood = appearance_log_likelihood(features, state, rho, params)
            state = update_appearance(state, features[:, 0], alive, none, none, params)
            return state, jnp.sum(log_likelihood)

        state = init_appearance(COMPONENTS, num_features(STEP), NUM_VALUES)
        return jax.lax.scan(step, state, (frames, boxes))[1]

    run(frames, boxes).block_until_ready()

    def timed():
        start = time.perf_counter()
        run(frames, boxes).block_until_ready()
        return (time.perf_counter() - start) / frames.shape[0] * 1e3

    return timed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20, help="frames per timed scan")
    parser.add_argument("--repeats", type=int, default=7, help="timed scans per variant")
    args = parser.parse_args()
    frames = read_frames(args.frames)
    rng = np.random.default_rng(0)
    boxes = np.stack(
        [random_boxes(rng, COMPONENTS * PARTICLES, *frames.shape[1:3]) for _ in frames]
    )
    frames, boxes = jnp.asarray(frames), jnp.asarray(boxes)
    variants = {
        "per_channel": box_features,
        "joint_marginals": joint_marginal_features,
    }
    timers = {
        name: scan_timer(
            functools.partial(fn, step=STEP, patch_shape=DEFAULT_PATCH_SHAPE), frames, boxes
        )
        for name, fn in variants.items()
    }
    timers["com_frame"] = com_frame_timer(frames, boxes)
    times = {name: [] for name in timers}
    for _ in range(args.repeats):
        for name, timed in timers.items():
            times[name].append(timed())
    result = {
        "boxes_per_frame": COMPONENTS * PARTICLES,
        "patch_shape": list(DEFAULT_PATCH_SHAPE),
        "step": STEP,
        "load_average": os.getloadavg()[0],
        **{
            f"{name}_ms_per_frame": {
                "min": round(min(values), 3),
                "median": round(statistics.median(values), 3),
            }
            for name, values in times.items()
        },
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
