"""Gradient tuning versus a grid sweep of the clutter and birth magnitudes.

The same as ``jaxtrack experiment gradient-tuning`` (see its ``--help``; logic in
:mod:`jaxtrack.experiments`):

    python experiments/gradient_tuning.py --out /tmp/gradient-tuning --quick
"""

import sys

from jaxtrack.cli import main

if __name__ == "__main__":
    sys.exit(main(["experiment", "gradient-tuning", *sys.argv[1:]]))
