"""Traced runs: `stereosim run --vcd / --timeline` on the compiled cycle engine.

A trace is recorded over a window of the frame (full-frame traces are gigabytes):

* ``A:B`` -- SVA clock cycles ``[A, B)`` (the default domain); ``nna:A:B``, ``sva:A:B`` or
  ``camera:A:B`` -- cycles of that domain. Cycle ``k`` of a domain starts at its edge ``k``.
* ``rows:A:B`` -- from the instant the left NNA's line buffer reaches image row ``A`` to the
  instant the sink holds row ``B - 1`` complete. The engine is deterministic, so a first
  untraced pass finds those instants and the second pass records between them.

The engine records every signal of :func:`sim.cycle.fast.trace_signals` in the window (its edges are
stepped one by one there; outside, quiet domains are settled in bulk as usual), ``--trace
PATTERNS`` keeps the signals whose paths match one of the glob patterns, and the exact size of
the VCD is computed before anything is written: above ``--trace-limit`` MB the run refuses
unless ``--force``. Tracing changes nothing else (same words, report and statistics).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from sim.config import ChipConfig
from sim.cycle.simulate import fast_engine_models
from sim.cycle.fast import _Setup, run_cycle_fast
from sim.errors import ConfigError
from traces.gtkw import write_gtkw
from traces.log import Clock, Signal, TraceLog, select, validate
from traces.timeline import write_timeline
from traces.vcd import estimate_vcd_bytes, write_vcd

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


def parse_window(spec: str | None) -> tuple[str, int, int | None]:
    """``(kind, A, B)``: kind is a domain name or "rows"; B None = to the end of the frame."""
    if spec is None:
        return "sva", 0, None
    parts = spec.split(":")
    kind = "sva"
    if len(parts) == 3:
        kind, parts = parts[0], parts[1:]
    if kind not in ("sva", "nna", "camera", "rows") or len(parts) != 2:
        raise ConfigError(
            f"--trace-window {spec!r}: expected A:B (SVA cycles), DOMAIN:A:B with DOMAIN nna, "
            "sva or camera, or rows:A:B (image rows), e.g. 0:100000 or rows:0:12"
        )
    try:
        a = int(parts[0]) if parts[0] else 0
        b = int(parts[1]) if parts[1] else None
    except ValueError:
        raise ConfigError(f"--trace-window {spec!r}: A and B must be whole numbers") from None
    if a < 0 or (b is not None and b <= a):
        raise ConfigError(f"--trace-window {spec!r}: need 0 <= A < B")
    return kind, a, b


def _domains(shape, cfg: ChipConfig) -> dict:
    return _Setup(shape, cfg).domains


def window_fs(spec: str | None, shape, cfg: ChipConfig, row_times=None) -> tuple[int, int]:
    """The window ``[start_fs, end_fs)`` of ``spec`` (``row_times`` from an untraced pass for a
    rows window; end None = the end of the run, given as a huge instant)."""
    kind, a, b = parse_window(spec)
    end_of_run = 1 << 62
    if kind == "rows":
        h = shape[0]
        b = h if b is None else b
        if b > h:
            raise ConfigError(f"--trace-window rows:{a}:{b}: the image has {h} rows")
        return int(row_times[0, a]), int(row_times[1, b]) + 1
    doms = _domains(shape, cfg)
    if kind not in doms:
        raise ConfigError(
            f"--trace-window {spec!r}: this configuration has no {kind} clock "
            f"(domains: {', '.join(doms)})"
        )
    d = doms[kind]
    return d.edge_fs(a), end_of_run if b is None else d.edge_fs(b)


def build_log(out: dict, patterns=()):
    """The :class:`traces.log.TraceLog` of a traced run's ``trace_out`` dict."""

    start, end = out["window"]
    log = TraceLog(
        signals=[Signal(p, w, d) for p, w, d in out["signals"]],
        clocks=[Clock(n, per, ph) for n, per, ph in out["domains"]],
        start_fs=start, end_fs=end, initial=out["initial"], times_fs=out["times_fs"],
        ids=out["ids"], values=out["values"],
    )
    log = validate(log)
    return select(log, patterns) if patterns else log


def run_traced(left: np.ndarray, right: np.ndarray, cfg: ChipConfig, request: TraceRequest):
    """Simulate one frame with a trace: ``(words, cycle report, log)``; raises ConfigError
    (nothing written) for a window outside the run, a trace above the size limit, or a
    configuration the compiled engine does not model."""

    if not fast_engine_models(cfg) or cfg.sim.engine == "readable":
        raise ConfigError(
            "traces are recorded by the compiled engine, which models one NNA submodule per "
            "camera: drop --vcd/--timeline or set nna.stereo_submodules=2 and sim.engine=auto"
        )
    shape = left.shape
    kind, _, _ = parse_window(request.window)
    row_times = None
    if kind == "rows":
        probe: dict = {}
        run_cycle_fast(left, right, cfg, trace_out=probe)
        row_times = probe["row_times"]
    start, end = window_fs(request.window, shape, cfg, row_times)
    out: dict = {}
    words, report, stats = run_cycle_fast(left, right, cfg, trace_window=(start, end),
                                          trace_out=out)
    last = int(stats["end_time_fs"])
    if not out["started"]:
        raise ConfigError(
            f"--trace-window {request.window!r} starts at {start} fs, after the frame ended "
            f"({last} fs): choose an earlier window"
        )
    out["window"] = (start, min(end, last + 1))
    log = build_log(out, request.patterns)
    report["trace"] = {"window_fs": [log.start_fs, log.end_fs], "signals": len(log.signals),
                       "value_changes": log.n_changes,
                       "outputs_in_window": out["outputs_in_window"]}
    return words, report, log


def check_size(log, request: TraceRequest) -> int:
    """The VCD's exact size in bytes; ConfigError above the limit unless ``force``."""

    size = estimate_vcd_bytes(log)
    if request.vcd and size > request.limit_mb * 1e6 and not request.force:
        raise ConfigError(
            f"the VCD would be {size / 1e6:.1f} MB ({log.n_changes} value changes), above "
            f"--trace-limit {request.limit_mb:g} MB: narrow --trace-window or --trace, or "
            "pass --force"
        )
    return size


def write_traces(log, request: TraceRequest, *, size_checked: bool = False) -> list[str]:
    """Write the VCD (and its .gtkw next to it) and the timeline the request names (each file
    atomically, after :func:`check_size` unless the caller ran it: ``size_checked``); returns
    the paths written."""

    if not size_checked:
        check_size(log, request)
    written = []
    if request.vcd:
        write_vcd(request.vcd, log)
        gtkw = os.path.splitext(request.vcd)[0] + ".gtkw"
        write_gtkw(gtkw, log, os.path.basename(request.vcd))
        written += [request.vcd, gtkw]
    if request.timeline:
        write_timeline(request.timeline, log)
        written.append(request.timeline)
    return written
