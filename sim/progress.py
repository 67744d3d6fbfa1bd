"""Feedback on long work: progress bars, and one line before numba compiles the kernels.

Progress bars (tqdm) go to stderr, so that stdout stays clean for tables and ``--json``. A bar
shows only when stderr is a terminal: piped, redirected or captured output (CI, pytest, a log
file) gets no bar and no control characters. ``quiet=True`` (a command's ``--quiet``) and the
environment variable ``TQDM_DISABLE=1`` turn bars off everywhere.

The first run after an install or an edit compiles the numba kernels, which takes tens of
seconds (docs/performance.md). :func:`compile_notice` prints one line to stderr before that
happens, and only when it will happen (:func:`kernels_need_compiling`).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from types import ModuleType

from numba.extending import is_jitted
from tqdm import tqdm

COMPILE_MESSAGE = (
    "stereosim: compiling the cycle/functional kernels (first run only, about {seconds} s; "
    "cached afterwards)"
)


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


def cached_kernels(modules: Iterable[ModuleType]) -> dict[str, list]:
    """The numba dispatchers defined in each module with ``cache=True``, by module name."""
    out: dict[str, list] = {}
    for module in modules:
        found = [obj for obj in vars(module).values()
                 if is_jitted(obj) and obj.py_func.__module__ == module.__name__
                 and obj.stats.cache_path is not None]
        if found:
            out[module.__name__] = found
    return out


def index_file(kernel) -> Path:
    """Where numba keeps the cache index of a ``cache=True`` dispatcher:
    ``<cache dir>/<file stem>.<qualname>-<first line>.py<major><minor>.nbi`` (numba's naming;
    the cache dir is ``__pycache__`` beside the source, or under ``NUMBA_CACHE_DIR``)."""
    func = kernel.py_func
    stem = Path(func.__code__.co_filename).stem
    qualname = func.__qualname__.replace("<", "").replace(">", "")
    version = f"py{sys.version_info[0]}{sys.version_info[1]}"
    name = f"{stem}.{qualname}-{func.__code__.co_firstlineno}.{version}.nbi"
    return Path(kernel.stats.cache_path) / name


def _index_state(kernel) -> str:
    """``"fresh"`` (the cache index exists and is not older than the source file: numba drops
    an index whose source changed, and one written after the last edit is current),
    ``"stale"`` (it exists but is older) or ``"none"``."""
    try:
        index = index_file(kernel).stat()
    except OSError:
        return "none"
    try:
        source = os.stat(kernel.py_func.__code__.co_filename)
    except OSError:
        return "stale"
    return "fresh" if index.st_mtime >= source.st_mtime else "stale"


def _group_cold(kernels: dict[str, list]) -> bool:
    if any(k.signatures for found in kernels.values() for k in found):
        return False  # loaded in this process already
    states = [{_index_state(k) for k in found} for found in kernels.values()]
    if not states:
        return False
    stale = any("stale" in s and "fresh" not in s for s in states)
    return stale or all(s == {"none"} for s in states)


def kernels_need_compiling(groups: Iterable[Iterable[ModuleType]]) -> bool:
    """True when running the kernels of these groups of modules will compile them.

    A group is cold when none of its kernels is loaded in this process yet, and either no
    kernel of any of its modules has a cache index on disk (a new install, a new
    ``NUMBA_CACHE_DIR``), or when a module's indexes are all older than its source (an edit).
    A module that has no index at all inside a group that has some is not counted: numba
    writes no index for a kernel that only other kernels call, and a run compiles only the
    kernels it uses."""
    return any(_group_cold(cached_kernels(modules)) for modules in groups)


def compile_notice(groups: Iterable[Iterable[ModuleType]], seconds: int, stream=None) -> bool:
    """Print :data:`COMPILE_MESSAGE` (one line, stderr by default) when the kernels of these
    groups of modules are about to be compiled (:func:`kernels_need_compiling`); returns
    whether it printed. Once the kernels are loaded (or cached) the check is false, so the line
    appears once per process at most."""
    if not kernels_need_compiling(groups):
        return False
    # through tqdm, so that a bar already on the terminal (eval's) is redrawn below the line
    stream = sys.stderr if stream is None else stream
    tqdm.write(COMPILE_MESSAGE.format(seconds=seconds), file=stream)
    stream.flush()
    return True
