"""``jaxtrack experiment hierarchical`` and ``hierarchical-noise``: their arguments, help and
runs (logic in :mod:`jaxtrack.experiments.hierarchical` and
:mod:`jaxtrack.experiments.hierarchical_noise`; registered in
:mod:`jaxtrack.commands.experiment`)."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from pathlib import Path

from jaxtrack.commands.cmt_ablation import (
    SHARED_DATA,
    video_experiment_inputs,
    video_experiment_options,
)
from jaxtrack.commands.paths import check_outputs, output_folder, sequence_inputs
from jaxtrack.experiments.cmt_ablation import HELD_OUT_SEEDS, PETS_VIDEO
from jaxtrack.experiments.common import markdown_table
from jaxtrack.experiments.hierarchical import TABLE_COLUMNS, run_experiment
from jaxtrack.experiments.hierarchical_noise import COLUMNS as NOISE_COLUMNS
from jaxtrack.experiments.hierarchical_noise import QUICK_FRAMES, development_folders
from jaxtrack.experiments.hierarchical_noise import run_experiment as run_noise_experiment

SEEDS = " ".join(map(str, HELD_OUT_SEEDS))
#: The files the experiment writes into --out (besides sequences/ and scenes/); the same for
#: every experiment run by :func:`run_video_experiment`.
FILES = ("table.md", "results.json")

HELP = "Hierarchical tracker: Kalman bank vs |S|^1/2 managed low level vs both levels"
QUICK_HELP = "smoke run: TUD-Campus and the first --seeds scene, their first frames"
DESCRIPTION = f"""\
The Hierarchical tracker (SPEC section 4): the Kalman bank alone, the low level with |S|^1/2
track management, and both levels (appearance trackers, re-association, events).

Sequences: PETS09-S2L1 (frames: --data/{PETS_VIDEO}), TUD-Campus and TUD-Stadtmitte (their
.mp4), whole; and the scripted video scenes of --seeds (default {SEEDS}: held out, never used
to tune any default), written to OUT/scenes/video-SEED. Each is tracked with two detection
sources: det (its own detections: MOT15's det.txt, the scenes' simulated detector) and bs
(the toolkit's background-subtraction detector on its frames, default settings), by the
three variants of `jaxtrack track --tracker hierarchical` with default configurations and
--seed.

Writes into --out: table.md (MOTA/IDF1/HOTA/IDSW/Frag/MT/ML per sequence and source, pooled
over the MOT15 sequences and over the scenes; the full tracker's event precision/recall
against the scenes' scripted group/split/entry/exit events; the identity kept across their
scripted occlusions, crossings and group walks, and the full tracker's cases not kept (event,
person, identity before and after); the issue's goals as PASS/FAIL),
results.json (the same with the configurations and run times) and
sequences/SEQ/SOURCE/VARIANT.txt (every result; .events.csv beside the full tracker's; the bs
detections as det.txt). Logic: jaxtrack.experiments.hierarchical.

examples:
  jaxtrack experiment hierarchical --out /tmp/hier
  jaxtrack experiment hierarchical --out /tmp/hier-q --quick --seeds 101"""


def run(args: argparse.Namespace) -> int:
    """Runs the experiment on the parsed arguments; prints the table and the goals."""
    return run_video_experiment(args, run_experiment, TABLE_COLUMNS)


def run_video_experiment(
    args: argparse.Namespace, experiment: Callable[..., dict], columns: Sequence[str]
) -> int:
    """Runs an experiment on the MOT15 videos and scenes (``--data``, ``--seeds``) with the
    parsed arguments: ``experiment(out, data, seeds, seed=, quick=, progress=, smoothing=)``
    returns its record (``rows``, ``goals``); prints the table (``columns``) and the goals."""
    data = Path(args.data or SHARED_DATA)
    seeds = list(dict.fromkeys(args.seeds or HELD_OUT_SEEDS))
    check_outputs(output_folder("--out", args.out, FILES), video_experiment_inputs(data))
    record = experiment(args.out, data, seeds, **video_experiment_options(args))
    print(markdown_table(record["rows"], columns))
    for goal in record["goals"]:
        print(f"{'PASS' if goal['pass'] else 'FAIL'}: {goal['goal']}: {goal['measured']}")
    print(f"wrote {Path(args.out) / 'table.md'}, {Path(args.out) / 'results.json'}")
    return 0


NOISE_HELP = "Hierarchical low level on the development split: a priori vs estimated noise"
NOISE_QUICK_HELP = (
    f"smoke run: the first two development sequences, their first {QUICK_FRAMES} frames"
)
NOISE_DESCRIPTION = """\
The evidence for the Hierarchical tracker's `noise` setting (jaxtrack.filters.hier_low_noise):
the managed low level (which does not read the images; it gets blank frames) on the MOT15
training sequences of --data that have no video, i.e. all but PETS09-S2L1, TUD-Campus and
TUD-Stadtmitte, which `jaxtrack experiment hierarchical` holds out; on their own detections,
with the a priori noise and the noise estimated from those detections, each with every
detection and with the detections scoring >= 0.9, and the Kalman bank for reference.
--seed changes nothing (neither draws random numbers).

Writes into --out: table.md (MOTA/IDF1/HOTA/IDSW/FP/FN pooled over the sequences, the
estimated noise of each sequence) and results.json. Logic:
jaxtrack.experiments.hierarchical_noise.

examples:
  jaxtrack experiment hierarchical-noise --out /tmp/noise
  python experiments/hierarchical_noise.py --out /tmp/noise-q --quick"""


def add_noise_arguments(parser: argparse.ArgumentParser) -> None:
    """``--data``."""
    parser.add_argument(
        "--data",
        metavar="DIR",
        help=f"the shared data folder with mot15/ (default: {SHARED_DATA})",
    )


def run_noise(args: argparse.Namespace) -> int:
    """Runs the development-split noise comparison; prints its table."""
    data = Path(args.data or SHARED_DATA)
    sequences = development_folders(data)
    inputs = [item for folder in sequences for item in sequence_inputs(folder)]
    check_outputs(output_folder("--out", args.out, FILES), inputs)
    record = run_noise_experiment(args.out, data, quick=args.quick, progress=not args.quiet)
    print(markdown_table(record["rows"], NOISE_COLUMNS))
    for name, line in record["estimated_noise"].items():
        print(f"{name}: {line}")
    print(f"wrote {Path(args.out) / 'table.md'}, {Path(args.out) / 'results.json'}")
    return 0
