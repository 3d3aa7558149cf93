"""UM vs GM on the scene bank's families: learned context on held-out kinds of scene.

The same as ``jaxtrack experiment context-gap`` (see its ``--help``; logic in
:mod:`jaxtrack.experiments.context_gap`):

    python experiments/context_gap.py --out /tmp/context-gap --quick
"""

import sys

from jaxtrack.cli import main

if __name__ == "__main__":
    sys.exit(main(["experiment", "context-gap", *sys.argv[1:]]))
