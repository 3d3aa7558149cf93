"""Fusion's motion predictor on PETS09-S2L1: held-out error against constant velocity, speed.

Accuracy: per-cell GP motion models (:mod:`jaxtrack.context.motion_models`, defaults) fitted
on the ground-truth trajectories of frames 1-397 (foot points, tracklets of 5 points), then
every tracklet of frames 398-795 predicts its next foot point
(:func:`jaxtrack.filters.fusion_motion.predict_motion`). Reported: the mean and RMS distance
(pixels) to the true next foot point, for the GP predictor, constant velocity with the last
velocity ``p_N + (p_N - p_{N-1})``, and constant velocity with the tracklet's mean velocity
(the GP's prior mean and fallback), over all test tracklets and over those in cells with a
model.

Speed: ``predict_motion`` jitted for 16 targets (each tracklet a random test tracklet), the
median per-frame time of ``--repeats`` calls (``block_until_ready``), against the same
prediction through tinygp's ``GaussianProcess.condition`` (which factorises the cell's
``K x K`` Gram matrix on each call; padded slots get a 1e6 diagonal), and their largest
difference. Prints one JSON object on its last line.
Usage: ``python benchmarks/fusion_motion.py [--repeats 200]``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import tinygp

from jaxtrack.context.motion_models import (
    cut_tracklets,
    fit_motion_models,
    mean_velocity,
    motion_kernel,
    tracklet_cells,
    tracklet_inputs,
)
from jaxtrack.filters.fusion_motion import predict_motion
from jaxtrack.io.motchallenge import read_mot_file
from jaxtrack.types import MotTable

SEQUENCE = Path(__file__).resolve().parents[2] / "shared" / "data" / "mot15" / "PETS09-S2L1"
WIDTH, HEIGHT, SPLIT, TARGETS = 768, 576, 397, 16


def tinygp_predict(models, tracklets, residuals):
    """The posterior mean and variance by tinygp's ``condition`` (one factorisation a target)."""

    def one(tracklet):
        cell = tracklet_cells(tracklet[-1], models.cell_size, models.grid)
        kernel = motion_kernel(models.length_scale, models.amplitude)
        diag = jnp.where(models.mask[cell], models.noise, 1e6)
        gp = tinygp.GaussianProcess(kernel, models.inputs[cell], diag=diag)
        query = tracklet_inputs(tracklet)[None]
        means = [gp.condition(residuals[cell][:, a], query).gp.loc[0] for a in range(2)]
        variance = gp.condition(residuals[cell][:, 0], query).gp.variance[0] + models.noise
        return tracklet[-1] + mean_velocity(tracklet) + jnp.stack(means), variance

    return jax.vmap(one)(tracklets)


def cell_residuals(models):
    """The cells' training residuals ``r = K_y alpha`` (zero on padded slots)."""

    def one(inputs, mask, alpha):
        kernel = motion_kernel(models.length_scale, models.amplitude)
        gram = jnp.where(mask[:, None] & mask[None], kernel(inputs, inputs), 0.0)
        return (gram + jnp.diag(jnp.where(mask, models.noise, 1.0))) @ alpha

    return jax.vmap(one)(models.inputs, models.mask, models.alpha)


def median_ms(function, repeats):
    jax.block_until_ready(function())
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(function())
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=200)
    args = parser.parse_args()
    gt = read_mot_file(SEQUENCE / "gt" / "gt.txt", kind="gt")

    def part(selected):
        return MotTable.from_arrays(gt.frames[selected], gt.ids[selected], gt.boxes[selected])

    train = cut_tracklets(part((gt.confs > 0) & (gt.frames <= SPLIT)))
    test = cut_tracklets(part((gt.confs > 0) & (gt.frames > SPLIT)))
    start = time.perf_counter()
    models = jax.block_until_ready(fit_motion_models(train, WIDTH, HEIGHT))
    fit_s = time.perf_counter() - start
    predict = jax.jit(predict_motion)
    points, _ = predict(
        models, jnp.asarray(test.points, jnp.float32), jnp.ones(len(test.points), bool)
    )
    cells = np.asarray(
        tracklet_cells(test.points[:, -1], float(models.cell_size), np.asarray(models.grid))
    )
    fitted = np.asarray(models.fitted)[cells]
    predictions = {
        "gp": np.asarray(points),
        "cv_last_velocity": 2 * test.points[:, -1] - test.points[:, -2],
        "cv_mean_velocity": test.points[:, -1] + mean_velocity(test.points),
    }
    errors = {}
    for name, predicted in predictions.items():
        distance = np.linalg.norm(predicted - test.next_points, axis=1)
        errors[name] = {
            "mean_px": round(float(distance.mean()), 4),
            "rms_px": round(float(np.sqrt((distance**2).mean())), 4),
            "mean_px_in_fitted_cells": round(float(distance[fitted].mean()), 4),
        }
    rng = np.random.default_rng(0)
    frame = jnp.asarray(test.points[rng.choice(len(test.points), TARGETS)], jnp.float32)
    valid = jnp.ones(TARGETS, bool)
    residuals = cell_residuals(models)
    ours = jax.jit(lambda t: predict_motion(models, t, valid))
    theirs = jax.jit(lambda t: tinygp_predict(models, t, residuals))
    difference = max(
        float(jnp.max(jnp.abs(a - b))) for a, b in zip(ours(frame), theirs(frame), strict=True)
    )
    result = {
        "train_tracklets": len(train.points),
        "test_tracklets": len(test.points),
        "fitted_cells": int(models.fitted.sum()),
        "cells": int(models.fitted.size),
        "test_tracklets_in_fitted_cells": int(fitted.sum()),
        "length_scale": round(float(models.length_scale), 4),
        "amplitude": round(float(models.amplitude), 4),
        "noise": round(float(models.noise), 4),
        "fit_s": round(fit_s, 3),
        "errors": errors,
        "targets": TARGETS,
        "predict_ms_per_frame": round(median_ms(lambda: ours(frame), args.repeats), 4),
        "tinygp_condition_ms_per_frame": round(median_ms(lambda: theirs(frame), args.repeats), 4),
        "tinygp_max_difference": difference,
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
