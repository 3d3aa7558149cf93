"""``jaxtrack tune``: tune the PHD tracker's parameters by gradient descent (optax adam)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from jaxtrack.commands.arguments import (
    BIRTHS_PER_DETECTION,
    KEYS,
    LEARNING_RATE,
    PARTICLES,
    PATIENCE,
    STEPS,
    add_config,
    add_frames,
    add_json,
    add_out,
    add_quiet,
    add_seed,
    load_config,
    ranged,
)
from jaxtrack.commands.paths import (
    check_outputs,
    file_input,
    output_file,
    sequence_inputs,
    side_file,
)
from jaxtrack.errors import InputError
from jaxtrack.filters.phd_tracker import TUNABLE
from jaxtrack.io import load_sequence
from jaxtrack.pipelines.tuning import (
    CONFIG_TRAINABLE,
    TUNING_BIRTHS_PER_DETECTION,
    TUNING_PARTICLES,
    tune_sequence,
)
from jaxtrack.tuning.objectives import ESTIMATORS

DESCRIPTION = """\
Tune the particle PHD tracker's parameters on a span (--frames A:B) of a MOTChallenge
sequence by gradient descent through the filter (jaxtrack.tuning), and write a tracker
configuration that `jaxtrack track --config` uses directly.

Objectives:
  likelihood   minus the PHD measurement log-likelihood per frame (SPEC section 1); needs
               no ground truth
  supervised   a relaxed GOSPA between the PHD and the ground-truth boxes plus a
               cardinality term (needs gt/gt.txt)

Parameters are optimised in an unconstrained space (log for rates and noise scales, logit
for probabilities), adam with the loss averaged over --keys fixed PRNG keys (common random
numbers); the result averages the last iterates. By default the clutter and birth rates are
tuned. --tune can add initial_rate, detection_prob, survival_prob, motion_noise_std,
measurement_noise_std; every tuned value goes into the configuration written. birth_rate is
lambda_s (births per frame after the first frame), never the first frame's initial_rate.

Starts from --config (a tracker configuration) or the defaults. Writes OUT (the
configuration: the --config values plus the tuned ones, as the keys that differ from the
defaults) and OUT.tuning.json beside it (start and tuned values, loss history, settings);
--json prints that report as one JSON object."""

EPILOG = """\
examples:
  jaxtrack tune ../shared/data/mot15/PETS09-S2L1 --frames 1:400 --objective likelihood \\
      --out /tmp/tuned.json
  jaxtrack track ../shared/data/mot15/PETS09-S2L1 --frames 401:795 --config /tmp/tuned.json \\
      --out /tmp/t.txt
  jaxtrack tune SEQ --objective supervised --tune clutter_rate,birth_rate --steps 40 \\
      --out tuned.json"""


def register(subparsers) -> None:
    """Adds the ``tune`` parser to the CLI's sub-parsers."""

    parser = subparsers.add_parser(
        "tune",
        help="tune the PHD tracker's parameters by gradient descent; writes a --config JSON",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("sequence", metavar="SEQ_DIR", help="MOTChallenge sequence folder")
    add_out(parser, "tracker configuration to write", metavar="OUT.json")
    add_frames(parser)
    parser.add_argument(
        "--objective",
        choices=("likelihood", "supervised"),
        default="likelihood",
        help="what to minimise (default likelihood)",
    )
    add_config(parser)
    parser.add_argument(
        "--tune",
        default=",".join(CONFIG_TRAINABLE),
        metavar="NAMES",
        help=f"comma-separated parameters to tune, of {', '.join(TUNABLE)} "
        f"(default {','.join(CONFIG_TRAINABLE)})",
    )
    parser.add_argument(
        "--steps", type=ranged(STEPS), default=60, help="most adam steps (default 60)"
    )
    parser.add_argument(
        "--keys", type=ranged(KEYS), default=2, help="PRNG keys per step (default 2)"
    )
    parser.add_argument(
        "--learning-rate",
        type=ranged(LEARNING_RATE),
        default=0.1,
        help="adam learning rate (default 0.1)",
    )
    parser.add_argument(
        "--patience",
        type=ranged(PATIENCE),
        default=20,
        help="stop after this many steps without improvement (0: never; default 20)",
    )
    parser.add_argument(
        "--particles",
        type=ranged(PARTICLES),
        default=TUNING_PARTICLES,
        help=f"particles of the tuning filter (default {TUNING_PARTICLES})",
    )
    parser.add_argument(
        "--births-per-detection",
        type=ranged(BIRTHS_PER_DETECTION),
        default=TUNING_BIRTHS_PER_DETECTION,
        help=f"birth particles per detection while tuning (default {TUNING_BIRTHS_PER_DETECTION})",
    )
    parser.add_argument(
        "--estimator",
        choices=ESTIMATORS,
        default="stop_gradient",
        help="resampling gradient estimator (default stop_gradient)",
    )
    add_seed(parser)
    add_quiet(parser)
    add_json(parser)
    parser.set_defaults(func=run)


def run(args) -> int:

    out = Path(args.out)
    if out.suffix != ".json":
        raise InputError(f"--out must be a .json file, got {out}")
    check_outputs(
        [output_file("--out", args.out), side_file("--out", args.out, ".tuning.json")],
        [
            *sequence_inputs(args.sequence),
            *file_input(args.config, f"the tracker configuration --config {args.config}"),
        ],
    )
    base = load_config(args.config)
    names = [name.strip() for name in args.tune.split(",") if name.strip()]
    sequence = load_sequence(args.sequence, frames=args.frames)
    tuning = tune_sequence(
        sequence,
        args.objective,
        base,
        names,
        seed=args.seed,
        num_steps=args.steps,
        num_keys=args.keys,
        learning_rate=args.learning_rate,
        patience=args.patience,
        num_particles=args.particles,
        births_per_detection=args.births_per_detection,
        estimator=args.estimator,
        progress=not args.quiet,
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(tuning.config.overrides(), indent=2) + "\n")
    report_path = out.with_suffix(".tuning.json")
    report_path.write_text(json.dumps(tuning.report, indent=2) + "\n")
    report = tuning.report
    if args.json:
        print(json.dumps({"out": str(out), "report_file": str(report_path), **report}))
        return 0
    changes = ", ".join(
        f"{name} {_show(report['start'][name])} -> {_show(report['tuned'][name])}"
        for name in report["tuned"]
    )
    print(
        f"wrote {out} and {report_path} ({report['steps']} steps, {report['stop_reason']}, "
        f"{report['seconds']:.1f} s): {changes}"
    )
    return 0


def _show(value) -> str:
    if isinstance(value, list):
        return "[" + ", ".join(f"{v:.4g}" for v in value) + "]"
    return f"{value:.4g}"
