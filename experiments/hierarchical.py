"""The Hierarchical tracker (SPEC section 4): Kalman bank vs managed low level vs both levels.

The same as ``jaxtrack experiment hierarchical`` (see its ``--help``; logic in
:mod:`jaxtrack.experiments.hierarchical`):

    python experiments/hierarchical.py --out /tmp/hier
    python experiments/hierarchical.py --out /tmp/hier-quick --quick
"""

import sys

from jaxtrack.cli import main

if __name__ == "__main__":
    sys.exit(main(["experiment", "hierarchical", *sys.argv[1:]]))
