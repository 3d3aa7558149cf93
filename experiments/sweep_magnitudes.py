"""Magnitude sweep, PHD-context Fig. 15: MOTA/MOTP/MODA/MODP against lambda_r and lambda_s.

Learns context on the first half of a sequence (births from a UM tracker run, clutter from
the ground truth), then tracks the second half for every point of a log-spaced grid of
clutter magnitudes lambda_r (0.1..10 false detections per frame) and birth magnitudes
lambda_s (0.02..2 births per frame), 9 x 9 by default, with uniform intensities (UM) and with
the learned ones (GM): 162 tracker runs in one vmapped sweep sharded over all JAX devices.
Writes ``sweep.csv`` (every configuration), ``sweep.png`` (scores against each magnitude),
``sweep_mota.png`` (MOTA over the grid) and ``summary.md`` into ``--out``. Runs on the
synthetic default scene of ``--seed`` (written to ``OUT/scene``) unless ``--sequence
SEQ_DIR`` is given. All logic is in :mod:`jaxtrack.experiments.magnitudes`.

    python experiments/sweep_magnitudes.py --out /tmp/sweep
    python experiments/sweep_magnitudes.py --out /tmp/pets --sequence SEQ_DIR
    XLA_FLAGS=--xla_force_host_platform_device_count=2 python experiments/sweep_magnitudes.py ...
"""

from __future__ import annotations

import argparse
import json
import sys

from jaxtrack.experiments.common import experiment_parser, run_script
from jaxtrack.experiments.magnitudes import run_magnitude_sweep, sweep_summary

NAME = "sweep_magnitudes.py"


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = experiment_parser(
        NAME, __doc__, quick_help="short smoke run (short scene, few particles, 3 x 3)"
    )
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)

    def body() -> int:
        result, files = run_magnitude_sweep(
            args.out, args.seed, args.quick, args.sequence, progress=lambda step: print(step)
        )
        print(files[-1].read_text())
        print(json.dumps(sweep_summary(result), indent=2))
        print("wrote " + ", ".join(str(path) for path in files))
        return 0

    return run_script(body, NAME)


if __name__ == "__main__":
    sys.exit(main())
