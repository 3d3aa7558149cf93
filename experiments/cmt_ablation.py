"""CMT ablation (Cui et al., Sec. VII, Fig. 8, Fig. 9): MTb vs MTb+CPD vs CMT, PHD and Kalman.

The same as ``jaxtrack experiment cmt-ablation`` (see its ``--help``; logic in
:mod:`jaxtrack.experiments.cmt_ablation`):

    python experiments/cmt_ablation.py --out /tmp/cmt
    python experiments/cmt_ablation.py --out /tmp/cmt-quick --quick
"""

import sys

from jaxtrack.cli import main

if __name__ == "__main__":
    sys.exit(main(["experiment", "cmt-ablation", *sys.argv[1:]]))
