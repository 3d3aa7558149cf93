"""CMT: COM against EWOM on the scripted crossings, by how alike the pair dress (issue 17's
SE goal; Cui et al. Sec. VI, Fig. 9).

The same as ``jaxtrack experiment cmt-crossings`` (see its ``--help``; logic in
:mod:`jaxtrack.experiments.cmt_crossings`):

    python experiments/cmt_crossings.py --out /tmp/crossings
    python experiments/cmt_crossings.py --out /tmp/crossings-quick --quick
"""

import sys

from jaxtrack.cli import main

if __name__ == "__main__":
    sys.exit(main(["experiment", "cmt-crossings", *sys.argv[1:]]))
