"""The Fusion tracker (SPEC section 3): the paper's Table 1 ablation and Table 4 row.

The same as ``jaxtrack experiment fusion`` (see its ``--help``; logic in
:mod:`jaxtrack.experiments.fusion`):

    python experiments/fusion.py --out /tmp/fusion
    python experiments/fusion.py --out /tmp/fusion-quick --quick
"""

import sys

from jaxtrack.cli import main

if __name__ == "__main__":
    sys.exit(main(["experiment", "fusion", *sys.argv[1:]]))
