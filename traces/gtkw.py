"""A GTKWave save file (``.gtkw``) that opens a stereosim VCD with sensible groups.

The file references the VCD (``[dumpfile]``, relative to where GTKWave is started, so keep the
two files side by side and start GTKWave in their folder), starts the view at the window's start
(``[timestart]``, in the VCD's 1 fs unit) and lists the traces in groups: the clocks first,
then one group per unit -- the first two components of the signal path, ``top.cameras``,
``top.nna``, ``top.fifo``, ``top.sva`` -- in the order the log declares them. Each group is
opened with ``@800200`` and a ``-name`` comment line and closed with ``@1000200`` and the same
comment line; each trace is preceded by its display flags: ``@28`` (binary, for 1-bit wires)
or ``@22`` (hexadecimal, for vectors). Trace names are the full hierarchical names GTKWave gives
the VCD's variables: ``top.nna.left.valid``, and vectors with their range,
``top.nna.left.fill[15:0]``. No absolute path, date or window size is written, so the file is
byte-identical for identical input.
"""

from __future__ import annotations

import os

from sim.errors import ConfigError
from sim.outputs import atomic_write_bytes
from traces.log import CLOCK_SCOPE, TraceLog, validate

GROUP_OPEN, GROUP_CLOSE = "@800200", "@1000200"
FLAG_BINARY, FLAG_HEX = "@28", "@22"


def unit_of(path: str) -> str:
    """The unit a signal belongs to: the first two components of its path (``top.nna``), or the
    first one for a two-component path."""
    parts = path.split(".")
    return ".".join(parts[:2]) if len(parts) > 2 else parts[0]


def trace_name(path: str, width: int) -> str:
    """The name GTKWave shows for a VCD variable written by :mod:`traces.vcd`."""
    return path if width == 1 else f"{path}[{width - 1}:0]"


def gtkw_text(log: TraceLog, dumpfile: str) -> str:
    """The save file for the VCD of ``log`` stored at ``dumpfile``."""
    validate(log)
    if not isinstance(dumpfile, str) or not dumpfile or '"' in dumpfile or "\n" in dumpfile:
        raise ConfigError(f"GTKWave dump file name {dumpfile!r} must be a path without quotes")
    lines = [
        "[*] stereosim trace view: clocks, then one group per unit",
        f'[dumpfile] "{dumpfile}"',
        f"[timestart] {log.start_fs}",
    ]
    groups: dict[str, list[tuple[str, int]]] = {}
    if log.clocks:
        groups[CLOCK_SCOPE] = [(f"{CLOCK_SCOPE}.{c.name}", 1) for c in log.clocks]
    for sig in log.signals:
        groups.setdefault(unit_of(sig.path), []).append((sig.path, sig.width))
    tops = sorted({sig.path.split(".")[0] for sig in log.signals})
    lines += [f"[treeopen] {top}." for top in tops]
    for group, members in groups.items():
        label = group.rsplit(".", 1)[-1]
        lines += [GROUP_OPEN, f"-{label}"]
        for path, width in members:
            lines += [FLAG_BINARY if width == 1 else FLAG_HEX, trace_name(path, width)]
        lines += [GROUP_CLOSE, f"-{label}"]
    return "\n".join(lines) + "\n"


def write_gtkw(path: str | os.PathLike, log: TraceLog, dumpfile: str | os.PathLike) -> None:
    """Write the save file atomically. ``dumpfile`` is written as given (use the VCD's name if
    the two files sit in one folder)."""
    atomic_write_bytes(path, gtkw_text(log, os.fspath(dumpfile)).encode("ascii"))
