"""``jaxtrack experiment NAME``: the paper's experiments (logic in :mod:`jaxtrack.experiments`).

Every experiment takes ``--out DIR`` (required), ``--seed N`` (default 0), ``--quick`` (a
short smoke run) and ``--quiet``; those on one sequence also ``--sequence SEQ_DIR``
(default: the synthetic scene of ``--seed``, written to ``OUT/scene``). The scripts in
``experiments/`` run the same command (``python experiments/context_ablation.py ...`` is
``jaxtrack experiment context-ablation ...``).
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

from jaxtrack.commands import (
    cmt_ablation,
    cmt_crossings,
    fusion_experiment,
    hierarchical_experiment,
)
from jaxtrack.commands.arguments import (
    PARTICLES,
    RETRODICTION,
    SEED_COUNT_TYPE,
    SEED_TYPE,
    add_out,
    add_quiet,
    add_seed,
    consecutive_seeds,
    ranged,
    refuse_ignored,
)
from jaxtrack.commands.paths import (
    SCENE_FILES,
    benchmark_inputs,
    check_outputs,
    output_folder,
    sequence_inputs,
    video_input,
)
from jaxtrack.configs import SMOOTHINGS
from jaxtrack.datasets.scene_bank import FAMILIES
from jaxtrack.errors import InputError
from jaxtrack.experiments.ablation import ABLATION_COLUMNS, run_ablation
from jaxtrack.experiments.common import markdown_table
from jaxtrack.experiments.comparison import COMPARISON_COLUMNS, run_comparison
from jaxtrack.experiments.context_gap import GAP_SUMMARY_COLUMNS, gap_summary, run_context_gap
from jaxtrack.experiments.context_generalisation import (
    GAIN_COLUMNS,
    GENERALISATION_FILES,
    REAL_SEEDS,
    REAL_SEQUENCES,
    VIDEO_DETECTIONS,
    VIDEO_FILE,
    VIDEO_SEQUENCE,
    gain_table,
    goal_lines,
    run_context_generalisation,
)
from jaxtrack.experiments.magnitudes import run_magnitude_sweep, sweep_summary
from jaxtrack.experiments.tuning import SUMMARY_COLUMNS, gradient_tuning_experiment
from jaxtrack.filters.births import VELOCITY_PROPOSALS
from jaxtrack.filters.phd import CONFIRMATIONS
from jaxtrack.filters.phd_tracker import PHDConfig

#: The data folder beside the repository (``../shared/data``).
SHARED_DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"
#: The MOT15 training sequences (default ``--mot-root`` of compare-trackers).
DEFAULT_MOT_ROOT = SHARED_DATA / "mot15"
#: PETS09-S2L1 (default ``--pets`` of gradient-tuning).
DEFAULT_PETS = DEFAULT_MOT_ROOT / "PETS09-S2L1"


class Experiment(NamedTuple):
    """One ``jaxtrack experiment`` sub-command.

    Attributes:
        help: the one line ``jaxtrack experiment --help`` lists.
        description: what it does and writes (its ``--help``).
        quick_help: what ``--quick`` shortens.
        sequence: whether it takes ``--sequence SEQ_DIR``.
        add_extras: adds its own arguments, or None.
        run: runs it on the parsed arguments; returns the exit status.
        files: the files it writes into ``--out``.
        scene: the sub-folder of ``--out`` its synthetic scene is written to (without
            ``--sequence``).
    """

    help: str
    description: str
    quick_help: str
    sequence: bool
    add_extras: Callable[[argparse.ArgumentParser], None] | None
    run: Callable[[argparse.Namespace], int]
    files: tuple[str, ...]
    scene: str = "scene"


def _steps(args: argparse.Namespace) -> Callable[[str], None] | None:
    """Prints each step (and turns the progress bars on) unless ``--quiet``."""
    return None if args.quiet else print


def _written(files) -> str:
    return "wrote " + ", ".join(str(path) for path in files)


def _check_paths(args: argparse.Namespace, inputs: list | None = None) -> None:
    """Refuses a bad ``--out`` (or one over an input) before the experiment starts."""
    experiment = EXPERIMENTS[args.experiment]
    files = list(experiment.files)
    sequence = getattr(args, "sequence", None)
    if sequence is None:
        files += [f"{experiment.scene}/{name}" for name in SCENE_FILES]
    inputs = list(inputs or [])
    if sequence is not None:
        inputs += sequence_inputs(sequence)
    check_outputs(output_folder("--out", args.out, files), inputs)


def _context_ablation(args: argparse.Namespace) -> int:
    _check_paths(args)

    result, files = run_ablation(
        args.out, args.seed, args.quick, args.sequence, progress=_steps(args)
    )
    print(markdown_table(result.rows, ABLATION_COLUMNS))
    print(_written(files))
    return 0


def _sweep_magnitudes(args: argparse.Namespace) -> int:
    _check_paths(args)

    result, files = run_magnitude_sweep(
        args.out, args.seed, args.quick, args.sequence, progress=_steps(args)
    )
    print(files[-1].read_text())
    print(json.dumps(sweep_summary(result), indent=2))
    print(_written(files))
    return 0


def _context_gap_extras(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--family",
        action="append",
        choices=tuple(FAMILIES),
        metavar="NAME",
        help=f"a scene family (repeatable; default all: {', '.join(FAMILIES)})",
    )
    parser.add_argument(
        "--num-seeds",
        type=SEED_COUNT_TYPE,
        default=3,
        metavar="K",
        help="seeds --seed .. --seed + K - 1 of each family (default 3)",
    )


def _context_gap(args: argparse.Namespace) -> int:
    families = args.family or list(FAMILIES)
    seeds = consecutive_seeds(args.seed, args.num_seeds, "--num-seeds")
    files = list(EXPERIMENTS[args.experiment].files)
    files += [
        f"scenes/{family}-{seed}/{name}"
        for family in families
        for seed in seeds
        for name in SCENE_FILES
    ]
    check_outputs(output_folder("--out", args.out, files), [])
    rows, written = run_context_gap(args.out, families, seeds, args.quick, _steps(args))
    print(markdown_table(gap_summary(rows), GAP_SUMMARY_COLUMNS))
    print(_written(written))
    return 0


def _context_generalisation_extras(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--families",
        nargs="+",
        choices=tuple(FAMILIES),
        metavar="NAME",
        help=f"scene families of the bank (default all: {', '.join(FAMILIES)})",
    )
    parser.add_argument(
        "--seeds",
        nargs="+",
        type=SEED_TYPE,
        metavar="N",
        help="seeds of the bank's scenes (default 0 1 2; with --quick 0)",
    )
    parser.add_argument(
        "--data",
        metavar="DIR",
        help=f"the shared data folder with mot15/ and video/ (default: {SHARED_DATA})",
    )
    parser.add_argument(
        "--no-real",
        action="store_true",
        help="only the bank (no PETS09-S2L1, TUD-Stadtmitte, video)",
    )
    parser.add_argument(
        "--no-video",
        action="store_true",
        help="no video detector's output on vtest.avi (always so with --quick)",
    )
    parser.add_argument(
        "--no-tuned", action="store_true", help="skip GM+tuned (the gradient tuning)"
    )
    parser.add_argument(
        "--particles",
        type=ranged(PARTICLES),
        metavar="N",
        help="the PHD tracker's particles in every run (default 2048; with --quick 256): "
        "GM's gain over UM shrinks as the particles grow",
    )
    parser.add_argument(
        "--real-seeds",
        type=SEED_COUNT_TYPE,
        metavar="K",
        help="runs of each real sequence, seeds --seed .. --seed + K - 1 (default "
        f"{len(REAL_SEEDS)}; with --quick 1): one run's MOTA moves by points with the seed",
    )
    parser.add_argument(
        "--confirmation",
        choices=tuple(CONFIRMATIONS),
        default="auto",
        help="the PHD tracker's track confirmation in every run (PHDConfig.confirmation; "
        "default auto): 'evidence' adds up the log-odds of a track's detections, read through "
        "the detector's calibration learned with each context (UM included); 'score' needs "
        "one detection scoring 0.97; 'auto' is 'evidence' where a calibration was learned",
    )
    parser.add_argument(
        "--retrodiction",
        type=ranged(RETRODICTION),
        metavar="N",
        default=0,
        help="extend every run's confirmed tracks back by up to N frames onto the detections "
        "before their first box (PHDConfig.retrodiction; default 0, off): raises UM's and "
        "GM's MOTA, UM's more",
    )
    parser.add_argument(
        "--smoothing",
        choices=SMOOTHINGS,
        default="none",
        help="every run's offline output re-estimated by the Rauch-Tung-Striebel smoother "
        "under the tracker's own dynamics (PHDConfig.smoothing; default none)",
    )
    parser.add_argument(
        "--birth-velocity",
        choices=VELOCITY_PROPOSALS,
        default=PHDConfig.birth_velocity,
        help="the births' velocity proposal in every run (PHDConfig.birth_velocity; default "
        f"{PHDConfig.birth_velocity}): 'detections' draws most births' velocities at the "
        "displacements from the previous frame's detections, 'uniform' over the velocity range",
    )
    parser.add_argument(
        "--first-frame",
        action="store_true",
        help="every context also learns the first frame's intensity (where the targets are; "
        "learn-context --first-frame): GM, A1, A4 and A6 start their runs from it instead "
        "of the uniform one",
    )
    parser.add_argument(
        "--oracle",
        action="store_true",
        help="also GM-oracle: GM with a context learned on each scene's test half itself "
        "(not held out; it bounds what a better learner could give the tracker, and GM's "
        "distance below it is the learner's generalisation gap; the goals read GM only; "
        "adds one learning per scene)",
    )


def _context_generalisation(args: argparse.Namespace) -> int:
    if args.no_real:
        refuse_ignored(args, ["data", "real_seeds"], "is not used with --no-real")
    families = args.families or list(FAMILIES)
    seeds = list(dict.fromkeys(args.seeds or ([0] if args.quick else [0, 1, 2])))
    num_real = args.real_seeds or (1 if args.quick else len(REAL_SEEDS))
    real_seeds = consecutive_seeds(args.seed, num_real, "--real-seeds")
    data = None if args.no_real else Path(args.data or SHARED_DATA)
    video = data is not None and not (args.quick or args.no_video)
    files = list(GENERALISATION_FILES)
    files += [
        f"scenes/{family}-{seed}/{name}"
        for family in families
        for seed in seeds
        for name in SCENE_FILES
    ]
    inputs = []
    if data is not None:
        for name in REAL_SEQUENCES:
            inputs += sequence_inputs(data / "mot15" / name)
        if video:
            files.append(str(VIDEO_DETECTIONS))
            inputs += video_input(data / VIDEO_FILE, f"the video {data / VIDEO_FILE}")
            inputs += sequence_inputs(data / "mot15" / VIDEO_SEQUENCE)
    check_outputs(output_folder("--out", args.out, files), inputs)
    result = run_context_generalisation(
        args.out,
        families,
        seeds,
        data,
        video,
        tuned=not args.no_tuned,
        quick=args.quick,
        real_seeds=real_seeds,
        particles=args.particles,
        confirmation=args.confirmation,
        retrodiction=args.retrodiction,
        smoothing=args.smoothing,
        birth_velocity=args.birth_velocity,
        first_frame=args.first_frame,
        oracle=args.oracle,
        progress=not args.quiet,
    )
    print(markdown_table(gain_table(result.summary), GAIN_COLUMNS))
    for line in goal_lines(result.goals):
        print(line)
    for note in result.notes:
        print(f"note: {note}")
    print(_written(result.files))
    return 0


def _compare_trackers_extras(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--mot-root",
        metavar="DIR",
        help=f"folder of sequence folders also compared (default: {DEFAULT_MOT_ROOT})",
    )
    parser.add_argument("--no-mot", action="store_true", help="skip the --mot-root sequences")


def _compare_trackers(args: argparse.Namespace) -> int:
    if args.quick or args.no_mot:
        refuse_ignored(args, ["mot_root"], "is not compared with --quick or --no-mot")
    mot_root = None if args.quick or args.no_mot else args.mot_root or str(DEFAULT_MOT_ROOT)
    inputs = []
    if mot_root is not None:
        root = Path(mot_root)
        folders = (
            sorted(p for p in root.iterdir() if (p / "seqinfo.ini").is_file())
            if root.is_dir()
            else []
        )
        if not folders:
            raise InputError(f"{root}: no sequence folders (with seqinfo.ini) found")
        inputs = benchmark_inputs(mot_root, folders)
    _check_paths(args, inputs)
    rows, files = run_comparison(
        args.out, args.seed, args.quick, args.sequence, mot_root, progress=not args.quiet
    )
    print(markdown_table(rows, COMPARISON_COLUMNS[:-1]))
    print(_written(files))
    return 0


def _gradient_tuning_extras(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--pets", metavar="SEQ_DIR", help=f"PETS09-S2L1 folder (default: {DEFAULT_PETS})"
    )
    parser.add_argument("--no-pets", action="store_true", help="only the synthetic scene")


def _gradient_tuning(args: argparse.Namespace) -> int:
    if args.no_pets:
        refuse_ignored(args, ["pets"], "is not used with --no-pets")
    pets = None if args.no_pets else args.pets or str(DEFAULT_PETS)
    _check_paths(args, [] if pets is None else sequence_inputs(pets))
    result = gradient_tuning_experiment(
        args.out,
        args.seed,
        args.quick,
        pets,
        progress=not args.quiet,
    )
    print(markdown_table(result["summary"], SUMMARY_COLUMNS))
    for goal in result["goals"]:
        print(
            f"{goal['dataset']}: tuned MOTA {goal['tuned_MOTA']:.2f} vs grid "
            f"{goal['grid_MOTA']:.2f} ({goal['tuned_vs_grid_percent']:.1f}%), "
            f"{goal['tuning_runs']} vs {goal['grid_runs']} runs: "
            f"goal {'met' if goal['met'] else 'NOT met'}"
        )
    print(f"wrote {args.out}/summary.csv, steps.csv, goals.csv, summary.md, gradient_tuning.png")
    return 0


#: The experiments, by name (``experiments/<name with _>.py`` runs the same).
EXPERIMENTS = {
    "context-ablation": Experiment(
        help="context ablation (PHD-context Fig. 14): UM, GM and A1-A6 on one test span",
        description="""\
Context ablation, PHD-context Fig. 14: UM, GM and A1-A6 on the same test span.

Learns context on the first half of a sequence (births from a UM tracker run, and for A6
from the ground truth; clutter from the ground truth), tracks the second half with every
variant and writes ablation.csv, ablation.png (bars of the MOTA/MOTP/MODA/MODP % difference
w.r.t. UM) and summary.md into --out. Logic: jaxtrack.experiments.ablation.

examples:
  jaxtrack experiment context-ablation --out /tmp/ablation
  jaxtrack experiment context-ablation --out /tmp/pets --sequence SEQ_DIR""",
        quick_help="short smoke run (short scene, few particles)",
        sequence=True,
        add_extras=None,
        run=_context_ablation,
        files=("ablation.csv", "ablation.png", "summary.md"),
    ),
    "sweep-magnitudes": Experiment(
        help="magnitude sweep (PHD-context Fig. 15): scores against lambda_r and lambda_s",
        description="""\
Magnitude sweep, PHD-context Fig. 15: MOTA/MOTP/MODA/MODP against lambda_r and lambda_s.

Learns context on the first half of a sequence (births from a UM tracker run, clutter from
the ground truth), then tracks the second half for every point of a log-spaced grid of
clutter magnitudes lambda_r (0.1..10 false detections per frame) and birth magnitudes
lambda_s (0.02..2 births per frame), 9 x 9 by default, with uniform intensities (UM) and with
the learned ones (GM): 162 tracker runs in one vmapped sweep sharded over all JAX devices
(on CPU one device per core; a configuration's numbers do not depend on how many).
Writes sweep.csv (every configuration), sweep.png (scores against each magnitude),
sweep_mota.png (MOTA over the grid) and summary.md into --out. Logic:
jaxtrack.experiments.magnitudes.

examples:
  jaxtrack experiment sweep-magnitudes --out /tmp/sweep
  JAX_NUM_CPU_DEVICES=1 jaxtrack experiment sweep-magnitudes ...   # one CPU device""",
        quick_help="short smoke run (short scene, few particles, 3 x 3)",
        sequence=True,
        add_extras=None,
        run=_sweep_magnitudes,
        files=("sweep.csv", "sweep.png", "sweep_mota.png", "summary.md"),
    ),
    "context-gap": Experiment(
        help="UM vs GM on the scene bank's families (learned context on held-out scenes)",
        description="""\
UM vs GM on the scene families of the test bank (jaxtrack.datasets.scene_bank): street,
plaza-edges, sparse-door, layout-change, flicker, uniform, misplaced.

For each family and seed, writes the scene to OUT/scenes/FAMILY-SEED, learns context on its
first half (births from a UM tracker run, clutter from the ground truth, as
context-ablation does), tracks the second half with uniform intensities (UM) and with the
learned ones (GM), and scores both. Writes context_gap.csv (every score) and summary.md
(MOTA per family and seed) into --out. Logic: jaxtrack.experiments.context_gap.

examples:
  jaxtrack experiment context-gap --out /tmp/gap --quick
  jaxtrack experiment context-gap --out /tmp/street --family street --num-seeds 1""",
        quick_help="few particles (the scenes are the same)",
        sequence=False,
        add_extras=_context_gap_extras,
        run=_context_gap,
        files=("context_gap.csv", "summary.md"),
        scene="scenes",
    ),
    "context-generalisation": Experiment(
        help="UM, GM, A1-A6, GM+tuned on the scene bank and real sequences (issue 15 goals)",
        description=f"""\
Does learned context generalise? UM, GM, A1-A6 and GM+tuned on held-out scenes.

Scenes: every family of the scene bank (jaxtrack.datasets.scene_bank: street, plaza-edges,
sparse-door, layout-change, flicker, uniform, misplaced) for each of --seeds, written to
OUT/scenes/FAMILY-SEED, learned on frames 1-300 and tested on 301-600; then (unless
--no-real) from --data: PETS09-S2L1 (learn 1:397, test 398:795), TUD-Stadtmitte (learn
1:89, test 90:179) and (unless --no-video or --quick) PETS09-video: the video detector
(jaxtrack detect, horprasert) run once over video/vtest.avi, its detections cached in
OUT/{VIDEO_DETECTIONS} (delete it to detect again), paired with PETS09-S2L1's ground truth
and seqinfo.ini (7 fps), same spans.

Variants: context learned on the training half with births from a UM tracker run and
clutter from the ground truth (as context-ablation) gives GM and A1-A5; births from the
ground truth give A6; GM+tuned is the GM context tuned on the training half by the
likelihood objective (skipped with a note while jaxtrack.pipelines.tuning.tune_sequence
takes no context; --no-tuned skips it). All variants of a scene track its test half in
one compiled run with the scene's seed (a bank scene's seed); each real sequence is
learned, tuned and tracked with --real-seeds seeds (--seed onwards; a real sequence's MOTA
moves by points with the particles' seed alone) and its group's mean is what the goals
read.

Writes into --out: context_generalisation.csv (scores of every scene and variant, with
MOTA_gain_pct = 100 (MOTA - MOTA_UM) / |MOTA_UM| and the misses and false positives by
kind, FN_*/FP_*, as jaxtrack eval --errors counts them against the scene's detections),
summary.csv (per family or real sequence and variant: mean/min/max MOTA and gain over the
seeds, mean minus UM's in points, FP, FN and the kinds summed over the seeds),
contexts.csv (the learned densities), gain.png (relative MOTA gain of GM and GM+tuned per
group: bars = mean over seeds, marks = min..max, lines at 0 and +9%) and
summary.md (the tables, issue 15's goals as PASS/FAIL with their numbers, UM's, GM's and
GM+tuned's errors by kind, run time per stage). Prints the gain table and the goals. Logic:
jaxtrack.experiments.context_generalisation.

examples:
  jaxtrack experiment context-generalisation --out /tmp/cg
  jaxtrack experiment context-generalisation --out /tmp/cg --no-tuned --no-video
  jaxtrack experiment context-generalisation --out /tmp/q --quick --families street \\
      --no-real --no-tuned""",
        quick_help="few particles, a 3-step tuning, one seed (unless --seeds), no video",
        sequence=False,
        add_extras=_context_generalisation_extras,
        run=_context_generalisation,
        files=GENERALISATION_FILES,
        scene="scenes",
    ),
    "compare-trackers": Experiment(
        help="tracker comparison (PHD-context Fig. 16): PHD-GM, PHD-UM, Kalman, SORT-like",
        description="""\
Tracker comparison, PHD-context Fig. 16: PHD-context vs data association, same detections.

On each sequence, context is learned on the first half and four trackers are scored on the
second half: the PHD tracker with learned context (PHD-GM) and with uniform intensities
(PHD-UM), the Kalman data-association baseline (Kalman) and its SORT-like preset. Unless
--quick or --no-mot, also on every sequence under --mot-root, with pooled scores. Writes
comparison.csv, comparison.png and summary.md into --out. Logic:
jaxtrack.experiments.comparison.

examples:
  jaxtrack experiment compare-trackers --out /tmp/compare
  jaxtrack experiment compare-trackers --out /tmp/quick --quick""",
        quick_help="short smoke run (short synthetic scene, few particles, no --mot-root)",
        sequence=True,
        add_extras=_compare_trackers_extras,
        run=_compare_trackers,
        files=("comparison.csv", "comparison.png", "summary.md"),
    ),
    "gradient-tuning": Experiment(
        help="gradient tuning of the magnitudes vs an 8 x 8 grid sweep (synthetic, PETS)",
        description="""\
Gradient tuning versus a grid sweep of the clutter and birth magnitudes.

From mis-specified magnitudes (lambda_r = 10, lambda_s = 1), tunes the PHD tracker by adam on
the unsupervised PHD log-likelihood of a training span and compares it on the test span with
the best configuration of an 8x8 grid sweep (chosen by training MOTA): on the synthetic scene
of --seed (halves) and on PETS09-S2L1 (frames 1-400 / 401-795). Writes summary.csv,
steps.csv (loss and test MOTA per step), goals.csv, summary.md and gradient_tuning.png
(loss and MOTA against the step) into --out. Logic: jaxtrack.experiments.tuning.

examples:
  jaxtrack experiment gradient-tuning --out /tmp/gt
  jaxtrack experiment gradient-tuning --out /tmp/gt-synthetic --no-pets""",
        quick_help="short smoke run (short spans, 3x3 grid, 2 steps)",
        sequence=False,
        add_extras=_gradient_tuning_extras,
        run=_gradient_tuning,
        files=("summary.csv", "steps.csv", "goals.csv", "summary.md", "gradient_tuning.png"),
        scene="synthetic",
    ),
    "cmt-ablation": Experiment(
        help=cmt_ablation.HELP,
        description=cmt_ablation.DESCRIPTION,
        quick_help=cmt_ablation.QUICK_HELP,
        sequence=False,
        add_extras=cmt_ablation.add_arguments,
        run=cmt_ablation.run,
        files=cmt_ablation.ABLATION_FILES,
        scene="scenes",
    ),
    "cmt-crossings": Experiment(
        help=cmt_crossings.HELP,
        description=cmt_crossings.DESCRIPTION,
        quick_help=cmt_crossings.QUICK_HELP,
        sequence=False,
        add_extras=cmt_crossings.add_arguments,
        run=cmt_crossings.run,
        files=cmt_crossings.FILES,
        scene="scenes",
    ),
    "hierarchical": Experiment(
        help=hierarchical_experiment.HELP,
        description=hierarchical_experiment.DESCRIPTION,
        quick_help=hierarchical_experiment.QUICK_HELP,
        sequence=False,
        add_extras=cmt_ablation.add_video_arguments,
        run=hierarchical_experiment.run,
        files=hierarchical_experiment.FILES,
        scene="scenes",
    ),
    "hierarchical-noise": Experiment(
        help=hierarchical_experiment.NOISE_HELP,
        description=hierarchical_experiment.NOISE_DESCRIPTION,
        quick_help=hierarchical_experiment.NOISE_QUICK_HELP,
        sequence=False,
        add_extras=hierarchical_experiment.add_noise_arguments,
        run=hierarchical_experiment.run_noise,
        files=hierarchical_experiment.FILES,
        scene="scenes",
    ),
    "fusion": Experiment(
        help=fusion_experiment.HELP,
        description=fusion_experiment.DESCRIPTION,
        quick_help=fusion_experiment.QUICK_HELP,
        sequence=False,
        add_extras=fusion_experiment.add_arguments,
        run=fusion_experiment.run,
        files=hierarchical_experiment.FILES,
        scene="scenes",
    ),
}


def register(subparsers) -> None:
    """Adds the ``experiment`` parser (one sub-parser per experiment) to the CLI."""
    parser = subparsers.add_parser(
        "experiment",
        help="run one of the paper's experiments (ablation, sweep, comparison, tuning)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    experiments = parser.add_subparsers(dest="experiment", metavar="NAME", required=True)
    for name, experiment in EXPERIMENTS.items():
        sub = experiments.add_parser(
            name,
            help=experiment.help,
            description=experiment.description,
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        add_out(sub, "output folder (created if needed)", metavar="DIR")
        add_seed(sub)
        if experiment.sequence:
            sub.add_argument(
                "--sequence",
                metavar="SEQ_DIR",
                help="MOTChallenge sequence with gt (default: the synthetic scene of --seed)",
            )
        sub.add_argument("--quick", action="store_true", help=experiment.quick_help)
        add_quiet(sub)
        if experiment.add_extras is not None:
            experiment.add_extras(sub)
        sub.set_defaults(func=experiment.run)
