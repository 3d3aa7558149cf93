"""The Hierarchical low level on the development split: a priori vs estimated noise.

The same as ``jaxtrack experiment hierarchical-noise`` (see its ``--help``; logic in
:mod:`jaxtrack.experiments.hierarchical_noise`):

    python experiments/hierarchical_noise.py --out /tmp/noise
    python experiments/hierarchical_noise.py --out /tmp/noise-quick --quick
"""

import sys

from jaxtrack.cli import main

if __name__ == "__main__":
    sys.exit(main(["experiment", "hierarchical-noise", *sys.argv[1:]]))
