"""Tracker comparison, PHD-context Fig. 16: PHD-context vs data association, same detections.

On each sequence, context is learned on the first half and four trackers are scored on the
second half: the PHD tracker with learned context (PHD-GM) and with uniform intensities
(PHD-UM), the Kalman data-association baseline (Kalman) and its SORT-like preset. Runs on
the synthetic default scene of ``--seed`` (written to ``OUT/scene``) unless ``--sequence
SEQ_DIR`` is given, and, unless ``--quick``, also on every sequence under ``--mot-root``
(default ``../shared/data/mot15`` beside the repository) with pooled scores. Writes
``comparison.csv``, ``comparison.png`` and ``summary.md`` into ``--out``. All logic is in
:mod:`jaxtrack.experiments.comparison`.

    python experiments/compare_trackers.py --out /tmp/compare
    python experiments/compare_trackers.py --out /tmp/quick --quick
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from jaxtrack.experiments.common import experiment_parser, markdown_table, run_script
from jaxtrack.experiments.comparison import COMPARISON_COLUMNS, run_comparison

NAME = "compare_trackers.py"
#: The MOT15 training sequences beside the repository.
DEFAULT_MOT_ROOT = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "mot15"


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = experiment_parser(
        NAME,
        __doc__,
        quick_help="short smoke run (short synthetic scene, few particles, no --mot-root)",
    )
    parser.add_argument(
        "--mot-root",
        metavar="DIR",
        default=str(DEFAULT_MOT_ROOT),
        help="folder of sequence folders also compared (default: %(default)s)",
    )
    parser.add_argument("--no-mot", action="store_true", help="skip the --mot-root sequences")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    mot_root = None if args.quick or args.no_mot else args.mot_root

    def body() -> int:
        rows, files = run_comparison(args.out, args.seed, args.quick, args.sequence, mot_root)
        print(markdown_table(rows, COMPARISON_COLUMNS[:-1]))
        print("wrote " + ", ".join(str(path) for path in files))
        return 0

    return run_script(body, NAME)


if __name__ == "__main__":
    sys.exit(main())
