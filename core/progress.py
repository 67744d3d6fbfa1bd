"""Feedback on long work: progress bars, and a notice while numba compiles the kernels.

Progress bars (tqdm) go to stderr, so that stdout stays clean for tables and ``--json``. A bar
shows only when stderr is a terminal: piped, redirected or captured output (CI, pytest, a log
file) gets no bar and no control characters. ``quiet=True`` (a command's ``--quiet``) and the
environment variable ``TQDM_DISABLE=1`` turn bars off everywhere.

The first run after an install or an edit compiles the numba kernels it uses, which takes
from seconds to minutes (docs/performance.md); a later command that needs others compiles
those (the first ``--vcd`` run the trace writers', say), and the notice says so again.
Inside :func:`compile_notice` numba's own compile events are watched: once compiling has
taken a second, one line on stderr says so (while it compiles), and the end of the block
prints how long compiling took and how many kernels it compiled. What is announced is
therefore exactly what the run compiles -- every ``@njit`` module, the stages', both
engines', the trace writers' -- with no list of modules to keep up to date, and nothing is
printed when every kernel comes from numba's cache (or a few kernels compile in a moment).
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import threading
import time
from collections.abc import Callable, Iterator

from numba.core import event
from tqdm import tqdm

# each kernel compiles when a command first calls it: a first run compiles the engine's, the
# first traced run after it the trace writers' (traces/vcd.py), and so on
COMPILE_MESSAGE = (
    "stereosim: compiling numba kernels (each once after an install or an edit, by the first "
    "command that needs it; cached afterwards)"
)
COMPILED_MESSAGE = "stereosim: compiling took {seconds:.1f} s ({kernels} numba kernels)"
# the closing line when a helper process compiled some of them at the same time
COMPILED_WITH_HELPER = ("stereosim: compiling took {seconds:.1f} s ({kernels} numba kernels, "
                        "{helper} of them in a helper process at the same time)")
# compiling shorter than this in all is not announced (a kernel of a new signature, say)
COMPILE_NOTICE_DELAY_S = 1.0


def show_progress(quiet: bool = False, stream=None) -> bool:
    """True when a progress bar should be drawn on ``stream`` (default stderr): not ``quiet``,
    not switched off by ``TQDM_DISABLE``, and the stream is a terminal."""
    if quiet or os.environ.get("TQDM_DISABLE", "").strip().lower() in ("1", "true", "yes"):
        return False
    stream = sys.stderr if stream is None else stream
    isatty = getattr(stream, "isatty", None)
    try:
        return bool(isatty is not None and isatty())
    except (OSError, ValueError):  # a closed or detached stream
        return False


def progress_bar(total: int | None, desc: str, unit: str, *, quiet: bool = False,
                 initial: int = 0) -> tqdm:
    """A tqdm bar on stderr with rate and ETA, disabled by :func:`show_progress`'s rules.
    Use it as a context manager or close it."""
    return tqdm(total=total, desc=desc, unit=unit, initial=initial, file=sys.stderr,
                disable=not show_progress(quiet), dynamic_ncols=True, smoothing=0.1)


def poller(bar: tqdm, count: Callable[[], int]) -> Callable[[], None] | None:
    """A callback that moves ``bar`` to ``count()``, for a loop that reports now and then
    (None when the bar is disabled, so the loop need not call anything)."""
    if bar.disable:
        return None

    def poll() -> None:
        bar.update(count() - bar.n)

    return poll


# ---- the compile notice -------------------------------------------------------------------------


class CompileWatch(event.Listener):
    """Listens to numba's ``numba:compile`` events: adds up the time of the outermost compiles
    (a kernel compiles the kernels it calls inside its own event) and counts the kernels
    compiled (one per function and signature). Once ``delay_s`` seconds of compiling have
    passed -- while a kernel compiles -- it announces the compile on ``stream`` (stderr by
    default); a few short compiles stay silent. A timer thread says it in time, since a
    single kernel may compile for many seconds."""

    def __init__(self, stream=None, delay_s: float = COMPILE_NOTICE_DELAY_S):
        self.stream = stream
        self.delay_s = delay_s
        self.seconds = 0.0
        self.kernels: set[tuple] = set()
        self.helper_kernels: set[tuple] = set()
        self.announced = False
        self._depth = 0
        self._since = 0.0
        self._timer: threading.Timer | None = None
        self._lock = threading.Lock()

    def _write(self, line: str) -> None:
        stream = sys.stderr if self.stream is None else self.stream
        # through tqdm, so that a bar already on the terminal (eval's) is redrawn below the line
        tqdm.write(line, file=stream)
        stream.flush()

    def _announce(self) -> None:
        with self._lock:
            if self._depth > 0 and not self.announced:
                self.announced = True
                self._write(COMPILE_MESSAGE)

    def on_start(self, ev) -> None:
        func = ev.data["dispatcher"].py_func
        with self._lock:
            self.kernels.add((func.__module__, func.__qualname__, str(ev.data["args"])))
            self._depth += 1
            if self._depth > 1:
                return
            self._since = time.perf_counter()
            left = self.delay_s - self.seconds
        if self.announced:
            return
        if left <= 0:
            self._announce()
        elif math.isfinite(left):  # an infinite delay (a silent watch) needs no timer
            self._timer = threading.Timer(left, self._announce)
            self._timer.daemon = True
            self._timer.start()

    def on_end(self, ev) -> None:
        with self._lock:
            self._depth -= 1
            if self._depth > 0:
                return
            self.seconds += time.perf_counter() - self._since
            timer, self._timer = self._timer, None
        if timer is not None:
            timer.cancel()

    def add_helper(self, kernels: set[tuple], waited_s: float) -> None:
        """Count the ``kernels`` a helper process compiled for this run
        (:mod:`sim.cycle.compiled.prewarm`) and the ``waited_s`` seconds this process waited
        for it after its own compiles: compiling time too, said as such."""
        with self._lock:
            self.helper_kernels |= kernels
            self.kernels |= kernels
            self.seconds += waited_s
            late = not self.announced and self.kernels and self.seconds >= self.delay_s
            self.announced = self.announced or bool(late)
        if late:  # (this process compiled too little to have said it)
            self._write(COMPILE_MESSAGE)

    def report(self) -> None:
        """The closing line, when the compile was announced."""
        if not self.announced:
            return
        if self.helper_kernels:
            self._write(COMPILED_WITH_HELPER.format(seconds=self.seconds,
                                                    kernels=len(self.kernels),
                                                    helper=len(self.helper_kernels)))
        else:
            self._write(COMPILED_MESSAGE.format(seconds=self.seconds, kernels=len(self.kernels)))


_open = threading.local()  # the outermost open notice of this thread (.watch)


def current_watch() -> CompileWatch | None:
    """The compile notice open in this thread (None outside one)."""
    return getattr(_open, "watch", None)


@contextlib.contextmanager
def compile_notice(stream=None, delay_s: float = COMPILE_NOTICE_DELAY_S
                   ) -> Iterator[CompileWatch]:
    """Within the block, numba compiling for more than ``delay_s`` seconds in all prints
    :data:`COMPILE_MESSAGE` (one line, stderr by default) while it compiles, and leaving the
    block then prints :data:`COMPILED_MESSAGE` with the time spent compiling and the kernels
    compiled -- nothing at all when every kernel came from the cache or compiling was brief.
    A block inside another one reports through the outer one, so a command gets one pair of
    lines. Usable as a decorator."""
    outer = getattr(_open, "watch", None)
    if outer is not None:
        yield outer
        return
    watch = _open.watch = CompileWatch(stream, delay_s)
    try:
        with event.install_listener("numba:compile", watch):
            yield watch
    finally:
        _open.watch = None
        timer = watch._timer
        if timer is not None:  # (an exception out of a compile)
            timer.cancel()
        watch.report()
