"""Traced runs: `stereosim run --vcd / --timeline` on the compiled cycle engine.

A trace is recorded over a window of the frame (full-frame traces are gigabytes), in the window
syntax ``stereosim wave --window`` shares (:mod:`traces.window`):

* ``0:100us``, ``1.5us:2us`` -- a time window ``[A, B)``, with units fs, ps, ns, us, ms or s.
* ``A:B`` -- SVA clock cycles ``[A, B)`` (the default domain); ``nna:A:B``, ``sva:A:B`` or
  ``camera:A:B`` -- cycles of that domain. Cycle ``k`` of a domain starts at its edge ``k``.
* ``rows:A:B`` -- from the instant the left NNA's line buffer reaches image row ``A`` to the
  instant the sink holds row ``B - 1`` complete. The engine is deterministic, so a first
  untraced pass finds those instants and the second pass records between them.

The engine records every signal of the chip plan (:mod:`sim.cycle.plan`) at every clock edge in
the window -- the compiled engine reads them off the event streams, the readable kernel records
its blocks' state, and both give the same VCD -- ``--trace PATTERNS`` keeps the signals whose
paths match one of the glob patterns, and the exact size of the VCD is computed before anything
is written: above ``--trace-limit`` MB the run refuses unless ``--force``. Tracing changes
nothing else (same words, report and statistics). Split frames are traced like whole ones.

Beside the dump go a GTKWave save file (``.gtkw``, :mod:`traces.gtkw`) and, when the trace holds
a ``status`` signal, the translate filter file it names (``<stem>.status.txt``); both name
their files by absolute path, resolved when they are written, so ``gtkwave out/t.gtkw`` works
from any folder. All of them are published as one set with the run's other outputs.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from stereosim.core.errors import ConfigError
from stereosim.core.outputs import publish
from stereosim.core.progress import compile_notice
from stereosim.sim.cycle.contract import RunStopped
from stereosim.sim.cycle.plan import ChipPlan
from stereosim.sim.cycle.simulate import simulate
from stereosim.traces.fst import fst_bytes
from stereosim.traces.gtkw import gtkw_text, has_status, status_filter_text
from stereosim.traces.log import select
from stereosim.traces.timeline import timeline_bytes
from stereosim.traces.vcd import estimate_vcd_bytes, vcd_bytes
from stereosim.traces.window import ROWS, Window
from stereosim.traces.window import parse_window as parse_any_window

DEFAULT_LIMIT_MB = 500


@dataclass(frozen=True)
class TraceRequest:
    """What to trace and where to write it (paths may be None)."""

    window: str | None = None
    patterns: tuple[str, ...] = ()
    vcd: str | None = None
    timeline: str | None = None
    force: bool = False
    limit_mb: float = DEFAULT_LIMIT_MB


def parse_window(spec: str | None) -> Window:
    """The ``--trace-window`` of ``spec`` (None = the whole frame); ConfigError if malformed."""
    return parse_any_window(spec, default="sva", option="--trace-window")


def window_fs(spec: str | None, plan: ChipPlan, row_times=None) -> tuple[int, int]:
    """The window ``[start_fs, end_fs)`` of ``spec`` (``row_times`` from an untraced pass for a
    rows window; end None = the end of the run, given as a huge instant, and so is a row a
    stopped run never reached: -1 in ``row_times``)."""
    win = parse_window(spec)
    end_of_run = 1 << 62
    a = win.start or 0
    if win.kind == ROWS:
        h = plan.shape[0]
        b = h if win.end is None else win.end
        if b > h or a >= b:
            raise ConfigError(f"--trace-window {spec!r}: the image has rows 0 to {h - 1}")
        first, last = int(row_times[0, a]), int(row_times[1, b])
        return (first if first >= 0 else end_of_run), (last + 1 if last >= 0 else end_of_run)
    end = win.end
    if not win.is_time:
        if win.kind not in plan.domains:
            raise ConfigError(
                f"--trace-window {spec!r}: this configuration has no {win.kind} clock "
                f"(domains: {', '.join(plan.domains)})"
            )
        per = plan.domains[win.kind].period_fs
        a, end = a * per, None if end is None else end * per
    if a >= end_of_run:
        raise ConfigError(
            f"--trace-window {spec!r} starts at {a} fs, after any run has ended (2**62 fs): "
            "choose an earlier window"
        )
    # an end past every run is the end of the run (the engine counts time in int64)
    return a, end_of_run if end is None else min(end, end_of_run)


def trace_section(log, outputs_in_window: int) -> dict:
    """The report's ``trace`` section of a recorded ``log``."""
    return {"window_fs": [log.start_fs, log.end_fs], "signals": len(log.signals),
            "value_changes": log.n_changes, "outputs_in_window": outputs_in_window}


def run_traced(plan: ChipPlan, left: np.ndarray, right: np.ndarray, request: TraceRequest):
    """Simulate one frame with a trace: ``(frame result, log)``; raises ConfigError (nothing
    written) for a window outside the run or a trace above the size limit. Either engine
    records it (sim.engine; the same signals and values). A run that stops raises its
    :class:`~sim.cycle.contract.RunStopped` with ``trace`` the log of the window up to the stop
    (the request's signals; None when the window starts after it)."""
    row_times = None
    if parse_window(request.window).kind == ROWS:
        try:
            row_times = simulate(plan, left, right).row_times
        except RunStopped as stop:  # the rows reached before the stop
            row_times = stop.row_times
    start, end = window_fs(request.window, plan, row_times)
    try:
        frame = simulate(plan, left, right, window=(start, end))
    except RunStopped as stop:
        if stop.trace is not None and request.patterns:
            stop.trace = select(stop.trace, request.patterns)
        raise
    if frame.trace is None:
        last = int(frame.stats["end_time_fs"])
        raise ConfigError(
            f"--trace-window {request.window!r} starts at {start} fs, after the frame ended "
            f"({last} fs): choose an earlier window"
        )
    log = select(frame.trace, request.patterns) if request.patterns else frame.trace
    frame.report["trace"] = trace_section(log, frame.outputs_in_window)
    return frame, log


def is_fst(path: str) -> bool:
    """Does a ``--vcd`` path name an FST dump (``.fst``: GTKWave's compressed format)?"""
    return path.lower().endswith(".fst")


def check_size(log, request: TraceRequest, size: int | None = None) -> int:
    """The dump's size in bytes (a VCD's exact size computed before writing it; an FST's
    ``size``, once written); ConfigError above the limit unless ``force``."""
    if size is None:
        size = estimate_vcd_bytes(log)
    if request.vcd and size > request.limit_mb * 1e6 and not request.force:
        kind = "FST" if is_fst(request.vcd) else "VCD"
        raise ConfigError(
            f"the {kind} would be {size / 1e6:.1f} MB ({log.n_changes} value changes), above "
            f"--trace-limit {request.limit_mb:g} MB: narrow --trace-window or --trace, or "
            "pass --force"
        )
    return size


def trace_paths(request: TraceRequest) -> list[tuple[str, str]]:
    """``(path, what the user knows it as)`` of every file a request writes (checked before the
    run): the VCD, the .gtkw beside it, the timeline."""
    paths = []
    if request.vcd:
        paths += [(request.vcd, "--vcd"), (gtkw_path(request.vcd), "the .gtkw beside --vcd"),
                  (filter_path(request.vcd), "the GTKWave status filter beside --vcd")]
    if request.timeline:
        paths.append((request.timeline, "--timeline"))
    return paths


def gtkw_path(vcd: str) -> str:
    """The GTKWave save file written beside a dump."""
    return os.path.splitext(vcd)[0] + ".gtkw"


def filter_path(vcd: str) -> str:
    """The GTKWave translate filter file (status names) written beside a dump."""
    return os.path.splitext(vcd)[0] + ".status.txt"


@compile_notice()
def trace_files(log, request: TraceRequest) -> dict[str, bytes]:
    """The bytes of every file the request names (after :func:`check_size`), by path (the
    writers' kernels compile on first use: :func:`core.progress.compile_notice`)."""
    files = {}
    if request.vcd and is_fst(request.vcd):
        files[request.vcd] = fst_bytes(log)
        check_size(log, request, len(files[request.vcd]))
    else:
        check_size(log, request)
        if request.vcd:
            files[request.vcd] = vcd_bytes(log)
    if request.vcd:
        filt = filter_path(request.vcd) if has_status(log) else None
        files[gtkw_path(request.vcd)] = gtkw_text(
            log, os.path.abspath(request.vcd), filt and os.path.abspath(filt)).encode()
        if filt:
            files[filt] = status_filter_text().encode()
    if request.timeline:
        files[request.timeline] = timeline_bytes(log)
    return files


def write_traces(log, request: TraceRequest) -> list[str]:
    """Write the dump (and its .gtkw and filter file next to it) and the timeline the request
    names, as one set
    (:func:`core.outputs.publish`); returns the paths written."""
    return publish(trace_files(log, request))
