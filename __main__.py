"""``python -m stereosim``: the ``stereosim`` command line."""

import sys

from stereosim.sim.cli import main

sys.exit(main())
