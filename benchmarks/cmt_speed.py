"""CMT's speed on PETS09-S2L1 (768x576, ``vtest.avi``): a tracking run and a 64-configuration
sweep.

* ``frames_per_s``: what ``jaxtrack track PETS09-S2L1 --video vtest.avi --tracker cmt`` does
  after loading and zone learning: :func:`jaxtrack.pipelines.stream.track_streamed` over all
  795 frames with the default :class:`~jaxtrack.filters.cmt_tracker.CMTConfig` at the
  goal's size, 16 components x 40 particles (``--components``; ``--variant cmt``), decoding
  and appearance features included, the offline output rows included. The first run
  compiles; ``frames_per_s`` is the best of ``--repeats`` runs after it, ``first_run_s`` the
  compiling run and ``compile_s`` their difference. ``default_frames_per_s``: the same with
  the default configuration's own table (32 components since session 46), when it differs.
* ``sweep_64_seconds``: 64 CMT configurations (a grid of 8 SDV motion-noise scales x 8
  appearance weights, :func:`sweep_grid`) over PETS09-S2L1 (``--sweep-frames``, default
  all 795) with :func:`jaxtrack.pipelines.sweep.sweep_frames`: the video decoded once, all 64
  configurations in one vmapped call per chunk of 32 frames (``--sweep-group``), every
  configuration scored (MOTA, IDF1, ...); compile, decoding and scoring included. Each
  configuration gives what ``jaxtrack track --tracker cmt`` gives with it (same key, zones,
  chunks). ``sweep_loop_s_per_configuration`` is ``run_s`` (one configuration tracked alone,
  decoding included) for comparison.

Prints one JSON object on its last line. The goal is ``frames_per_s >= 25`` on 2 CPU cores
(``taskset -c 0,1``); timings on a shared machine vary with its other load
(``load_average``).
"""

from __future__ import annotations

import json
import os

import jax
import numpy as np
from timing import timed, video_run_parser

from jaxtrack.filters.cmt_tracker import CMTConfig
from jaxtrack.filters.registry import build_tracker
from jaxtrack.io import load_sequence
from jaxtrack.io.video import open_sequence_frames
from jaxtrack.pipelines.stream import track_streamed
from jaxtrack.pipelines.sweep import sweep_frames
from jaxtrack.pipelines.zones import tracker_zones

SWEEP_SIZE = (8, 8)
#: Component slots of the issue's speed goal (16 x 40 particles).
GOAL_COMPONENTS = 16


def main() -> None:
    parser = video_run_parser(__doc__.split("\n")[0])
    parser.add_argument(
        "--sweep-frames", type=int, default=0, help="frames of the sweep (default 0: all)"
    )
    parser.add_argument(
        "--sweep-group", type=int, default=64, help="configurations per vmapped call (default 64)"
    )
    parser.add_argument("--no-sweep", action="store_true", help="skip the sweep")
    parser.add_argument(
        "--components",
        type=int,
        default=GOAL_COMPONENTS,
        help=f"component slots of the timed runs and the sweep (default {GOAL_COMPONENTS}, "
        "the issue's goal)",
    )
    args = parser.parse_args()

    config = CMTConfig(max_components=args.components)
    span = None if args.frames == 0 else (1, args.frames)
    seq = load_sequence(args.sequence, span)
    zones, zone_note = tracker_zones(seq, None, 0)

    def timed_runs(config: CMTConfig):
        """(compiling run's seconds, best later run's seconds, the later runs' seconds, the
        result rows, the parameters tracked with)."""
        _, params = build_tracker(config, seq.info, zones)

        def track():
            with open_sequence_frames(args.sequence, seq.info, args.video) as reader:
                return track_streamed(seq, reader, config, 0, params)

        first_run, rows = timed(track)
        runs = [timed(track)[0] for _ in range(args.repeats)]
        return first_run, min(runs), runs, rows, params

    first_run, best, runs, rows, params = timed_runs(config)
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
    default = CMTConfig()
    if default.max_components != config.max_components:
        default_best = timed_runs(default)[1]
        result["default_components"] = default.max_components
        result["default_frames_per_s"] = round(seq.num_frames / default_best, 2)
    if not args.no_sweep:
        result.update(sweep_timing(args, config, params, seq, best))
    result["cpu_count"] = os.cpu_count()
    result["cpu_affinity"] = len(os.sched_getaffinity(0))
    result["load_average"] = [round(x, 2) for x in os.getloadavg()]
    result["devices"] = [str(d) for d in jax.devices()]
    print(json.dumps(result))


def sweep_grid(default_weight: float) -> tuple[np.ndarray, np.ndarray]:
    """The 8 motion-noise scales (``2^(k/3)``, 0.5-2.5) and 8 appearance weights (0-1.75
    times ``default_weight`` in steps of a quarter of it) of the sweep: both contain the
    defaults (scale 1, the default weight)."""
    scales = 2.0 ** ((np.arange(SWEEP_SIZE[0]) - 3) / 3)
    weights = default_weight * np.arange(SWEEP_SIZE[1]) / 4
    return scales, weights


def sweep_timing(args, config: CMTConfig, params, seq, track_s: float) -> dict:
    """64 configurations of CMT over the first ``--sweep-frames`` frames, scored."""
    count = seq.num_frames if args.sweep_frames == 0 else min(args.sweep_frames, seq.num_frames)
    span = load_sequence(args.sequence, (1, count))
    scales, weights = sweep_grid(config.appearance_weight)
    grid_scale, grid_weight = (g.ravel() for g in np.meshgrid(scales, weights, indexing="ij"))
    updates = {
        "motion_noise_std": np.asarray(params.mixture.motion_noise_std)[None] * grid_scale[:, None],
        "appearance_weight": grid_weight,
    }
    with open_sequence_frames(args.sequence, span.info, args.video) as reader:
        run_s, result = timed(
            lambda: sweep_frames(
                span,
                reader,
                config,
                updates,
                params=params,
                chunk_size=args.sweep_group,
                progress=True,
            )
        )
    idf1 = result.scores["IDF1"]
    best = int(np.argmax(idf1))
    at_default = (grid_scale == 1) & (grid_weight == config.appearance_weight)
    return {
        "sweep_configurations": int(grid_scale.size),
        "sweep_frames": count,
        "sweep_group": args.sweep_group,
        "sweep_64_seconds": round(run_s, 2),
        "sweep_frames_per_s_per_configuration": round(count * grid_scale.size / run_s, 2),
        "sweep_loop_s_per_configuration": round(track_s * count / seq.num_frames, 2),
        "sweep_idf1_min_max_pct": [
            round(100 * float(idf1.min()), 1),
            round(100 * float(idf1.max()), 1),
        ],
        "sweep_best_idf1": {
            "IDF1_pct": round(100 * float(idf1[best]), 1),
            "motion_noise_scale": round(float(grid_scale[best]), 3),
            "appearance_weight": round(float(grid_weight[best]), 3),
        },
        "sweep_default_idf1_pct": round(100 * float(idf1[np.flatnonzero(at_default)[0]]), 1),
    }


if __name__ == "__main__":
    main()
