"""Context ablation, PHD-context Fig. 14: UM, GM and A1-A6 on the same test span.

The same as ``jaxtrack experiment context-ablation`` (see its ``--help``; logic in
:mod:`jaxtrack.experiments`):

    python experiments/context_ablation.py --out /tmp/context-ablation --quick
"""

import sys

from jaxtrack.cli import main

if __name__ == "__main__":
    sys.exit(main(["experiment", "context-ablation", *sys.argv[1:]]))
