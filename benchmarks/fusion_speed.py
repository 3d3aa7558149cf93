"""The Fusion tracker end to end on PETS09-S2L1 (768x576, ``vtest.avi``, MOT15 detections).

What ``jaxtrack track PETS09-S2L1 --video vtest.avi --tracker fusion`` does after loading the
sequence, timed in its parts, with the default
:class:`~jaxtrack.filters.fusion_tracker.FusionConfig` (the three-member pool
``detection,classifier,predictor``, the proposed fusion, 32 slots):

* ``context_s``: learning the context on the training span (the first half of the frames:
  zones and activity mask, the local GP motion models, the voting thresholds per region;
  :func:`~jaxtrack.pipelines.frame_context.streamed_params`);
* ``track_s``: the streamed run over every frame, decoding included (the next chunk decoded
  in a background thread while the current one runs), the offline output rows included
  (:func:`~jaxtrack.pipelines.stream.track_streamed`); the best of ``--repeats`` runs after a
  first one that compiles (``track_first_s``; ``compile_s`` = ``track_first_s - track_s``).

``frames_per_s`` = frames / (context_s + track_s): the end-to-end rate after compilation;
``frames_per_s_with_compile`` counts the compiling run instead; ``track_frames_per_s`` is
the streamed run alone. ``decode_ms_per_frame`` is the decoding of every frame alone (one
thread, :class:`~jaxtrack.io.video.VideoReader`) and ``step_ms_per_frame`` the jitted step
alone on frames already in memory (``--step-frames`` frames from frame 200, the state of a
run up to there, one call per frame, ``block_until_ready``): the two parts of ``track_s``,
which overlap in the streamed run. ``pool_step_ms_per_frame`` gives the step with each pool
of one member (the rest of the step, voting, signatures and occlusion, is in all of them):
the members' share of the step.

Prints one JSON object on its last line. The goal is ``frames_per_s >= 15`` on 2 CPU cores
(``taskset -c 0,1``); timings on a shared machine vary with its other load
(``load_average``). Usage: ``python benchmarks/fusion_speed.py [--frames N] [--repeats R]
[--step-frames F] [--no-pools]``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import jax
import numpy as np
from timing import timed

from jaxtrack.filters.base import fit_detections
from jaxtrack.filters.fusion import MEMBERS
from jaxtrack.filters.fusion_tracker import FusionConfig
from jaxtrack.filters.registry import build_tracker
from jaxtrack.io import load_sequence
from jaxtrack.io.video import VideoReader, open_sequence_frames
from jaxtrack.pipelines.frame_context import streamed_params
from jaxtrack.pipelines.stream import track_streamed
from jaxtrack.types import FrameInputs

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
#: First frame (1-based) of the step-alone timing: people in the scene, targets voted in.
STEP_FROM = 200


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sequence", type=Path, default=DATA / "mot15" / "PETS09-S2L1")
    parser.add_argument("--video", type=Path, default=DATA / "video" / "vtest.avi")
    parser.add_argument("--frames", type=int, default=0, help="frames tracked (0: all)")
    parser.add_argument("--repeats", type=int, default=2, help="timed runs after the first")
    parser.add_argument("--step-frames", type=int, default=50, help="frames of the step timing")
    parser.add_argument("--no-pools", action="store_true", help="skip the one-member pools")
    args = parser.parse_args()

    config = FusionConfig()
    seq = load_sequence(args.sequence, None if args.frames == 0 else (1, args.frames))
    with open_sequence_frames(args.sequence, seq.info, args.video) as reader:
        context_s, (params, used) = timed(lambda: streamed_params(config, seq, reader))

        def track():
            return track_streamed(seq, reader, config, 0, params)

        first_s, rows = timed(track)
        track_s = min(timed(track)[0] for _ in range(args.repeats))
        decode_s, _ = timed(lambda: [reader.read(k) for k in range(1, seq.num_frames + 1)])
        steps = step_timing(args, seq, reader, params)
    frames = seq.num_frames
    result = {
        "benchmark": "fusion_speed",
        "video": str(args.video),
        "frames": frames,
        "image_size": [seq.info.im_width, seq.info.im_height],
        "pool": config.pool,
        "fusion": config.fusion,
        "slots": config.max_targets,
        "training": used["training"],
        "result_rows": len(rows.frames),
        "context_s": round(context_s, 2),
        "track_first_s": round(first_s, 2),
        "track_s": round(track_s, 2),
        "compile_s": round(first_s - track_s, 2),
        "track_frames_per_s": round(frames / track_s, 1),
        "decode_ms_per_frame": round(1e3 * decode_s / frames, 2),
        **steps,
        "frames_per_s_with_compile": round(frames / (context_s + first_s), 1),
        "goal_frames_per_s": 15,
        "cpu_affinity": len(os.sched_getaffinity(0)),
        "load_average": [round(x, 2) for x in os.getloadavg()],
        "devices": [str(d) for d in jax.devices()],
        "frames_per_s": round(frames / (context_s + track_s), 1),
    }
    print(json.dumps(result))


def step_timing(args, seq, reader: VideoReader, params) -> dict:
    """The jitted step alone (ms per frame, median over ``--step-frames`` frames, the state
    carried) for the default pool and, unless ``--no-pools``, each pool of one member, all
    from the state of the default pool's steps up to frame :data:`STEP_FROM`."""
    first = max(min(STEP_FROM, seq.num_frames - args.step_frames), 0)
    count = min(args.step_frames, seq.num_frames - first)
    detections = fit_detections(seq.detections)
    key = jax.random.PRNGKey(0)

    def inputs(k):  # frame k + 1 (k from 0)
        return FrameInputs(jax.tree.map(lambda x: x[k], detections), reader.read(k + 1))

    config = FusionConfig()
    pools = [config.pool] if args.no_pools else [config.pool, *MEMBERS]
    steps = {pool: jax.jit(build_tracker(FusionConfig(pool=pool), seq.info)[0].step) for pool in pools}
    state = build_tracker(config, seq.info)[0].init(key, params)
    for k in range(first):
        state = steps[config.pool](key, state, params, inputs(k))[0]
    timed_inputs = [inputs(first + k) for k in range(count)]
    result = {"step_from_frame": first + 1, "step_frames": count}
    for pool, step in steps.items():
        carry = state
        jax.block_until_ready(step(key, carry, params, timed_inputs[0]))  # compiles
        times = []
        for frame_inputs in timed_inputs:
            start = time.perf_counter()
            carry = jax.block_until_ready(step(key, carry, params, frame_inputs))[0]
            times.append(time.perf_counter() - start)
        name = "step_ms_per_frame" if pool == config.pool else f"step_ms_per_frame_{pool}"
        result[name] = round(1e3 * float(np.median(times)), 2)
    return result

if __name__ == "__main__":
    main()
