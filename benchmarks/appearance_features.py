"""Speed and accuracy of the appearance features on PETS09-S2L1 frames (768x576).

Speed: a jitted ``lax.scan`` over ``--frames`` frames (decoded once from vtest.avi, uint8 RGB)
computes, per frame, the top and bottom joint RGB histograms (8 bins per channel = 512 joint
bins) of 16 targets x 64 particles = 1024 boxes. The targets are the frame's ground-truth
boxes (filled up to 16 with pedestrian-sized boxes at seeded random places), the particles
their boxes jittered (5 px, 5 %). The step's output is one number per box (the histograms
dotted with a fixed vector), so XLA computes every histogram but the scan does not write them
out. Times are per frame, after compilation, ``block_until_ready``, median and minimum of
``--repeats`` runs of the scan, runs interleaved within a group (so a change in the
machine's other load affects them alike): the default, its bilinear twin and its float
quantisation twin first (a short group), then the other variants, then the two slow ones
(3 repeats). Also reported: the process CPU time per frame (both cores' threads summed) and
``others_cpu_share``, the CPU time other processes took during each group's timed runs as a
share of all the cores' time (the machine is shared; 0 means nothing else ran). Reported:

* ``features_ms_per_frame``: the default, :func:`jaxtrack.appearance.top_bottom_histograms`
  (nearest-pixel uint8 samples binned by a bit shift, ``v >> 5``; scatter-add counting) with
  the patch :data:`jaxtrack.appearance.DEFAULT_PATCH_SHAPE`;
* ``alternatives``: other patch sizes; bilinear samples
  (:func:`jaxtrack.appearance.sample_patch`) instead of nearest-pixel ones; the samples
  quantised as floats (``floor(v / 32)``, the same bins; the default before the shift);
  counting by summed one-hot vectors instead of the scatter-add; per-channel histograms
  (3 x 8 bins, CMT's bucket features) instead of joint, from patch samples or exact from an
  integral histogram of the frame; the Epanechnikov kernel per half;
  and the features followed by the Bhattacharyya likelihood of each particle against its
  target's model (what a tracker step does next).

Accuracy: on ``--accuracy-frames`` frames, for every ground-truth box wholly inside the image,
the Bhattacharyya distance between each half's patch histogram and its full-resolution
histogram (every pixel whose centre lies in the half, NumPy), per patch size and sampler
(median and 90th percentile, of the mean over the two halves); ``nearest_full_is_own``: the
share of boxes (in frames with two people or more) whose patch histograms are nearer their
own full-resolution histograms than any other person's in the frame; for scale, the median
distance between the full-resolution histograms of two different people in the same frame.

Prints one JSON object on its last line. Goal: ``features_ms_per_frame <= 2`` on 2 CPU cores.
Timings on a shared machine vary with the other load on it (``load_average`` is reported).
Usage: ``python benchmarks/appearance_features.py [--quick]``.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import platform
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.appearance import (
    DEFAULT_PATCH_SHAPE,
    band_histograms,
    bhattacharyya_distance,
    epanechnikov,
    halves,
    histogram_likelihood,
    joint_bins,
    normalise,
    quantise,
    sample_nearest,
    sample_patch,
    top_bottom_histograms,
)
from jaxtrack.io import read_mot_file
from jaxtrack.io.video import VideoReader

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
VIDEO = DATA / "video" / "vtest.avi"
GROUND_TRUTH = DATA / "mot15" / "PETS09-S2L1" / "gt" / "gt.txt"
NUM_TARGETS, NUM_PARTICLES = 16, 64
STEP = 32.0  # 8 bins per channel
PATCHES = ((8, 4), (12, 6), (16, 8), (24, 12), (32, 16))


def read_frames(count: int, first: int = 1) -> np.ndarray:
    """Frames ``first .. first + count - 1`` of vtest.avi, ``[count, 576, 768, 3]`` uint8 RGB."""
    with VideoReader(VIDEO) as reader:
        return np.stack([reader.read(first + t) for t in range(count)])


def particle_boxes(gt, count: int, rng: np.random.Generator) -> np.ndarray:
    """``[count, 1024, 4]``: 64 jittered copies of 16 target boxes per frame."""
    boxes = np.empty((count, NUM_TARGETS * NUM_PARTICLES, 4), np.float32)
    for t in range(count):
        targets = gt.boxes[gt.frames == t + 1][:NUM_TARGETS]
        extra = NUM_TARGETS - len(targets)
        size = rng.uniform([25, 60], [45, 110], (extra, 2))
        corner = rng.uniform(0, 1, (extra, 2)) * ([768, 576] - size)
        targets = np.concatenate([targets, np.concatenate([corner, size], 1)])
        scale = np.repeat(targets[:, 2:], NUM_PARTICLES, 0)
        jitter = rng.normal(0, 1, (NUM_TARGETS * NUM_PARTICLES, 4))
        jitter[:, :2] *= 5.0
        jitter[:, 2:] *= 0.05 * scale
        boxes[t] = np.repeat(targets, NUM_PARTICLES, 0) + jitter
    return boxes


def nearest_top_bottom(frame, boxes, patch_shape):
    """The default: :func:`top_bottom_histograms` with nearest-pixel samples."""
    return jax.vmap(top_bottom_histograms, in_axes=(None, 0, None, None))(
        frame, boxes, patch_shape, STEP
    )


def as_float(pixels):
    """RGB as float colours (the float path; :func:`jaxtrack.appearance.rgb` keeps uint8)."""
    return pixels.astype(jnp.float32)


def float_quantise_top_bottom(frame, boxes, patch_shape):
    """The default but quantising the samples as floats (``floor(v / 32)``, not ``v >> 5``)."""
    features = functools.partial(top_bottom_histograms, colour_space=as_float)
    return jax.vmap(features, in_axes=(None, 0, None, None))(frame, boxes, patch_shape, STEP)


def bilinear_top_bottom(frame, boxes, patch_shape):
    """:func:`top_bottom_histograms` with bilinear samples (the brief's first design)."""
    features = functools.partial(top_bottom_histograms, sampler=sample_patch)
    return jax.vmap(features, in_axes=(None, 0, None, None))(frame, boxes, patch_shape, STEP)


def _joint_bins(frame, box, patch_shape):
    patch = sample_nearest(frame, box, patch_shape)
    return joint_bins(quantise(patch.values.astype(jnp.float32), STEP), 8), patch.valid


def one_hot_top_bottom(frame, boxes, patch_shape):
    """As the default but counting by summed one-hot vectors over the 512 bins."""

    def one(box):
        bins, valid = _joint_bins(frame, box, patch_shape)
        hot = jax.nn.one_hot(bins, 512) * valid[..., None]
        rows = patch_shape[0] // 2
        return normalise(jnp.stack([hot[:rows].sum((0, 1)), hot[rows:].sum((0, 1))]))

    return jax.vmap(one)(boxes)


def channel_top_bottom(frame, boxes, patch_shape):
    """Per-channel (3 x 8 bins) top and bottom histograms: CMT's bucket features directly."""

    def one(box):
        patch = sample_nearest(frame, box, patch_shape)
        bins = quantise(patch.values.astype(jnp.float32), STEP)
        counts = band_histograms(bins, patch.valid, halves(patch_shape[0]), 8)
        return counts.reshape(2, 24)

    return jax.vmap(one)(boxes)


def kernel_top_bottom(frame, boxes, patch_shape):
    """The default with one Epanechnikov kernel per half."""
    half = epanechnikov((patch_shape[0] // 2, patch_shape[1]))
    kernel = jnp.concatenate([half, half])
    features = functools.partial(top_bottom_histograms, kernel=kernel)
    return jax.vmap(features, in_axes=(None, 0, None, None))(frame, boxes, patch_shape, STEP)


def integral_channel_top_bottom(frame, boxes, patch_shape):
    """Exact per-channel (3 x 8 bins) histograms from an integral histogram of the frame.

    The integral image ``I[r, c] = sum_{r' < r, c' < c} onehot(F[r', c'])`` is built once
    per frame (``[577, 769, 3, 8]`` floats); each half is then 4 lookups. ``patch_shape`` is
    unused (every pixel counts); box edges are rounded to whole pixels. A joint 512-bin
    integral histogram would hold 227 million floats per frame, so it is not tried.
    """
    del patch_shape
    height, width = frame.shape[:2]
    hot = ((frame[..., None] >> 5) == jnp.arange(8, dtype=jnp.uint8)).astype(jnp.float32)
    integral = jnp.pad(jnp.cumsum(jnp.cumsum(hot, 0), 1), ((1, 0), (1, 0), (0, 0), (0, 0)))

    def one(box):
        x0, x1 = (jnp.clip(jnp.round(v), 0, width).astype(int) for v in (box[0], box[0] + box[2]))
        y0, ym, y1 = (
            jnp.clip(jnp.round(v), 0, height).astype(int)
            for v in (box[1], box[1] + box[3] / 2, box[1] + box[3])
        )
        top = integral[ym, x1] - integral[y0, x1] - integral[ym, x0] + integral[y0, x0]
        bottom = integral[y1, x1] - integral[ym, x1] - integral[y1, x0] + integral[ym, x0]
        return normalise(jnp.stack([top, bottom])).reshape(2, 24)

    return jax.vmap(one)(boxes)


def scan_function(features, patch_shape, likelihood: bool = False):
    """A jitted scan of ``features`` over frames and their boxes."""

    def step(carry, inputs):
        frame, frame_boxes = inputs
        histograms = features(frame, frame_boxes, patch_shape)
        if likelihood:
            models = histograms.reshape(NUM_TARGETS, NUM_PARTICLES, *histograms.shape[1:])[:, 0]
            target = jnp.repeat(models, NUM_PARTICLES, axis=0)
            out = jnp.prod(histogram_likelihood(histograms, target, 0.2), axis=-1)
        else:
            probe = jnp.arange(histograms.shape[-1], dtype=jnp.float32)
            out = jnp.sum(histograms * probe, axis=(-2, -1))
        return carry, out

    return jax.jit(lambda f, b: jax.lax.scan(step, 0.0, (f, b))[1])


def busy_seconds() -> float:
    """CPU seconds all processes have spent busy since boot (Linux ``/proc/stat``)."""
    with open("/proc/stat") as stat:
        fields = [int(v) for v in stat.readline().split()[1:]]
    return (sum(fields) - fields[3] - fields[4]) / os.sysconf("SC_CLK_TCK")


def time_scans(scans: dict, frames, boxes, repeats: int) -> tuple[dict, float]:
    """Times each scan (its runs interleaved with the others').

    Returns:
        Per scan: ms per frame (median, min), process CPU ms per frame, first-call seconds;
        and the CPU time of other processes during the timed runs as a share of all the
        cores' time (0: nothing else ran).
    """
    first, times, cpu = {}, {name: [] for name in scans}, {name: [] for name in scans}
    for name, scan in scans.items():
        start = time.perf_counter()
        scan(frames, boxes).block_until_ready()
        first[name] = time.perf_counter() - start
    for scan in scans.values():  # one untimed round: first-run memory and clock ramp-up
        scan(frames, boxes).block_until_ready()
    busy, own, wall = busy_seconds(), time.process_time(), time.perf_counter()
    for _ in range(repeats):
        for name, scan in scans.items():
            start, start_cpu = time.perf_counter(), time.process_time()
            scan(frames, boxes).block_until_ready()
            times[name].append((time.perf_counter() - start) * 1e3 / frames.shape[0])
            cpu[name].append((time.process_time() - start_cpu) * 1e3 / frames.shape[0])
    others = (busy_seconds() - busy) - (time.process_time() - own)
    result = {
        name: {
            "ms_per_frame_median": round(float(np.median(times[name])), 3),
            "ms_per_frame_min": round(float(np.min(times[name])), 3),
            "cpu_ms_per_frame_median": round(float(np.median(cpu[name])), 3),
            "first_call_s": round(first[name], 2),
        }
        for name in scans
    }
    share = max(others, 0.0) / ((time.perf_counter() - wall) * os.cpu_count())
    return result, round(share, 3)


def full_resolution(frame: np.ndarray, box: np.ndarray) -> np.ndarray:
    """Top and bottom joint RGB histograms from every pixel whose centre is in each half."""
    x, y, w, h = box
    cols = np.arange(frame.shape[1])
    rows = np.arange(frame.shape[0])
    in_cols = (cols + 0.5 >= x) & (cols + 0.5 < x + w)
    halves_out = []
    for lo, hi in ((y, y + h / 2), (y + h / 2, y + h)):
        in_rows = (rows + 0.5 >= lo) & (rows + 0.5 < hi)
        pixels = frame[np.ix_(in_rows, in_cols)].reshape(-1, 3).astype(np.int64) // 32
        counts = np.bincount(pixels[:, 0] * 64 + pixels[:, 1] * 8 + pixels[:, 2], minlength=512)
        halves_out.append(counts / counts.sum())
    return np.stack(halves_out)


def accuracy(gt, num_frames: int) -> dict:
    """Distance of patch histograms to full-resolution ones, per patch size, on GT boxes."""
    step_frames = np.linspace(1, 795, num_frames).astype(int)
    frames, boxes = [], []
    with VideoReader(VIDEO) as reader:
        for number in step_frames:
            rows = gt.boxes[gt.frames == number]
            inside = (
                (rows[:, 0] >= 0)
                & (rows[:, 1] >= 0)
                & (rows[:, 0] + rows[:, 2] <= 768)
                & (rows[:, 1] + rows[:, 3] <= 576)
            )
            if inside.any():
                frames.append(reader.read(int(number)))
                boxes.append(rows[inside])
    references = [
        np.stack([full_resolution(f, b) for b in bs]) for f, bs in zip(frames, boxes, strict=True)
    ]
    between = [
        float(np.mean(bhattacharyya_distance(a, b)))
        for refs in references
        for i, a in enumerate(refs)
        for b in refs[i + 1 :]
    ]
    result = {
        "frames": len(frames),
        "boxes": sum(len(b) for b in boxes),
        "median_distance_between_people": round(float(np.median(between)), 3),
        "median_box_height_px": round(float(np.median(np.concatenate(boxes)[:, 3])), 1),
    }
    samplers = {"nearest": nearest_top_bottom, "bilinear": bilinear_top_bottom}
    for patch in PATCHES:
        for sampler, function in samplers.items():
            features = jax.jit(functools.partial(function, patch_shape=patch))
            own, identified, crowded = [], 0, 0
            for frame, frame_boxes, refs in zip(frames, boxes, references, strict=True):
                histograms = np.asarray(features(frame, jnp.asarray(frame_boxes, jnp.float32)))
                # distance[i, j]: box i's patch halves to person j's full-resolution halves.
                distance = np.asarray(bhattacharyya_distance(histograms[:, None], refs[None])).mean(
                    -1
                )
                own.extend(np.diag(distance))
                if len(refs) > 1:
                    identified += int(np.sum(np.argmin(distance, 1) == np.arange(len(refs))))
                    crowded += len(refs)
            result[f"{sampler}_{patch[0]}x{patch[1]}"] = {
                "median_distance_to_full": round(float(np.median(own)), 3),
                "p90_distance_to_full": round(float(np.percentile(own, 90)), 3),
                "nearest_full_is_own": round(identified / max(crowded, 1), 3),
            }
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--frames", type=int, default=20, help="frames per timed scan")
    parser.add_argument("--repeats", type=int, default=11, help="timed scans (median, min)")
    parser.add_argument("--accuracy-frames", type=int, default=40, help="frames for accuracy")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quick", action="store_true", help="5 frames, 3 repeats, 5 accuracy")
    args = parser.parse_args()
    if args.quick:
        args.frames, args.repeats, args.accuracy_frames = 5, 3, 5

    gt = read_mot_file(GROUND_TRUTH, "gt")
    frames = jnp.asarray(read_frames(args.frames))
    boxes = jnp.asarray(particle_boxes(gt, args.frames, np.random.default_rng(args.seed)))
    load_before = os.getloadavg()[0]

    # The default against bilinear and float quantisation alone first (short, so other load
    # is less likely to fall on it), then the other sizes and variants, then the slow ones
    # with 3 repeats.
    default_name = f"nearest_{DEFAULT_PATCH_SHAPE[0]}x{DEFAULT_PATCH_SHAPE[1]}"
    main, main_share = time_scans(
        {
            default_name: scan_function(nearest_top_bottom, DEFAULT_PATCH_SHAPE),
            "bilinear_16x8": scan_function(bilinear_top_bottom, DEFAULT_PATCH_SHAPE),
            "float_quantise_16x8": scan_function(float_quantise_top_bottom, DEFAULT_PATCH_SHAPE),
        },
        frames,
        boxes,
        args.repeats,
    )
    scans = {}
    for patch in PATCHES:
        if patch != DEFAULT_PATCH_SHAPE:
            scans[f"nearest_{patch[0]}x{patch[1]}"] = scan_function(nearest_top_bottom, patch)
            scans[f"bilinear_{patch[0]}x{patch[1]}"] = scan_function(bilinear_top_bottom, patch)
    scans["per_channel_16x8"] = scan_function(channel_top_bottom, DEFAULT_PATCH_SHAPE)
    scans["epanechnikov_16x8"] = scan_function(kernel_top_bottom, DEFAULT_PATCH_SHAPE)
    scans["with_likelihood_16x8"] = scan_function(nearest_top_bottom, DEFAULT_PATCH_SHAPE, True)
    variants, variants_share = time_scans(scans, frames, boxes, args.repeats)
    slow = {
        "one_hot_16x8": scan_function(one_hot_top_bottom, DEFAULT_PATCH_SHAPE),
        "integral_per_channel": scan_function(integral_channel_top_bottom, DEFAULT_PATCH_SHAPE),
    }
    slow, slow_share = time_scans(slow, frames, boxes, 3)
    default = main.pop(default_name)
    result = {
        "features_ms_per_frame": default["ms_per_frame_median"],
        "features_ms_per_frame_min": default["ms_per_frame_min"],
        "features_cpu_ms_per_frame": default["cpu_ms_per_frame_median"],
        "others_cpu_share": {"main": main_share, "variants": variants_share, "slow": slow_share},
        "goal_ms_per_frame": 2.0,
        "patch_shape": list(DEFAULT_PATCH_SHAPE),
        "boxes_per_frame": NUM_TARGETS * NUM_PARTICLES,
        "histograms": "top + bottom halves, joint RGB, 8 bins a channel (512, v >> 5), scatter-add",
        "sampler": "nearest pixel (sample_nearest)",
        "frame_size": [768, 576],
        "scan_frames": args.frames,
        "repeats": args.repeats,
        "alternatives": main | variants | slow,
        "accuracy": accuracy(gt, args.accuracy_frames),
        "cpu_count": os.cpu_count(),
        "load_average": [round(load_before, 2), round(os.getloadavg()[0], 2)],
        "jax": jax.__version__,
        "machine": platform.machine(),
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
