"""Speed and accuracy of Fusion's correlation-filter classifier on PETS09-S2L1 (768x576).

Speed: 16 target slots (the ground-truth people of the first frame, filled up to 16 with
pedestrian-sized boxes at seeded random places) are started on frame ``--first`` of vtest.avi
and followed over ``--frames`` frames (decoded once, uint8 RGB) by a jitted ``lax.scan`` of
:func:`jaxtrack.filters.fusion_classifier.classifier_step` (every slot learning), and by a
host loop calling the jitted step once per frame (what a streaming tracker does). Times are
per frame after compilation, ``block_until_ready``, median and minimum of ``--repeats`` runs.

Accuracy (the classifier alone, no detections, no occlusion reasoning), from each start frame
of ``--accuracy-starts``: the start frame's ground-truth people present in every frame of the
next ``--frames`` frames are followed; reported: the distance between the tracked and the true
box centre (median and 90th percentile over people and frames, pixels) and the number of
people whose box still overlaps the truth by IoU >= 0.5 on the last frame.

Prints one JSON object on its last line (``ms_per_frame_scan`` is the headline number).
Usage: ``python benchmarks/fusion_classifier.py [--frames N] [--first F] [--repeats R]
[--accuracy-starts A,B,...]``.
"""

from __future__ import annotations

import argparse
import functools
import json
import platform
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.boxes import iou_matrix
from jaxtrack.filters.fusion_classifier import (
    CLASSIFIER_PATCH_SHAPE,
    classifier_params,
    classifier_step,
    init_classifier,
)
from jaxtrack.io import read_mot_file
from jaxtrack.io.video import VideoReader

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
VIDEO = DATA / "video" / "vtest.avi"
GROUND_TRUTH = DATA / "mot15" / "PETS09-S2L1" / "gt" / "gt.txt"
NUM_TARGETS = 16


def start_boxes(gt, frame: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``[16, 4]`` boxes (the frame's people, then random fillers) and the people's ids."""
    here = gt.frames == frame
    people, ids = gt.boxes[here][:NUM_TARGETS], gt.ids[here][:NUM_TARGETS]
    extra = NUM_TARGETS - len(people)
    size = rng.uniform([25, 60], [45, 110], (extra, 2))
    corner = rng.uniform(0, 1, (extra, 2)) * ([768, 576] - size)
    return np.concatenate([people, np.concatenate([corner, size], 1)]).astype(np.float32), ids


def follow_scan(state, video, params, update_mask):
    """The boxes and PSRs of :func:`classifier_step` scanned over ``video`` ``[T, H, W, 3]``."""

    def body(carry, frame):
        carry, response = classifier_step(carry, frame, params, update_mask)
        return carry, (carry.boxes, response.psr)

    return jax.lax.scan(body, state, video)[1]


def follow(gt, first: int, count: int, params, scan) -> tuple[list, int, np.ndarray]:
    """Follows frame ``first``'s people over ``count`` frames: centre errors, kept, PSRs."""
    with VideoReader(VIDEO) as reader:
        frames = np.stack([reader.read(first + t) for t in range(count + 1)])
    boxes, ids = start_boxes(gt, first, np.random.default_rng(0))
    alive = jnp.ones(NUM_TARGETS, bool)
    state = init_classifier(jnp.asarray(frames[0]), jnp.asarray(boxes), alive, params)
    tracked, psr = (np.asarray(v) for v in scan(state, jnp.asarray(frames[1:]), params))
    errors, kept = [], 0
    for slot, person in enumerate(ids):
        rows = [
            np.flatnonzero((gt.frames == first + 1 + t) & (gt.ids == person)) for t in range(count)
        ]
        if any(len(r) == 0 for r in rows):
            continue
        truth = gt.boxes[np.concatenate(rows)]
        centre = tracked[:, slot, :2] + tracked[:, slot, 2:] / 2
        errors.append(np.linalg.norm(centre - (truth[:, :2] + truth[:, 2:] / 2), axis=1))
        kept += int(iou_matrix(tracked[-1:, slot], truth[-1:])[0, 0] >= 0.5)
    return errors, kept, psr[:, : len(ids)].ravel()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=60, help="frames followed (default 60)")
    parser.add_argument("--first", type=int, default=1, help="1-based first frame (default 1)")
    parser.add_argument("--repeats", type=int, default=5, help="timed runs (default 5)")
    parser.add_argument(
        "--accuracy-starts",
        default="1,100,300,500",
        help="1-based start frames of the accuracy spans (default 1,100,300,500)",
    )
    args = parser.parse_args()

    gt = read_mot_file(GROUND_TRUTH, "gt")
    with VideoReader(VIDEO) as reader:
        frames = np.stack([reader.read(args.first + t) for t in range(args.frames + 1)])
    boxes, _ = start_boxes(gt, args.first, np.random.default_rng(0))
    params = classifier_params()  # the paper's PETS 2009 learning rate, 0.35
    alive, learn = jnp.ones(NUM_TARGETS, bool), jnp.ones(NUM_TARGETS, bool)
    state = init_classifier(jnp.asarray(frames[0]), jnp.asarray(boxes), alive, params)
    video = jnp.asarray(frames[1:])

    scan = jax.jit(functools.partial(follow_scan, update_mask=learn))
    step = jax.jit(classifier_step)
    start = time.perf_counter()
    jax.block_until_ready(scan(state, video, params))
    compile_s = time.perf_counter() - start
    step(state, video[0], params, learn)[0].boxes.block_until_ready()

    def host_loop():
        carry = state
        for t in range(args.frames):
            carry = step(carry, video[t], params, learn)[0]
        return carry.boxes.block_until_ready()

    scan_ms, loop_ms = [], []
    for _ in range(args.repeats):
        start = time.perf_counter()
        jax.block_until_ready(scan(state, video, params))
        scan_ms.append((time.perf_counter() - start) * 1e3 / args.frames)
        start = time.perf_counter()
        host_loop()
        loop_ms.append((time.perf_counter() - start) * 1e3 / args.frames)

    errors, kept, followed, psr = [], 0, 0, []
    for first in (int(v) for v in args.accuracy_starts.split(",")):
        span_errors, span_kept, span_psr = follow(gt, first, args.frames, params, scan)
        errors += span_errors
        kept += span_kept
        followed += len(span_errors)
        psr.append(span_psr)
    errors = np.concatenate(errors)
    print(
        json.dumps(
            {
                "ms_per_frame_scan": round(float(np.median(scan_ms)), 2),
                "ms_per_frame_scan_min": round(float(np.min(scan_ms)), 2),
                "ms_per_frame_host_loop": round(float(np.median(loop_ms)), 2),
                "compile_s": round(compile_s, 1),
                "targets": NUM_TARGETS,
                "patch_shape": list(CLASSIFIER_PATCH_SHAPE),
                "frames": args.frames,
                "first": args.first,
                "people_followed": followed,
                "centre_error_px_median": round(float(np.median(errors)), 1),
                "centre_error_px_p90": round(float(np.percentile(errors, 90)), 1),
                "kept_iou_0.5_last_frame": f"{kept}/{followed}",
                "psr_median_people": round(float(np.median(np.concatenate(psr))), 1),
                "accuracy_starts": args.accuracy_starts,
                "cpu": platform.processor() or platform.machine(),
            }
        )
    )


if __name__ == "__main__":
    main()
