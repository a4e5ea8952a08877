"""``python -m asperity_sim``: the ``asperity-sim`` command line (:mod:`asperity_sim.cli`)."""

import sys

from .cli import main

sys.exit(main())
