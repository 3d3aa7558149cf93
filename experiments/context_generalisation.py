"""Does learned context generalise? UM, GM, A1-A6 and GM+tuned on held-out scenes (issue 15).

The same as ``jaxtrack experiment context-generalisation`` (see its ``--help``; logic in
:mod:`jaxtrack.experiments.context_generalisation`):

    python experiments/context_generalisation.py --out /tmp/cg
"""

import sys

from jaxtrack.cli import main

if __name__ == "__main__":
    sys.exit(main(["experiment", "context-generalisation", *sys.argv[1:]]))
