"""``python -m asperity_sim``: the ``asperity-sim`` command line (:mod:`asperity_sim.ui.cli`)."""

import sys

from .ui.cli import main

sys.exit(main())
