"""Appearance re-association (Hierarchical Sec. 5.4) on ground-truth boxes, no tracker.

A trial: the people seen at every frame of a window (synthetic scenes: visibility >= 0.9) are
learnt by slots ``0 .. S-1`` over ``--learn`` frames (:func:`update_appearance` with the
scene's background image), then all lost; ``--gap`` frames later the same people are learnt
by new slots ``S .. 2S-1`` over 3 frames, and :func:`association_distances` /
:func:`reassociate` match the lost slots to the new ones (candidates: their mean histograms
and pools). A trial every 100 frames. Counted per lost person: ``right`` (matched to its own
new slot), ``wrong`` (to another person's), ``unmatched`` (no gated candidate; the tracker
retries at the next frame). For comparison, ``nearest_all_features_right``: the people whose
own new slot is nearest in the mean Bhattacharyya distance over all 49 features, pools and
gate ignored.

Data: the synthetic video scenes of seeds 0-2 (the development seeds; background image = the
scene's static canvas) and PETS09-S2L1 (held out: measured, never tuned on; background = the
per-pixel median of 20 frames). Default parameters
(:func:`~jaxtrack.filters.hier_appearance.default_params`).

Prints one JSON object on its last line. Usage:
``python benchmarks/hier_reassociation.py [--gap 60] [--learn 20]``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.appearance import bhattacharyya_distance
from jaxtrack.datasets.render import build_canvas, render_frame
from jaxtrack.datasets.video_scene import generate_video_scene
from jaxtrack.filters.hier_appearance import (
    box_histograms,
    default_params,
    init_table,
    update_appearance,
)
from jaxtrack.filters.hier_reassociation import association_distances, reassociate
from jaxtrack.io import read_mot_file
from jaxtrack.io.video import VideoReader

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
VIDEO = DATA / "video" / "vtest.avi"
GROUND_TRUTH = DATA / "mot15" / "PETS09-S2L1" / "gt" / "gt.txt"
SEEDS = (0, 1, 2)
CANDIDATE_FRAMES = 3
_histograms = jax.jit(box_histograms)
_update = jax.jit(update_appearance)
_distances = jax.jit(association_distances)
_reassociate = jax.jit(reassociate)


def trial(read_frame, background, boxes_of, frames_a, frames_b):
    """Counts ``[right, wrong, unmatched, nearest_all_features_right]`` of one trial."""
    params = default_params()
    size = boxes_of(frames_a[0]).shape[0]
    table = init_table(2 * size)
    for frames, offset in ((frames_a, 0), (frames_b, size)):
        update = jnp.zeros(2 * size, bool).at[offset : offset + size].set(True)
        for frame in frames:
            boxes = jnp.asarray(boxes_of(frame))
            target = jnp.zeros(table.models.histogram.shape).at[offset : offset + size]
            behind = jnp.zeros(table.models.histogram.shape).at[offset : offset + size]
            table = _update(
                table,
                target.set(_histograms(jnp.asarray(read_frame(frame)), boxes)),
                behind.set(_histograms(background, boxes)),
                update,
                params,
            )
    lost = jnp.arange(2 * size) < size
    distance, gated = _distances(table, lost, table.models.histogram, table.features, ~lost, params)
    match = np.asarray(_reassociate(distance, gated))[:size]
    own = np.arange(size) + size
    hist = table.models.histogram
    all_features = np.asarray(bhattacharyya_distance(hist[:size, None], hist[None, size:]))
    nearest = np.argmin(all_features.mean(-1), axis=1) == np.arange(size)
    right, wrong = np.sum(match == own), np.sum((match >= 0) & (match != own))
    return np.array([right, wrong, size - right - wrong, np.sum(nearest)])


def run_trials(gt, read_frame, background, visible, num_frames, learn, gap):
    """Sums the counts of the trials every 100 frames with at least two people."""
    totals = np.zeros(4, int)
    for start in range(1, num_frames - learn - gap - CANDIDATE_FRAMES + 1, 100):
        frames_a = range(start, start + learn)
        frames_b = range(start + learn + gap, start + learn + gap + CANDIDATE_FRAMES)
        ids = sorted(set.intersection(*(visible(f) for f in (*frames_a, *frames_b))))
        if len(ids) < 2:
            continue

        def boxes_of(frame, ids=ids):
            rows = gt.frames == frame
            return np.stack([gt.boxes[rows & (gt.ids == i)][0] for i in ids]).astype(np.float32)

        totals += trial(read_frame, background, boxes_of, frames_a, frames_b)
    return totals


def as_json(totals):
    names = ("right", "wrong", "unmatched", "nearest_all_features_right")
    return {"people": int(totals[:3].sum()), **dict(zip(names, map(int, totals), strict=True))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--gap", type=int, default=60, help="frames between loss and re-birth")
    parser.add_argument("--learn", type=int, default=20, help="frames learnt before the loss")
    args = parser.parse_args()
    synthetic = np.zeros(4, int)
    for seed in SEEDS:
        scene = generate_video_scene(seed)
        canvas = build_canvas(scene)
        gt = scene.gt_table

        def visible(frame, gt=gt):
            return set(gt.ids[(gt.frames == frame) & (gt.extra[:, -1] >= 0.9)])

        def read_frame(frame, scene=scene, canvas=canvas):
            return render_frame(scene, canvas, frame)

        synthetic += run_trials(
            gt,
            read_frame,
            jnp.asarray(canvas.background),
            visible,
            int(gt.frames.max()),
            args.learn,
            args.gap,
        )
    gt = read_mot_file(GROUND_TRUTH, kind="gt")
    with VideoReader(VIDEO) as reader:
        samples = np.stack([reader.read(1 + 40 * t) for t in range(20)])
        background = jnp.asarray(np.median(samples, axis=0).astype(np.uint8))
        pets = run_trials(
            gt,
            reader.read,
            background,
            lambda frame: set(gt.ids[gt.frames == frame]),
            int(gt.frames.max()),
            args.learn,
            args.gap,
        )
    print(
        json.dumps(
            {
                "gap": args.gap,
                "learn": args.learn,
                "synthetic_seeds_0_2": as_json(synthetic),
                "pets09_s2l1": as_json(pets),
            }
        )
    )


if __name__ == "__main__":
    main()
