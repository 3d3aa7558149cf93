"""Context ablation, PHD-context Fig. 14: UM, GM and A1-A6 on the same test span.

Learns context on the first half of a sequence (births from a UM tracker run, and for A6
from the ground truth; clutter from the ground truth), tracks the second half with every
variant and writes ``ablation.csv``, ``ablation.png`` (bars of the MOTA/MOTP/MODA/MODP %
difference w.r.t. UM) and ``summary.md`` into ``--out``. Runs on the synthetic default scene
of ``--seed`` (written to ``OUT/scene``) unless ``--sequence SEQ_DIR`` is given. All logic
is in :mod:`jaxtrack.experiments.ablation`.

    python experiments/context_ablation.py --out /tmp/ablation
    python experiments/context_ablation.py --out /tmp/pets --sequence SEQ_DIR
"""

from __future__ import annotations

import argparse
import sys

from jaxtrack.experiments.ablation import ABLATION_COLUMNS, run_ablation
from jaxtrack.experiments.common import experiment_parser, markdown_table, run_script

NAME = "context_ablation.py"


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = experiment_parser(
        NAME, __doc__, quick_help="short smoke run (short scene, few particles)"
    )
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)

    def body() -> int:
        result, files = run_ablation(
            args.out, args.seed, args.quick, args.sequence, progress=lambda step: print(step)
        )
        print(markdown_table(result.rows, ABLATION_COLUMNS))
        print("wrote " + ", ".join(str(path) for path in files))
        return 0

    return run_script(body, NAME)


if __name__ == "__main__":
    sys.exit(main())
