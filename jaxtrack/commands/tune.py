"""``jaxtrack tune``: tune the PHD tracker's parameters, or a learned context, by gradient
descent (optax adam)."""

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
    add_context_arguments,
    add_frames,
    add_json,
    add_out,
    add_quiet,
    add_seed,
    context_variant,
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
from jaxtrack.context.io import save_context
from jaxtrack.errors import InputError
from jaxtrack.filters.phd_tracker import TUNABLE, UNIFORM_SHARES
from jaxtrack.io import load_sequence
from jaxtrack.pipelines.tracking import load_tracker_context
from jaxtrack.pipelines.tuning import (
    CONFIG_TRAINABLE,
    CONTEXT_TRAINABLE,
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
--json prints that report as one JSON object.

Tuning a learned context (--context CTX.npz from jaxtrack learn-context, --variant GM by
default): the tracker starts from the context's intensities in that variant and, by
default, tunes the magnitudes and the uniform shares pi_u of the parts the variant takes
from the context (clutter_rate, birth_rate, birth_uniform_share, clutter_uniform_share; A1
tunes the birth part only, a share only where the density has learned Gaussians). OUT must
then be an .npz: the tuned context (the learned densities with the tuned magnitudes and
shares; its metadata records the events per frame, the start and tuned values, the span and
the objective), which `jaxtrack track --context OUT.npz --variant V` uses directly. Beside
it OUT.config.json (the --config values plus any tuned configuration key, e.g.
detection_prob) and OUT.tuning.json. A learned part's birth_rate / clutter_rate is its
intensity's magnitude lambda / P(V) (P(V): the density's mass inside the image, about 1).
The uniform shares are tunable only with a learned context: a uniform intensity has pi_u = 1
and nothing to share with."""

EPILOG = """\
examples:
  jaxtrack tune ../shared/data/mot15/PETS09-S2L1 --frames 1:400 --objective likelihood \\
      --out /tmp/tuned.json
  jaxtrack track ../shared/data/mot15/PETS09-S2L1 --frames 401:795 --config /tmp/tuned.json \\
      --out /tmp/t.txt
  jaxtrack tune SEQ --objective supervised --tune clutter_rate,birth_rate --steps 40 \\
      --out tuned.json
  jaxtrack learn-context SEQ --frames 1:300 --out ctx.npz
  jaxtrack tune SEQ --frames 1:300 --context ctx.npz --out tuned.npz
  jaxtrack track SEQ --frames 301:600 --context tuned.npz --config tuned.config.json \\
      --out t.txt"""


def register(subparsers) -> None:
    """Adds the ``tune`` parser to the CLI's sub-parsers."""

    parser = subparsers.add_parser(
        "tune",
        help="tune the PHD tracker's parameters (or a learned context) by gradient descent; "
        "writes a --config JSON (or the tuned context)",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("sequence", metavar="SEQ_DIR", help="MOTChallenge sequence folder")
    add_out(
        parser,
        "tracker configuration to write (.json); with --context, the tuned context (.npz)",
        metavar="OUT.json|OUT.npz",
    )
    add_frames(parser)
    parser.add_argument(
        "--objective",
        choices=("likelihood", "supervised"),
        default="likelihood",
        help="what to minimise (default likelihood)",
    )
    add_config(parser)
    add_context_arguments(
        parser,
        "the parts tuned: GM, A6 learned birth and clutter; A1 learned birth; A2 learned "
        "clutter; A3 the measured magnitudes of uniform densities; A4, A5 = A3 with learned "
        "birth, clutter",
    )
    parser.add_argument(
        "--tune",
        metavar="NAMES",
        help=f"comma-separated parameters to tune, of {', '.join(TUNABLE)}, and with --context "
        f"{', '.join(UNIFORM_SHARES.values())} (default {','.join(CONFIG_TRAINABLE)}; with "
        f"--context those of {','.join(CONTEXT_TRAINABLE)} that the variant takes from it)",
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

    variant = context_variant(args)
    out = Path(args.out)
    suffix = ".json" if args.context is None else ".npz"
    if out.suffix != suffix:
        given = "" if args.context is None else " with --context (the tuned context)"
        raise InputError(f"--out must be a {suffix} file{given}, got {out}")
    outputs = [output_file("--out", args.out), side_file("--out", args.out, ".tuning.json")]
    if args.context is not None:
        outputs.append(side_file("--out", args.out, ".config.json"))
    check_outputs(
        outputs,
        [
            *sequence_inputs(args.sequence),
            *file_input(args.config, f"the tracker configuration --config {args.config}"),
            *file_input(args.context, f"the context --context {args.context}"),
        ],
    )
    base = load_config(args.config)
    context = load_tracker_context(args.context)
    names = None
    if args.tune is not None:
        names = [name.strip() for name in args.tune.split(",") if name.strip()]
    sequence = load_sequence(args.sequence, frames=args.frames)
    tuning = tune_sequence(
        sequence,
        args.objective,
        base,
        names,
        context=context,
        variant=variant or "GM",
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
    config_path = out
    if context is not None:
        tuned = tuning.context
        save_context(out, tuned.birth, tuned.clutter, tuned.metadata, tuned.initial)
        config_path = Path(outputs[2].path)
    config_path.write_text(json.dumps(tuning.config.overrides(), indent=2) + "\n")
    report_path = Path(outputs[1].path)
    report_path.write_text(json.dumps(tuning.report, indent=2) + "\n")
    report = tuning.report
    if args.json:
        files = {"out": str(out), "report_file": str(report_path)}
        if context is not None:
            files["config_file"] = str(config_path)
        print(json.dumps({**files, **report}))
        return 0
    changes = ", ".join(
        f"{name} {_show(report['start'][name])} -> {_show(report['tuned'][name])}"
        for name in report["tuned"]
    )
    written = f"{out} and {report_path}"
    if context is not None:
        written = f"{out} (the tuned context, variant {variant}), {config_path} and {report_path}"
    print(
        f"wrote {written} ({report['steps']} steps, {report['stop_reason']}, "
        f"{report['seconds']:.1f} s): {changes}"
    )
    return 0


def _show(value) -> str:
    if isinstance(value, list):
        return "[" + ", ".join(f"{v:.4g}" for v in value) + "]"
    return f"{value:.4g}"
