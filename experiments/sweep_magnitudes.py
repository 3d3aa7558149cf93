"""Magnitude sweep, PHD-context Fig. 15: MOTA/MOTP/MODA/MODP against lambda_r and lambda_s.

The same as ``jaxtrack experiment sweep-magnitudes`` (see its ``--help``; logic in
:mod:`jaxtrack.experiments`):

    python experiments/sweep_magnitudes.py --out /tmp/sweep-magnitudes --quick
"""

import sys

from jaxtrack.cli import main

if __name__ == "__main__":
    sys.exit(main(["experiment", "sweep-magnitudes", *sys.argv[1:]]))
