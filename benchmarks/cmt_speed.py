"""CMT's speed on PETS09-S2L1 (768x576, ``vtest.avi``): a tracking run and a 64-configuration
sweep.

* ``frames_per_s``: what ``jaxtrack track PETS09-S2L1 --video vtest.avi --tracker cmt`` does
  after loading and zone learning: :func:`jaxtrack.pipelines.stream.track_streamed` over all
  795 frames with the default :class:`~jaxtrack.filters.cmt_tracker.CMTConfig` (16
  components x 40 particles, ``--variant cmt``), decoding and appearance features included,
  the offline output rows included. The first run compiles; ``frames_per_s`` is the best of
  ``--repeats`` runs after it, ``first_run_s`` the compiling run and ``compile_s`` their
  difference.
* ``sweep_64_seconds``: 64 CMT configurations (a grid over the SDV motion-noise scale and
  the appearance weight) over ``--sweep-frames`` frames of PETS09-S2L1 in one call of
  ``jit(vmap(run))`` (:func:`jaxtrack.filters.base.run` unchunked on
  :class:`~jaxtrack.types.FrameInputs`, the frames shared by every configuration, the
  detections at the capacity ``jaxtrack track`` gives the sequence), after a call that
  compiles (``sweep_compile_s``). :func:`jaxtrack.pipelines.sweep.sweep` is not used: it
  takes detections only (no frames), so it cannot run a tracker that looks at the images.

Prints one JSON object on its last line. The goal is ``frames_per_s >= 25`` on 2 CPU cores
(``taskset -c 0,1``); timings on a shared machine vary with its other load
(``load_average``).
"""

from __future__ import annotations

import json
import os

import jax
import jax.numpy as jnp
import numpy as np
from timing import timed, video_run_parser

from jaxtrack.filters.base import fit_detections, run
from jaxtrack.filters.cmt_tracker import CMTConfig
from jaxtrack.filters.registry import build_tracker
from jaxtrack.io import load_sequence
from jaxtrack.io.video import VideoReader, open_sequence_frames
from jaxtrack.pipelines.stream import track_streamed
from jaxtrack.pipelines.sweep import batch_params
from jaxtrack.pipelines.tracking import track_outputs
from jaxtrack.pipelines.zones import tracker_zones
from jaxtrack.types import FrameInputs

SWEEP_SIZE = (8, 8)


def main() -> None:
    parser = video_run_parser(__doc__.split("\n")[0])
    parser.add_argument("--sweep-frames", type=int, default=32, help="frames of the sweep")
    parser.add_argument("--no-sweep", action="store_true", help="skip the sweep")
    args = parser.parse_args()

    config = CMTConfig()
    span = None if args.frames == 0 else (1, args.frames)
    seq = load_sequence(args.sequence, span)
    zones, zone_note = tracker_zones(seq, None, 0)
    _, params = build_tracker(config, seq.info, zones)

    def track():
        with open_sequence_frames(args.sequence, seq.info, args.video) as reader:
            return track_streamed(seq, reader, config, 0, params)

    first_run, rows = timed(track)
    runs = [timed(track)[0] for _ in range(args.repeats)]
    best = min(runs)
    result = {
        "benchmark": "cmt_speed",
        "frames": seq.num_frames,
        "image_size": [seq.info.im_width, seq.info.im_height],
        "components": config.max_components,
        "particles_per_component": config.particles_per_component,
        "variant": config.variant,
        "zones": zone_note,
        "frames_per_s": round(seq.num_frames / best, 2),
        "run_s": [round(r, 2) for r in runs],
        "first_run_s": round(first_run, 2),
        "compile_s": round(first_run - best, 2),
        "result_rows": len(rows),
        "goal_frames_per_s": 25,
        "goal_met": seq.num_frames / best >= 25,
    }
    if not args.no_sweep:
        result.update(sweep_timing(args, config, params, seq))
    result["cpu_count"] = os.cpu_count()
    result["cpu_affinity"] = len(os.sched_getaffinity(0))
    result["load_average"] = [round(x, 2) for x in os.getloadavg()]
    result["devices"] = [str(d) for d in jax.devices()]
    print(json.dumps(result))


def sweep_timing(args, config: CMTConfig, params, seq) -> dict:
    """64 configurations of CMT over the first ``--sweep-frames`` frames in one vmapped call."""
    count = min(args.sweep_frames, seq.num_frames)
    filt, _ = build_tracker(config, seq.info)
    detections = jax.tree.map(lambda x: x[:count], fit_detections(seq.detections))
    with VideoReader(args.video) as reader:
        frames = np.stack([reader.read(k + 1) for k in range(count)])
    inputs = FrameInputs(detections, frames)
    scales = np.geomspace(0.5, 2.0, SWEEP_SIZE[0])
    weights = np.linspace(0.0, 2.0, SWEEP_SIZE[1])
    grid_scale, grid_weight = (g.ravel() for g in np.meshgrid(scales, weights, indexing="ij"))
    batched = batch_params(
        params,
        {
            "motion_noise_std": np.asarray(params.mixture.motion_noise_std)[None]
            * grid_scale[:, None],
            "appearance_weight": grid_weight,
        },
    )

    @jax.jit
    def sweep(batched_params, inputs):
        def one(p):
            return run(filt, jax.random.PRNGKey(0), p, inputs, frame_output=track_outputs)[1]

        return jax.vmap(one)(batched_params)

    compile_s, _ = timed(lambda: jax.block_until_ready(sweep(batched, inputs)))
    run_s, outputs = timed(lambda: jax.block_until_ready(sweep(batched, inputs)))
    tracked = np.asarray(jnp.sum(outputs.tracks.mask, axis=(1, 2)))
    return {
        "sweep_configurations": int(grid_scale.size),
        "sweep_frames": count,
        "sweep_64_seconds": round(run_s, 2),
        "sweep_compile_s": round(compile_s - run_s, 2),
        "sweep_frames_per_s_per_configuration": round(count * grid_scale.size / run_s, 2),
        "sweep_boxes_min_max": [int(tracked.min()), int(tracked.max())],
    }


if __name__ == "__main__":
    main()
