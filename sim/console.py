"""The ``stereosim`` console entry (also ``python -m stereosim``).

It installs the signal handler (:mod:`core.signals`) before it imports the command line, whose
modules (numba, OpenCV, the cycle model) take a second or more to load: a SIGTERM or Ctrl-C in
that time ends the process with its one line (``stereosim: terminated``, exit 143) instead of a
silent death or a traceback. The handler stays installed until the process exits, so a signal
that comes once the command's outcome is decided changes nothing.
"""

from __future__ import annotations

import sys

from stereosim.core import signals


def main(argv: list[str] | None = None) -> int:
    """Run one command (``argv``: the arguments, default ``sys.argv[1:]``); the exit status."""
    return signals.entry(lambda: _command(argv))


def _command(argv: list[str] | None) -> int:
    # the handler is in: importing the command line loads numba and OpenCV
    import stereosim.sim.cli

    return stereosim.sim.cli.main(argv)


if __name__ == "__main__":
    sys.exit(main())
