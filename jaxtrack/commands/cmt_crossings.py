"""``jaxtrack experiment cmt-crossings``: its arguments, help and run (logic in
:mod:`jaxtrack.experiments.cmt_crossings`; registered in :mod:`jaxtrack.commands.experiment`)."""

from __future__ import annotations

import argparse

from jaxtrack.commands.arguments import (
    SEED_COUNT_TYPE,
    SEED_TYPE,
    add_config,
    consecutive_seeds,
    load_config,
)
from jaxtrack.commands.paths import check_outputs, file_input, output_folder
from jaxtrack.datasets.video_files import TRUTH_FILE
from jaxtrack.experiments.cmt_ablation import TRACKER_SEEDS, goal_lines
from jaxtrack.experiments.cmt_crossings import (
    COLUMNS,
    DEFAULT_SEEDS,
    FAMILIES,
    FILES,
    run_crossing_families,
)
from jaxtrack.experiments.common import markdown_table

SEEDS = f"{DEFAULT_SEEDS[0]}-{DEFAULT_SEEDS[-1]}"
HELP = "CMT: COM vs EWOM on scripted crossings, by how alike the pair dress (SE goal)"
QUICK_HELP = "smoke run: one short scene per family, few particles, one tracker seed"
DESCRIPTION = f"""\
The contextual observation model (COM) against equally weighted features (EWOM) on the
scripted crossings of the synthetic video scenes, by how alike the crossing pair dress
(`jaxtrack simulate --video` scene setting crossing_alike, one family per value):

  both    top and bottom the same palette colour within +-4 levels (the default scenes,
          those of cmt-ablation): no colour feature separates the pair
  top     the tops alike, the bottoms two different palette colours
  bottom  the bottoms alike, the tops different

Each family's scenes (--seeds, default {SEEDS}, written to OUT/scenes/FAMILY-SEED; no
tracker default was set on them) are tracked by MTb+CPD (EWOM) and CMT (the same proposal
with COM), default configurations, zones learned on the fly, --tracker-seeds seeds from
--seed. Measured per family: SE on the crossings (frames with an identity switch of the
pair, from the crossing to 10 frames after it), the pair's identities kept / switched / lost
across the crossing, the scenes' pooled IDSW, IDF1 and MOTA, and Fig. 9's likelihood gap
between the pair under COM and EWOM (no tracker). The goal per family: SE on the crossings
falls with COM.

--config FILE.json changes both variants alike (for instance {{"support": "box",
"appearance_weight": 3}}: a stronger appearance term); it may not set the variant.

Writes into --out: table.md, results.json (with every scene's counts), crossings.png and
sequences/FAMILY-SEED/TRACKER.txt (the first tracker seed's results, MOTChallenge format).
Logic: jaxtrack.experiments.cmt_crossings. About 2 minutes per family and tracker seed with
12 scenes on 2 cores (18 minutes for the defaults).

examples:
  jaxtrack experiment cmt-crossings --out /tmp/crossings
  jaxtrack experiment cmt-crossings --out /tmp/c --families top --seeds 300 301 302
  jaxtrack experiment cmt-crossings --out /tmp/c-q --quick"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--seeds``, ``--families``, ``--tracker-seeds`` and ``--config``."""
    parser.add_argument(
        "--seeds",
        nargs="+",
        type=SEED_TYPE,
        metavar="N",
        help=f"scene seeds, the same in every family (default {SEEDS}; with --quick the first)",
    )
    parser.add_argument(
        "--families",
        nargs="+",
        choices=FAMILIES,
        default=list(FAMILIES),
        help="how alike the crossing pair dress (default: all three)",
    )
    parser.add_argument(
        "--tracker-seeds",
        type=SEED_COUNT_TYPE,
        metavar="K",
        help=f"runs of each variant on each scene, seeds --seed .. --seed + K - 1 (default "
        f"{TRACKER_SEEDS}; with --quick 1)",
    )
    add_config(parser)


def run(args: argparse.Namespace) -> int:
    """Runs the experiment on the parsed arguments; prints the table and the goals."""
    seeds = list(dict.fromkeys(args.seeds or DEFAULT_SEEDS))
    families = list(dict.fromkeys(args.families))
    count = args.tracker_seeds or (1 if args.quick else TRACKER_SEEDS)
    consecutive_seeds(args.seed, count, "--tracker-seeds")
    files = list(FILES)
    files += [
        f"scenes/{family}-{seed}/{name}"
        for family in families
        for seed in (seeds[:1] if args.quick else seeds)
        for name in ("seqinfo.ini", "det/det.txt", "gt/gt.txt", TRUTH_FILE, f"video-{seed}.mp4")
    ]
    config = load_config(args.config, "cmt")
    check_outputs(
        output_folder("--out", args.out, files),
        file_input(args.config, f"the tracker configuration --config {args.config}"),
    )
    result = run_crossing_families(
        args.out,
        seeds,
        families,
        seed=args.seed,
        tracker_seeds=count,
        quick=args.quick,
        progress=not args.quiet,
        config=config,
    )
    print(markdown_table(result.rows, COLUMNS))
    for line in goal_lines(result.goals):
        print(line)
    print("wrote " + ", ".join(str(path) for path in result.files))
    return 0
