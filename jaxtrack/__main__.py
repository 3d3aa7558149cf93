"""``python -m jaxtrack`` is the ``jaxtrack`` command."""

import sys

from jaxtrack.cli import main

sys.exit(main())
