"""Fast Signal Trace (FST, GTKWave's compressed format) from a :class:`~traces.log.TraceLog`,
written with libfst's own writer (the ``pylibfst`` binding of ``fstapi``).

The dump holds what the VCD of the same log holds (:mod:`traces.vcd`): the same scopes (a
top-level ``clocks`` scope with one 1-bit wire per clock, then the signals' paths), the same
timescale (1 fs), every value at the window's start, then the clocks' edges and the signals'
changes (repeats dropped) at strictly increasing instants, and a last instant at the window's
end. Vectors are declared by width; their names carry no range. A 720p frame's window is a
fraction of its VCD's size.
"""

from __future__ import annotations

import os
import tempfile

from pylibfst import ffi, lib

from stereosim.traces.log import CLOCK_SCOPE, TraceLog, validate
from stereosim.traces.vcd import (
    _events,
    _head_and_tail,
    _package_version,
    _start_state,
    clock_edges,
    scope_tree,
)


def _declare(ctx, log: TraceLog) -> list:
    """Scopes and variables in the VCD's order; the handles of the clocks then the signals."""
    handles = []
    if log.clocks:
        lib.fstWriterSetScope(ctx, lib.FST_ST_VCD_MODULE, CLOCK_SCOPE.encode(), ffi.NULL)
        for clk in log.clocks:
            handles.append(lib.fstWriterCreateVar(ctx, lib.FST_VT_VCD_WIRE, lib.FST_VD_IMPLICIT,
                                                  1, clk.name.encode(), 0))
        lib.fstWriterSetUpscope(ctx)
    root = scope_tree(log)
    sig_handles = [0] * len(log.signals)

    def emit(node: dict) -> None:
        for name, child in node.items():
            if isinstance(child, dict):
                lib.fstWriterSetScope(ctx, lib.FST_ST_VCD_MODULE, name.encode(), ffi.NULL)
                emit(child)
                lib.fstWriterSetUpscope(ctx)
            else:
                sig_handles[child] = lib.fstWriterCreateVar(
                    ctx, lib.FST_VT_VCD_WIRE, lib.FST_VD_IMPLICIT, log.signals[child].width,
                    name.encode(), 0)

    emit(root)
    return handles + sig_handles


def fst_bytes(log: TraceLog, *, version: str | None = None) -> bytes:
    """The FST of ``log`` as bytes (libfst writes a file: a private temporary one)."""
    validate(log)
    _, _, kernel_args = _head_and_tail(log, None, version)
    widths = [1] * len(log.clocks) + [s.width for s in log.signals]
    fd, path = tempfile.mkstemp(suffix=".fst")
    os.close(fd)
    try:
        ctx = lib.fstWriterCreate(path.encode(), 1)
        if ctx == ffi.NULL:
            raise OSError(f"libfst could not create {path}")
        lib.fstWriterSetPackType(ctx, lib.FST_WR_PT_LZ4)
        lib.fstWriterSetRepackOnClose(ctx, 0)
        lib.fstWriterSetParallelMode(ctx, 0)
        lib.fstWriterSetDate(ctx, b"")  # (libfst puts the wall-clock time there)
        lib.fstWriterSetTimescale(ctx, -15)
        lib.fstWriterSetVersion(ctx, (version or f"stereosim {_package_version()}").encode())
        lib.fstWriterSetComment(ctx, f"window [{log.start_fs}, {log.end_fs}) fs".encode())
        handles = _declare(ctx, log)

        def bits(value: int, width: int) -> bytes:
            return format(int(value), f"0{width}b").encode()

        lib.fstWriterEmitTimeChange(ctx, log.start_fs)
        for j, clk in enumerate(log.clocks):
            v0, _, _ = clock_edges(clk, log.start_fs, log.end_fs)
            lib.fstWriterEmitValueChange(ctx, handles[j], bits(v0, 1))
        state = _start_state(log)
        n_clocks = len(log.clocks)
        for i, sig in enumerate(log.signals):
            lib.fstWriterEmitValueChange(ctx, handles[n_clocks + i], bits(state[i], sig.width))
        ev_time, ev_code, ev_value = _events(kernel_args)
        last = log.start_fs
        for t, code, value in zip(ev_time.tolist(), ev_code.tolist(), ev_value.tolist()):
            if t != last:
                lib.fstWriterEmitTimeChange(ctx, t)
                last = t
            lib.fstWriterEmitValueChange(ctx, handles[code], bits(value, widths[code]))
        if log.end_fs != last:
            lib.fstWriterEmitTimeChange(ctx, log.end_fs)
        lib.fstWriterClose(ctx)
        with open(path, "rb") as f:
            return f.read()
    finally:
        os.unlink(path)
