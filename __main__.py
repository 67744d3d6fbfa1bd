"""``python -m stereosim``: the ``stereosim`` command line (its console entry, which installs
the signal handler before the heavy imports)."""

import sys

from stereosim.sim.console import main

sys.exit(main())
