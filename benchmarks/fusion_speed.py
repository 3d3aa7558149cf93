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
thread, :class:`~jaxtrack.io.video.VideoReader`) and ``step_ms_per_frame`` the jitted
:func:`~jaxtrack.filters.fusion.fusion_step` alone on frames already in memory (median over
``--step-frames`` frames from frame 201, each on the state the run reached there, one call a
frame, ``block_until_ready``): the two parts of ``track_s``, which overlap in the streamed
run. The ``stage_ms_*`` are stages of the step, each jitted alone on the same states and
frames: the detection member's Hungarian assignment (one of the step's two), the classifier
member (:func:`~jaxtrack.filters.fusion_classifier.classifier_step`), the predictor member
(:func:`~jaxtrack.filters.fusion_motion.predict_motion`) and the signatures (Fusion eq. 1)
of four boxes per slot (the three responses and the fused box). Compiled alone they do not
add up to the step (XLA fuses across stages; and the step also starts the classifiers of
new targets, re-identifies, reasons about occlusions and votes).

Prints one JSON object on its last line. The goal is ``frames_per_s >= 15`` on 2 CPU cores
(``taskset -c 0,1``); timings on a shared machine vary with its other load
(``load_average``). Usage: ``python benchmarks/fusion_speed.py [--frames N] [--repeats R]
[--step-frames F] [--no-stages]``.
"""

from __future__ import annotations

import functools
import json
import os

import jax
import jax.numpy as jnp
import numpy as np
from timing import timed, video_run_parser

from jaxtrack.association.assignment import gated_assignment
from jaxtrack.boxes import iou_matrix
from jaxtrack.context.motion_models import TRACKLET_LENGTH
from jaxtrack.filters.base import fit_detections
from jaxtrack.filters.fusion import (
    MEMBERS,
    SIGNATURE_MIN_ROWS,
    SIGNATURE_PATCH,
    SIGNATURE_STEP,
    feet,
)
from jaxtrack.filters.fusion_classifier import classifier_step
from jaxtrack.filters.fusion_motion import predict_motion
from jaxtrack.filters.fusion_profile import signatures
from jaxtrack.filters.fusion_tracker import FusionConfig
from jaxtrack.filters.fusion_voting import TARGET
from jaxtrack.filters.registry import build_tracker
from jaxtrack.io import load_sequence
from jaxtrack.io.video import VideoReader, open_sequence_frames
from jaxtrack.pipelines.frame_context import streamed_params
from jaxtrack.pipelines.stream import track_streamed
from jaxtrack.types import FrameInputs

#: First frame (1-based) of the step-alone timing: people in the scene, targets voted in.
STEP_FROM = 200


def main() -> None:
    parser = video_run_parser(__doc__.split("\n")[0])
    parser.add_argument("--step-frames", type=int, default=50, help="frames of the step timing")
    parser.add_argument("--no-stages", action="store_true", help="skip the stages' timings")
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
    """The jitted step alone and, unless ``--no-stages``, the members' stages alone (ms per
    frame, median over ``--step-frames`` frames from :data:`STEP_FROM`, on the states of the
    run up to each frame)."""
    first = max(min(STEP_FROM, seq.num_frames - args.step_frames), 0)
    count = min(args.step_frames, seq.num_frames - first)
    detections = fit_detections(seq.detections)
    key = jax.random.PRNGKey(0)
    filt, _ = build_tracker(FusionConfig(), seq.info)
    step = jax.jit(filt.step)
    state, states, inputs = filt.init(key, params), [], []
    for k in range(first + count):
        frame_inputs = FrameInputs(
            jax.tree.map(lambda x, k=k: x[k], detections), reader.read(k + 1)
        )
        if k >= first:
            states.append(state)
            inputs.append(frame_inputs)
        state = step(key, state, params, frame_inputs)[0]
    timings = {"step_ms_per_frame": (step, lambda k: (key, states[k], params, inputs[k]))}
    if not args.no_stages:
        timings.update(stage_timings(params, states, inputs))
    result = {"step_from_frame": first + 1, "step_frames": count}
    for name, (function, arguments) in timings.items():
        jax.block_until_ready(function(*arguments(0)))  # compiles
        times = []
        for k in range(count):
            call = functools.partial(function, *arguments(k))
            times.append(timed(lambda call=call: jax.block_until_ready(call()))[0])
        result[name] = round(1e3 * float(np.median(times)), 2)
    return result


def stage_timings(params, states, inputs) -> dict:
    """The pool members' stages and the responses' signatures, each jitted alone."""

    def assignment(state, frame_inputs):  # the detection member's Hungarian assignment
        detections = frame_inputs.detections
        iou = iou_matrix(state.boxes, detections.boxes, xp=jnp)
        allowed = target(state)[:, None] & detections.mask[None, :] & (iou >= params.gate)
        return gated_assignment(1.0 - iou, allowed)

    def classifier(state, frame_inputs):
        filters = state.classifier._replace(boxes=state.boxes, alive=target(state))
        return classifier_step(filters, frame_inputs.frame, params.classifier, target(state))

    def predictor(state, frame_inputs):
        del frame_inputs
        tracklets = feet(state.history[:, -TRACKLET_LENGTH:])
        return predict_motion(params.motion, tracklets, target(state))

    def responses(state, frame_inputs):  # four boxes per slot: three members and the fused
        boxes = jnp.tile(state.boxes, (len(MEMBERS) + 1, 1))
        return signatures(
            frame_inputs.frame, boxes, SIGNATURE_PATCH, SIGNATURE_STEP, SIGNATURE_MIN_ROWS
        )

    stages = {
        "assignment": assignment,
        "classifier": classifier,
        "predictor": predictor,
        "signatures_4_per_slot": responses,
    }
    return {
        f"stage_ms_{name}": (jax.jit(stage), lambda k: (states[k], inputs[k]))
        for name, stage in stages.items()
    }


def target(state) -> jax.Array:
    """The slots holding targets."""
    return state.voting.status == TARGET


if __name__ == "__main__":
    main()
