"""Gradient tuning versus a grid sweep of the clutter and birth magnitudes.

From mis-specified magnitudes (lambda_r = 10, lambda_s = 1), tunes the PHD tracker by adam on
the unsupervised PHD log-likelihood of a training span and compares it on the test span with
the best configuration of an 8x8 grid sweep (chosen by training MOTA): on the synthetic scene
of --seed (halves) and on PETS09-S2L1 (frames 1-400 / 401-795). Writes summary.csv,
steps.csv (loss and test MOTA per step), goals.csv, summary.md and gradient_tuning.png
(loss and MOTA against the step) into --out. All logic is in jaxtrack.experiments.tuning.

    python experiments/gradient_tuning.py --out /tmp/gt
    python experiments/gradient_tuning.py --out /tmp/gt-quick --quick
    python experiments/gradient_tuning.py --out /tmp/gt-synthetic --no-pets
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from jaxtrack.experiments.common import experiment_parser, markdown_table, run_script
from jaxtrack.experiments.tuning import SUMMARY_COLUMNS, gradient_tuning_experiment

NAME = "gradient_tuning.py"
PETS = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "mot15" / "PETS09-S2L1"


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = experiment_parser(
        NAME, __doc__, sequence=False, quick_help="short smoke run (short spans, 3x3 grid, 2 steps)"
    )
    parser.add_argument(
        "--pets", default=str(PETS), metavar="SEQ_DIR", help=f"PETS09-S2L1 folder (default {PETS})"
    )
    parser.add_argument("--no-pets", action="store_true", help="only the synthetic scene")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)

    def body() -> int:
        result = gradient_tuning_experiment(
            args.out, args.seed, args.quick, None if args.no_pets else args.pets
        )
        print(markdown_table(result["summary"], SUMMARY_COLUMNS))
        for goal in result["goals"]:
            print(
                f"{goal['dataset']}: tuned MOTA {goal['tuned_MOTA']:.2f} vs grid "
                f"{goal['grid_MOTA']:.2f} ({goal['tuned_vs_grid_percent']:.1f}%), "
                f"{goal['tuning_runs']} vs {goal['grid_runs']} runs: "
                f"goal {'met' if goal['met'] else 'NOT met'}"
            )
        print(
            f"wrote {args.out}/summary.csv, steps.csv, goals.csv, summary.md, gradient_tuning.png"
        )
        return 0

    return run_script(body, NAME)


if __name__ == "__main__":
    sys.exit(main())
