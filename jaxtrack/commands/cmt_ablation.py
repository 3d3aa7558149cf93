"""``jaxtrack experiment cmt-ablation``: its arguments, help and run (logic in
:mod:`jaxtrack.experiments.cmt_ablation`; registered in :mod:`jaxtrack.commands.experiment`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from jaxtrack.commands.arguments import SEED_COUNT_TYPE, SEED_TYPE, consecutive_seeds
from jaxtrack.commands.paths import check_outputs, output_folder, sequence_inputs, video_input
from jaxtrack.datasets.video_files import TRUTH_FILE
from jaxtrack.experiments.cmt_ablation import (
    ABLATION_FILES,
    HELD_OUT_SEEDS,
    PETS_VIDEO,
    TABLE_COLUMNS,
    TRACKER_SEEDS,
    VIDEO_SEQUENCES,
    goal_lines,
    run_cmt_ablation,
)
from jaxtrack.experiments.cmt_analysis import FIG8_FRAMES, FIG9_LEAD
from jaxtrack.experiments.common import EXPERIMENT_SMOOTHINGS, markdown_table

SEEDS = " ".join(map(str, HELD_OUT_SEEDS))
FIG8_SPAN = f"{FIG8_FRAMES[0]}-{FIG8_FRAMES[1]}"
#: The shared data folder beside the repository (``../shared/data``).
SHARED_DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"

HELP = "CMT ablation (Cui et al. Table II, Fig. 8, 9): MTb, MTb+CPD, CMT vs PHD, Kalman"
QUICK_HELP = "smoke run: TUD-Campus and the first --seeds scene, their first frames, few particles"
DESCRIPTION = f"""\
CMT ablation (Cui et al., Sec. VII): MTb vs MTb+CPD vs CMT, with PHD and Kalman beside them.

Sequences: PETS09-S2L1 (frames: --data/{PETS_VIDEO}), TUD-Campus and TUD-Stadtmitte (their
.mp4), whole, with their MOT15 detections; and the scripted video scenes of --seeds (default
{SEEDS}: held out, never used to tune any default; crossings of similarly dressed people,
groups, an occluder), written to OUT/scenes/video-SEED with their simulated detections. Every
tracker sees the same detections (CMT's foreground blobs) and runs with its default
configuration, --tracker-seeds times (seeds --seed onwards; the table and the goals
read the means): the CMT variants MTb (Gaussian prior + equally weighted features),
MTb+CPD (contextual proposal) and CMT (contextual proposal + contextual observation model),
the PHD tracker and the Kalman baseline. CMT's entry/exit zones are learned on the fly on
each sequence, as jaxtrack track does without --zones (table.md says what was found).

Fig. 8: MTb's and MTb+CPD's proposed particles on PETS09-S2L1 frames {FIG8_SPAN}, their
summed distance to the ground truth per frame. Fig. 9: the likelihood difference between the
two people of the first scene's scripted crossing under COM and EWOM, from {FIG9_LEAD} frames
before the crossing to its end.

Writes into --out: table.md (OE/DE/SE, MOTA/IDF1/HOTA/IDSW/MT/Frag per sequence and pooled
over the three MOT15 sequences and over the synthetic scenes, the issue's off-the-shelf
peers quoted (not re-run), the goals as PASS/FAIL, every seed's pooled rows, both analyses
in numbers), results.json (the same, with every seed's rows, the configurations, zones, run
times and the figures' per-frame numbers), fig8_prediction.png, fig9_discrimination.png and
sequences/SEQ/TRACKER.txt (every result of the first tracker seed, MOTChallenge format).
Logic: jaxtrack.experiments.cmt_ablation and cmt_analysis.

examples:
  jaxtrack experiment cmt-ablation --out /tmp/cmt
  jaxtrack experiment cmt-ablation --out /tmp/cmt-q --quick --seeds 101"""


def add_video_arguments(parser: argparse.ArgumentParser) -> None:
    """``--seeds``, ``--data`` and ``--smoothing``: the arguments of every experiment on the
    MOT15 videos and the scripted video scenes (cmt-ablation, hierarchical, fusion)."""
    parser.add_argument(
        "--seeds",
        nargs="+",
        type=SEED_TYPE,
        metavar="N",
        help=f"seeds of the synthetic video scenes (default {SEEDS}, held out; with --quick "
        "the first only)",
    )
    parser.add_argument(
        "--data",
        metavar="DIR",
        help=f"the shared data folder with mot15/ and video/ (default: {SHARED_DATA})",
    )
    parser.add_argument(
        "--smoothing",
        choices=EXPERIMENT_SMOOTHINGS,
        default="default",
        help="rts: every tracker's offline output re-estimated by the Rauch-Tung-Striebel "
        "smoother (the configurations' smoothing setting, under the PHD tracker's dynamics); "
        "none: every tracker's own estimates, as the papers output them; default: each "
        "configuration's own (the Fusion tracker's is rts since session 63, the others' "
        "none). The references (True identities) are not trackers and stay as they are",
    )


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """:func:`add_video_arguments` and ``--tracker-seeds``."""
    add_video_arguments(parser)
    parser.add_argument(
        "--tracker-seeds",
        type=SEED_COUNT_TYPE,
        metavar="K",
        help=f"runs of every tracker on every sequence, seeds --seed .. --seed + K - 1 (default "
        f"{TRACKER_SEEDS}; with --quick 1); the table and the goals read the means: one run's "
        "IDF1 moves by points with the seed",
    )


def video_experiment_inputs(data: Path) -> list:
    """The inputs an experiment on the MOT15 videos reads from ``data`` (PETS09-S2L1's
    video, the three sequences' files), for :func:`~jaxtrack.commands.paths.check_outputs`."""
    inputs = video_input(data / PETS_VIDEO, f"the video {data / PETS_VIDEO}")
    for name in VIDEO_SEQUENCES:
        inputs += sequence_inputs(data / "mot15" / name)
    return inputs


def video_experiment_options(args: argparse.Namespace) -> dict:
    """The keyword arguments every experiment on the MOT15 videos takes from the parsed
    arguments: ``seed``, ``quick``, ``progress`` and ``smoothing``."""
    return {
        "seed": args.seed,
        "quick": args.quick,
        "progress": not args.quiet,
        "smoothing": args.smoothing,
    }


def run(args: argparse.Namespace) -> int:
    """Runs the experiment on the parsed arguments; prints the table and the goals."""
    data = Path(args.data or SHARED_DATA)
    seeds = list(dict.fromkeys(args.seeds or HELD_OUT_SEEDS))
    count = args.tracker_seeds or (1 if args.quick else TRACKER_SEEDS)
    tracker_seeds = consecutive_seeds(args.seed, count, "--tracker-seeds")
    files = list(ABLATION_FILES)
    files += [
        f"scenes/video-{seed}/{name}"
        for seed in seeds
        for name in ("seqinfo.ini", "det/det.txt", "gt/gt.txt", TRUTH_FILE, f"video-{seed}.mp4")
    ]
    check_outputs(output_folder("--out", args.out, files), video_experiment_inputs(data))
    result = run_cmt_ablation(
        args.out, data, seeds, tracker_seeds=len(tracker_seeds), **video_experiment_options(args)
    )
    print(markdown_table(result.rows, TABLE_COLUMNS))
    for line in goal_lines(result.goals):
        print(line)
    print("wrote " + ", ".join(str(path) for path in result.files))
    return 0
