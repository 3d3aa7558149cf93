"""Tracker comparison, PHD-context Fig. 16: PHD-context vs data association.

The same as ``jaxtrack experiment compare-trackers`` (see its ``--help``; logic in
:mod:`jaxtrack.experiments`):

    python experiments/compare_trackers.py --out /tmp/compare-trackers --quick
"""

import sys

from jaxtrack.cli import main

if __name__ == "__main__":
    sys.exit(main(["experiment", "compare-trackers", *sys.argv[1:]]))
