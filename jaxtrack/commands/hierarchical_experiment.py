"""``jaxtrack experiment hierarchical``: its arguments, help and run (logic in
:mod:`jaxtrack.experiments.hierarchical`; registered in :mod:`jaxtrack.commands.experiment`)."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from pathlib import Path

from jaxtrack.commands.cmt_ablation import SHARED_DATA
from jaxtrack.commands.paths import check_outputs, output_folder, sequence_inputs, video_input
from jaxtrack.experiments.cmt_ablation import HELD_OUT_SEEDS, PETS_VIDEO, VIDEO_SEQUENCES
from jaxtrack.experiments.common import markdown_table
from jaxtrack.experiments.hierarchical import TABLE_COLUMNS, run_experiment

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
scripted occlusions, crossings and group walks; the issue's goals as PASS/FAIL),
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
    parsed arguments: ``experiment(out, data, seeds, seed=, quick=, progress=)`` returns its
    record (``rows``, ``goals``); prints the table (``columns``) and the goals."""
    data = Path(args.data or SHARED_DATA)
    seeds = list(dict.fromkeys(args.seeds or HELD_OUT_SEEDS))
    inputs = video_input(data / PETS_VIDEO, f"the video {data / PETS_VIDEO}")
    for name in VIDEO_SEQUENCES:
        inputs += sequence_inputs(data / "mot15" / name)
    check_outputs(output_folder("--out", args.out, FILES), inputs)
    record = experiment(
        args.out, data, seeds, seed=args.seed, quick=args.quick, progress=not args.quiet
    )
    print(markdown_table(record["rows"], columns))
    for goal in record["goals"]:
        print(f"{'PASS' if goal['pass'] else 'FAIL'}: {goal['goal']}: {goal['measured']}")
    print(f"wrote {Path(args.out) / 'table.md'}, {Path(args.out) / 'results.json'}")
    return 0
