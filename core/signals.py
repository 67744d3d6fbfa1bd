"""SIGINT, SIGTERM and SIGHUP while a command runs (the promises of docs/reliability.md).

A command's :class:`Handler` turns these signals into exceptions in the main thread --
``KeyboardInterrupt`` for SIGINT, :class:`Terminated` for SIGTERM and SIGHUP -- so that every
``finally`` runs (staging folders and half-made folders are removed) and the command line exits
128 + the signal's number with one line (:func:`exit_line`). Three more rules close the gaps a
plain handler leaves:

* :func:`held` blocks the signals for a stretch that must not be cut: :func:`core.outputs.publish`
  holds them from the moment it switches a set until its clean-up is done, so a signal lands
  before the switch (the old set stays) or after it (the new set is complete, which
  :func:`note_published` records and the exit line says).
* :meth:`Handler.settle`: once a command's outcome is decided (its status, or its one-line
  error), a signal no longer interrupts it; the process exits with that outcome instead of a
  traceback or a silent death.
* A signal whose exception is raised inside a finalizer (a ``__del__`` or a weakref callback
  that Python runs between two bytecodes of the command: llvmlite frees its objects so) cannot
  propagate: Python would print "Exception ignored ..." with a traceback and go on. The hook
  :class:`_Unraisable` keeps it instead (``Handler.swallowed``) and prints nothing, and the command
  line ends the command with its one line (:func:`swallowed`).
* :func:`install` is idempotent: the console entry (:mod:`sim.console`) installs the handler
  before it imports the heavy modules (numba, OpenCV), the command reuses it, and it stays in
  place until the process exits.
* The interpreter's shutdown: once the handler is settled, the process's exit (an ``atexit``
  callback, :func:`_at_exit`) ignores :data:`HELD` for the rest of its life -- Python puts the
  default action back while it finalizes, and a SIGTERM in that stretch (numba's and llvmlite's
  objects are freed then) killed a process whose outcome was decided, without its status --
  and the unraisable hook keeps the settled handler, so a finalizer that fails in that
  stretch after a signal stopped the command still prints nothing ("Exception ignored in ..."
  after the signal's line).
* :func:`entry` installs it *inside* the ``try`` that turns a signal into its line: a signal that
  lands the moment the handler is in -- before the command's own ``try`` is entered -- still
  ends the process with its one line, never a traceback and exit 1.

Only the standard library is imported here: the console entry needs this module before anything
else.
"""

from __future__ import annotations

import atexit
import contextlib
import signal
import sys
from collections.abc import Callable, Iterator

HELD = frozenset({signal.SIGINT, signal.SIGTERM, signal.SIGHUP})
_WORDS = {signal.SIGINT: "interrupted", signal.SIGTERM: "terminated", signal.SIGHUP: "hung up"}


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised in the main thread so that clean-up runs."""

    def __init__(self, signum: int = signal.SIGTERM):
        super().__init__(signum)
        self.signum = signum


class Handler:
    """The handler of :data:`HELD` while a command runs: raises until :meth:`settle`, and
    keeps a signal for the end of a :func:`held` stretch; ``published`` says whether a set of
    outputs was switched in (:func:`note_published`)."""

    def __init__(self):
        self.settled = False
        self.published = False
        self.holding = 0  # nested held() stretches
        self.pending: int | None = None
        self.swallowed: KeyboardInterrupt | None = None  # raised inside a finalizer
        self.raised = False  # a signal was raised: the command is being stopped by it

    def __call__(self, signum, frame):
        if self.settled:  # the outcome is decided: the process exits with it
            return
        if self.holding:  # another thread took the signal: it waits for the stretch's end
            self.pending = self.pending or signum
            return
        self.raised = True
        if signum == signal.SIGINT:
            raise KeyboardInterrupt
        raise Terminated(signum)

    def settle(self) -> None:
        """From now on a signal is ignored: the command's outcome is decided."""
        self.settled = True


def current() -> Handler | None:
    """The installed :class:`Handler`, or None."""
    handler = signal.getsignal(signal.SIGTERM)
    return handler if isinstance(handler, Handler) else None


def install() -> Handler | None:
    """Install a :class:`Handler` on :data:`HELD` for the rest of the process, or return the one
    installed already; None outside the main thread (where signals cannot be caught)."""
    handler = current()
    if handler is not None:
        return handler
    handler = Handler()
    try:
        for signum in HELD:
            signal.signal(signum, handler)
    except ValueError:  # not the main thread
        return None
    if not isinstance(sys.unraisablehook, _Unraisable):
        sys.unraisablehook = _Unraisable(sys.unraisablehook)
        atexit.register(_at_exit)
    return handler


def entry(command: Callable[[], int]) -> int:
    """A process's entry: install the :class:`Handler` for the rest of the process and run
    ``command``; its status, or 128 + the signal's number with the signal's one line on stderr
    when a signal lands outside the command's own handling (between the handler's install and
    the command's ``try``; during the imports of a console entry)."""
    try:
        install()
        status = command()
        handler = current()
        if handler is not None:
            handler.settle()  # the status is decided: a signal no longer changes it
        return status
    except KeyboardInterrupt as exc:
        handler = current()
        if handler is not None:
            handler.settle()
        status, line = exit_line(exc, handler is not None and handler.published)
        print(line, file=sys.stderr)
        return status


class _Unraisable:
    """``sys.unraisablehook`` while a :class:`Handler` is installed: the exception of a signal
    raised inside a finalizer is kept in the handler (``swallowed``), silently; so is, silently,
    a finalizer's failure once a signal is stopping the command (llvmlite's objects, left half
    made by a compile the signal cut, fail as they are freed: "Exception ignored in
    ObjectRef.__del__" after the signal's line); anything else goes to the hook it replaced."""

    def __init__(self, previous):
        self.previous = previous
        self.ending: Handler | None = None  # the settled handler of a process that exits

    def __call__(self, unraisable) -> None:
        # (no module global is looked up first: late in the shutdown they may be gone)
        handler = self.ending if self.ending is not None else current()
        if handler is not None and isinstance(unraisable.exc_value, KeyboardInterrupt):
            handler.swallowed = handler.swallowed or unraisable.exc_value
            return
        if handler is not None and handler.raised:
            return
        self.previous(unraisable)


def _at_exit() -> None:
    """The process exits (``atexit``): if its handler is settled, its outcome is decided, and
    :data:`HELD` are ignored from now on -- Python's finalization would otherwise put their
    default action back before it frees the last objects, and a signal then would kill the
    process without its status. The unraisable hook keeps the handler, which the signal
    module no longer returns."""
    handler = current()
    if handler is None or not handler.settled:
        return
    for signum in HELD:
        signal.signal(signum, signal.SIG_IGN)
    if isinstance(sys.unraisablehook, _Unraisable):
        sys.unraisablehook.ending = handler


def swallowed() -> KeyboardInterrupt | None:
    """The signal's exception that a finalizer swallowed while the command ran, or None."""
    handler = current()
    return None if handler is None else handler.swallowed


@contextlib.contextmanager
def handling() -> Iterator[Handler | None]:
    """A :class:`Handler` for the duration: the installed one if there is one (then it stays),
    else a new one, and the previous handlers put back at the end (for callers of ``main`` in
    their own process)."""
    if current() is not None:
        yield current()
        return
    previous = {signum: signal.getsignal(signum) for signum in HELD}
    handler = install()
    try:
        yield handler
    finally:
        if handler is not None:
            for signum, old in previous.items():
                signal.signal(signum, signal.SIG_DFL if old is None else old)


@contextlib.contextmanager
def held() -> Iterator[None]:
    """Hold :data:`HELD` back for the duration; one that arrives meanwhile is delivered at the
    end. Blocking them covers this thread; a signal another thread takes (numpy's BLAS,
    torch's and tqdm's threads do not block them) reaches the installed :class:`Handler`, which
    keeps it."""
    handler = current()
    old = signal.pthread_sigmask(signal.SIG_BLOCK, HELD)
    if handler is not None:
        handler.holding += 1
    try:
        yield
    finally:
        if handler is not None:
            handler.holding -= 1
        signal.pthread_sigmask(signal.SIG_SETMASK, old)  # a blocked signal is delivered here
        if handler is not None and not handler.holding and handler.pending is not None:
            signum, handler.pending = handler.pending, None
            handler(signum, None)


def note_published() -> None:
    """Record that a set of outputs was switched in (read by :func:`exit_line`)."""
    handler = current()
    if handler is not None:
        handler.published = True


def exit_line(exc: KeyboardInterrupt, published: bool) -> tuple[int, str]:
    """The exit status (128 + the signal's number) and the one line of a command stopped by
    ``exc``; ``published``: its outputs were written, complete, before the signal came."""
    signum = getattr(exc, "signum", signal.SIGINT)
    line = f"stereosim: {_WORDS[signum]}"
    if published:
        line += " after writing its outputs (they are complete)"
    return 128 + signum, line
