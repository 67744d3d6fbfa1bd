"""A GTKWave save file (``.gtkw``) that opens a stereosim dump ready to read, written with pyvcd's
:class:`vcd.gtkw.GTKWSave`.

What the save file sets up:

* **The dump.** ``[dumpfile]`` holds the path the caller gives. ``stereosim run`` gives the dump's
  absolute path, resolved when the files are written, so ``gtkwave out/t.gtkw`` works from any
  folder; the golden test gives a bare file name, so its bytes do not depend on where it runs.
  A VCD and an FST dump get the same save file (GTKWave names their variables alike).
* **The window, zoomed to fit.** The GTKWave window has a fixed size (``[size]``), the signal
  name pane a fixed width (``[signals_width]``) and the signal search tree is folded away, so
  the wave pane is about 1036 pixels wide (GTKWave 3.3.118, GTK 3). GTKWave shows
  ``2 ** -zoom / 200`` dump time units (fs) per pixel (measured: the grid of a screenshot and
  GTKWave's Tcl ``getWindowEndTime`` agree), so the zoom that fits the window
  ``[start_fs, end_fs)`` across :data:`WAVE_WIDTH_PX` pixels -- a little less than the pane,
  so that a slightly narrower pane still shows the end -- is
  ``log2(WAVE_WIDTH_PX / (200 * (end_fs - start_fs)))``, rounded down to 1/1000;
  ``[timestart]`` is the window's start.
* **Unique, readable names.** Every trace has an alias: its path without the leading ``top.``,
  with ``/`` between the levels, as in ModelSim's wave window (``nna/left/sub0/status``,
  ``fifo/nna_left_to_sva/occupancy``, ``clocks/sva``). Not dots: GTKWave 3.3 shows only the
  last dot-separated level of a name by default (``hier_max_level``, which a save file cannot
  set), so ``nna.left.sub0.status`` and ``nna.right.sub0.status`` would both read ``status``.
  If dropping ``top.`` would make two aliases equal, the full paths are used.
* **One group per block.** The clocks first, then one group per block in the order the log
  declares them, labelled like the aliases. A signal belongs to the nearest enclosing scope
  that has a ``status`` signal (``top.nna.left.sub0.line_buffer.fill`` is in block
  ``nna/left/sub0``), else to its own scope (``top.fifo.nna_left_to_sva.push`` is in
  ``fifo/nna_left_to_sva``).
* **Formats.** 1-bit wires in binary; counts -- rows, columns, fill levels, occupancies, words,
  counters (:data:`COUNT_NAMES`) -- in decimal; other vectors (descriptors, costs) in hex.
  ``status`` signals are shown in decimal through a translate filter file
  (:func:`status_filter_text`) that names the kernel's four activities: 0 idle, 1 busy (green),
  2 starved (orange: waits for data), 3 blocked (red: waits for space). The filter file is a
  separate file; its path is written like the dump's.

The same log, paths and GTKWave size give the same bytes (no date, no file size, no mtime).
"""

from __future__ import annotations

import io
import math
import os

from vcd.gtkw import GTKWSave, make_translation_filter

from stereosim.core.errors import ConfigError
from stereosim.core.outputs import atomic_write_bytes
from stereosim.traces.log import CLOCK_SCOPE, TraceLog, validate

#: The names and GTKWave colours of the status codes 0..3, as the chip traces them
#: (sim.cycle.plan.STATUS_CODES); the timeline and the wave picture read them from here.
STATUS_NAMES = ("idle", "busy", "starved", "blocked")
STATUS_COLOURS = (None, "green", "orange", "red")
STATUS_SUFFIX = ".status"

#: The last path components of signals that count something, shown in decimal.
COUNT_NAMES = frozenset({
    "row", "rows", "row_in", "row_out", "rows_ready", "col", "cols", "column", "columns",
    "fill", "occupancy", "count", "sent", "pixels_sent", "words", "phase", "disparity",
})

#: GTKWave's window and its signal name pane (the wave pane they leave is 1036 pixels wide in
#: GTKWave 3.3.118; tests/traces/test_gtkwave_screenshot.py checks the fit), and the width the
#: window is fitted to.
WINDOW_PX = (1400, 900)
SIGNALS_WIDTH_PX = 300
WAVE_WIDTH_PX = 1000
#: GTKWave draws ``2 ** -zoom / PIXELS_PER_FRAME`` time units per pixel.
PIXELS_PER_FRAME = 200


def unit_of(path: str) -> str:
    """The unit a signal belongs to: the first two components of its path (``top.nna``), or the
    first one for a two-component path."""
    parts = path.split(".")
    return ".".join(parts[:2]) if len(parts) > 2 else parts[0]


def trace_name(path: str, width: int) -> str:
    """The name GTKWave gives a variable written by :mod:`traces.vcd` (vectors with their
    range, ``top.nna.left.sub0.line_buffer.fill[3:0]``)."""
    return path if width == 1 else f"{path}[{width - 1}:0]"


def datafmt_of(path: str, width: int) -> str:
    """How GTKWave shows a signal: ``bin`` for a wire, ``dec`` for a status or a count, ``hex``
    for other vectors."""
    if width == 1:
        return "bin"
    name = path.rsplit(".", 1)[-1]
    return "dec" if name in COUNT_NAMES or path.endswith(STATUS_SUFFIX) else "hex"


def block_of(path: str, blocks: set[str]) -> str:
    """The block a signal belongs to: the nearest enclosing scope in ``blocks`` (the scopes that
    have a status signal), else the signal's own scope."""
    parts = path.split(".")
    for k in range(len(parts) - 1, 0, -1):
        scope = ".".join(parts[:k])
        if scope in blocks:
            return scope
    return ".".join(parts[:-1])


def aliases(paths: list[str]) -> list[str]:
    """The names shown for ``paths``: without a leading ``top.`` when that keeps them unique,
    with ``/`` between the levels (``top.nna.left.sub0.status`` -> ``nna/left/sub0/status``)."""
    short = [p.removeprefix("top.") for p in paths]
    chosen = short if len(set(short)) == len(short) else list(paths)
    return [p.replace(".", "/") for p in chosen]


def zoom_to_fit(start_fs: int, end_fs: int, wave_width_px: int = WAVE_WIDTH_PX) -> float:
    """GTKWave's zoom that shows ``[start_fs, end_fs)`` across ``wave_width_px`` pixels,
    rounded down to 1/1000 so the whole window fits."""
    fs_per_px = (end_fs - start_fs) / wave_width_px
    return math.floor(-math.log2(fs_per_px * PIXELS_PER_FRAME) * 1000) / 1000


def status_filter_text() -> str:
    """The translate filter file for ``status`` signals shown in decimal."""
    rows = [(code, name) if colour is None else (code, name, colour)
            for code, (name, colour) in enumerate(zip(STATUS_NAMES, STATUS_COLOURS))]
    return make_translation_filter(rows, datafmt="dec") + "\n"


def has_status(log: TraceLog) -> bool:
    """Does the log hold a ``status`` signal (so the save file needs the filter file)?"""
    return any(s.path.endswith(STATUS_SUFFIX) for s in log.signals)


def _check_path(what: str, path) -> str:
    if not isinstance(path, str) or not path or '"' in path or "\n" in path:
        raise ConfigError(f"GTKWave {what} name {path!r} must be a path without quotes")
    return path


def gtkw_text(log: TraceLog, dumpfile: str, filter_file: str | None = None) -> str:
    """The save file for the dump of ``log`` stored at ``dumpfile``; ``filter_file`` is where
    :func:`status_filter_text` is stored (needed when the log has a status signal). Both paths
    are written as given."""
    validate(log)
    _check_path("dump file", dumpfile)
    if has_status(log):
        if filter_file is None:
            raise ConfigError("the log has status signals: give the translate filter file's path")
        _check_path("filter file", filter_file)
    out = io.StringIO()
    save = GTKWSave(out)
    save.comment("stereosim trace view: clocks, then one group per block; zoomed to the window")
    save.dumpfile(dumpfile, abspath=False)
    save.size(*WINDOW_PX)
    save.signals_width(SIGNALS_WIDTH_PX)
    save.sst_expanded(False)
    save.timestart(log.start_fs)
    save.zoom_markers(zoom_to_fit(log.start_fs, log.end_fs))
    for top in sorted({sig.path.split(".")[0] for sig in log.signals}):
        save.treeopen(top)

    rows = [(f"{CLOCK_SCOPE}.{c.name}", 1) for c in log.clocks]
    rows += [(s.path, s.width) for s in log.signals]
    names = aliases([p for p, _ in rows])
    blocks = {s.path[: -len(STATUS_SUFFIX)] for s in log.signals
              if s.path.endswith(STATUS_SUFFIX)}
    groups: dict[str, list[tuple[str, int, str]]] = {}
    for (path, width), alias in zip(rows, names):
        group = CLOCK_SCOPE if path.startswith(CLOCK_SCOPE + ".") else block_of(path, blocks)
        groups.setdefault(group, []).append((path, width, alias))
    group_names = aliases(list(groups))
    for members, label in zip(groups.values(), group_names):
        with save.group(label):
            for path, width, alias in members:
                status = path.endswith(STATUS_SUFFIX) and width > 1
                save.trace(trace_name(path, width), alias=alias, datafmt=datafmt_of(path, width),
                           translate_filter_file=filter_file if status else None)
    return out.getvalue()


def write_gtkw(path: str | os.PathLike, log: TraceLog, dumpfile: str | os.PathLike,
               filter_file: str | os.PathLike | None = None) -> None:
    """Write the save file atomically; ``dumpfile`` and ``filter_file`` are written into it as
    given (write the filter file itself with :func:`write_status_filter`)."""
    filt = None if filter_file is None else os.fspath(filter_file)
    atomic_write_bytes(path, gtkw_text(log, os.fspath(dumpfile), filt).encode("ascii"))


def write_status_filter(path: str | os.PathLike) -> None:
    """Write the translate filter file of :func:`status_filter_text` atomically."""
    atomic_write_bytes(path, status_filter_text().encode("ascii"))
