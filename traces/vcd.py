"""Value Change Dump (IEEE 1364-2005 section 18) from a :class:`~traces.log.TraceLog`.

The file is laid out as follows (``docs/traces.md`` shows an example):

* header: ``$date`` (only when a date string is given, so that two dumps of one log are
  byte-identical), ``$version stereosim ...``, a ``$comment`` with the window, ``$timescale 1 fs``
  (kernel time is integer femtoseconds, so every edge is exact);
* declarations: one ``$scope module`` per path component, in order of first appearance; under a
  top-level ``clocks`` scope one 1-bit wire per clock; then ``$var wire W id name $end`` per signal
  (vectors carry their range, ``name [W-1:0]``, so GTKWave and Surfer name them alike);
  identifier codes are printable ASCII 33..126, shortest first, clocks before signals;
* ``#start_fs`` and ``$dumpvars`` with every value at the start of the window (the log's initial
  values with the changes at ``start_fs`` applied);
* the body: strictly increasing ``#t``, and at each instant the clocks' edges and then the
  signals that changed (no repeats), by identifier; scalars ``0!``/``1!``, vectors ``b1010 !``
  without leading zeros;
* a final ``#end_fs`` without changes, so viewers show the window's last cycle.

Each clock has a rising edge at ``phase_fs + k * period_fs`` and a falling edge ``period_fs // 2``
later; the edges in the window are generated here, not logged.

:func:`vcd_bytes` is the fast writer, three compiled (numba) passes: merge the log's changes with
the clock edges and drop repeats, size the text, format it into one buffer.
:func:`vcd_text_pyvcd` writes the same dump with pyvcd and serves as the reference it is tested
against. :func:`estimate_vcd_bytes` gives the exact size of the fast writer's output from the
first two passes; :func:`bound_vcd_bytes` bounds it before a
run, from the signals and the window only.
"""

from __future__ import annotations

import io
import os
from importlib import metadata
from typing import NamedTuple

import numpy as np

from stereosim.core.errors import ConfigError
from stereosim.core.kernel_cache import njit
from stereosim.core.outputs import atomic_write_bytes
from stereosim.traces.log import CLOCK_SCOPE, Clock, Signal, TraceLog, validate

TIMESCALE = "1 fs"
_FIRST_CODE, _N_CODE_CHARS = 33, 94


def _package_version() -> str:
    try:
        return metadata.version("stereosim")
    except metadata.PackageNotFoundError:
        return "unknown"


def identifier_code(index: int) -> str:
    """The VCD identifier code of the ``index``-th variable: ``!`` .. ``~``, then ``!!`` ..,
    (bijective base 94 over printable ASCII 33..126, so every index has its own code)."""
    if index < 0:
        raise ValueError(f"identifier index must be >= 0; got {index}")
    chars = []
    while True:
        chars.append(chr(_FIRST_CODE + index % _N_CODE_CHARS))
        index = index // _N_CODE_CHARS - 1
        if index < 0:
            return "".join(chars)


def clock_edges(clock: Clock, start_fs: int, end_fs: int) -> tuple[int, np.ndarray, np.ndarray]:
    """A clock in ``[start_fs, end_fs)``: its value at ``start_fs`` (after an edge at that instant)
    and the instants (int64) and values (uint8) of its edges strictly inside the window."""
    period, phase, high = clock.period_fs, clock.phase_fs, clock.period_fs // 2
    if start_fs < phase:
        value = 0
    else:
        value = 1 if (start_fs - phase) % period < high else 0

    def after(offset: int) -> np.ndarray:
        # Edges at offset + phase + k*period, k >= 0, with start < t < end.
        first = phase + offset
        k0 = 0 if start_fs < first else (start_fs - first) // period + 1
        k1 = 0 if end_fs <= first else (end_fs - 1 - first) // period + 1
        return first + np.arange(k0, max(k0, k1), dtype=np.int64) * period

    rise, fall = after(0), after(high)
    times = np.concatenate([rise, fall])
    values = np.concatenate([np.ones(rise.size, np.uint8), np.zeros(fall.size, np.uint8)])
    order = np.argsort(times, kind="stable")
    return value, times[order], values[order]


# ---- declarations -----------------------------------------------------------------------------


def scope_tree(log: TraceLog) -> dict:
    """The signals' scopes as a tree: each node a dict name -> node (a scope) or int (a signal
    id), in the order of first appearance (the VCD's and the FST's declarations)."""
    root: dict = {}
    for i, sig in enumerate(log.signals):
        *scopes, name = sig.path.split(".")
        node = root
        for s in scopes:
            node = node.setdefault(s, {})
        node[name] = i
    return root


def _declarations(log: TraceLog) -> tuple[list[str], list[str], list[str]]:
    """The ``$scope``/``$var`` lines, the clocks' codes and the signals' codes."""
    clock_codes = [identifier_code(j) for j in range(len(log.clocks))]
    sig_codes = [identifier_code(len(log.clocks) + i) for i in range(len(log.signals))]
    root = scope_tree(log)
    lines = []
    if log.clocks:
        lines.append(f"$scope module {CLOCK_SCOPE} $end")
        for clk, code in zip(log.clocks, clock_codes):
            lines.append(f"$var wire 1 {code} {clk.name} $end")
        lines.append("$upscope $end")

    def emit(node: dict) -> None:
        for name, child in node.items():
            if isinstance(child, dict):
                lines.append(f"$scope module {name} $end")
                emit(child)
                lines.append("$upscope $end")
            else:
                w = log.signals[child].width
                ref = name if w == 1 else f"{name} [{w - 1}:0]"
                lines.append(f"$var wire {w} {sig_codes[child]} {ref} $end")

    emit(root)
    return lines, clock_codes, sig_codes


def _value_text(value: int, width: int, code: str) -> str:
    return f"{value}{code}" if width == 1 else f"b{value:b} {code}"


def _start_state(log: TraceLog) -> np.ndarray:
    """Every signal's value at ``start_fs`` (initial values with the changes at start applied)."""
    state = log.initial.copy()
    k = int(np.searchsorted(log.times_fs, log.start_fs, side="right"))
    for i, v in zip(log.ids[:k].tolist(), log.values[:k].tolist()):
        state[i] = v
    return state


def _head_and_tail(log: TraceLog, date: str | None, version: str | None):
    """Header text, the ``$dumpvars`` block, the trailer, and the arrays the kernel needs."""
    lines = []
    if date is not None:
        lines.append(f"$date {date} $end")
    lines.append(f"$version {version or 'stereosim ' + _package_version()} $end")
    lines.append(f"$comment window [{log.start_fs}, {log.end_fs}) fs $end")
    lines.append(f"$timescale {TIMESCALE} $end")
    decl, clock_codes, sig_codes = _declarations(log)
    lines += decl
    lines.append("$enddefinitions $end")
    state = _start_state(log)
    lines.append(f"#{log.start_fs}")
    lines.append("$dumpvars")
    edge_times, edge_codes, edge_values = [], [], []
    for j, clk in enumerate(log.clocks):
        v0, t, v = clock_edges(clk, log.start_fs, log.end_fs)
        lines.append(_value_text(v0, 1, clock_codes[j]))
        edge_times.append(t)
        edge_codes.append(np.full(t.size, j, dtype=np.int32))
        edge_values.append(v)
    for i, sig in enumerate(log.signals):
        lines.append(_value_text(int(state[i]), sig.width, sig_codes[i]))
    lines.append("$end")
    head = ("\n".join(lines) + "\n").encode("ascii")
    tail = f"#{log.end_fs}\n".encode("ascii")
    if edge_times:
        ct = np.concatenate(edge_times)
        cc = np.concatenate(edge_codes)
        cv = np.concatenate(edge_values)
        order = np.lexsort((cc, ct))
        ct, cc, cv = ct[order], cc[order], cv[order]
    else:
        ct, cc, cv = np.zeros(0, np.int64), np.zeros(0, np.int32), np.zeros(0, np.uint8)
    codes = clock_codes + sig_codes
    max_len = max((len(c) for c in codes), default=1)
    code_bytes = np.zeros((len(codes), max_len), dtype=np.uint8)
    code_len = np.zeros(len(codes), dtype=np.int64)
    for k, c in enumerate(codes):
        code_bytes[k, : len(c)] = np.frombuffer(c.encode("ascii"), dtype=np.uint8)
        code_len[k] = len(c)
    k0 = int(np.searchsorted(log.times_fs, log.start_fs, side="right"))
    code_width = np.array([1] * len(log.clocks) + [s.width for s in log.signals], dtype=np.int64)
    kernel_args = (
        log.times_fs[k0:], log.ids[k0:], log.values[k0:], state,
        ct, cc.astype(np.int64), cv.astype(np.uint64), len(log.clocks),
        code_width, code_bytes, code_len,
    )
    return head, tail, kernel_args


# ---- the compiled body writer -------------------------------------------------------------------


class Events(NamedTuple):
    """Parallel arrays of events: instants (int64), codes (int64: a clock, or n_clocks + the
    signal id) and values (uint64)."""

    time: np.ndarray
    code: np.ndarray
    value: np.ndarray


@njit(cache=True)
def _merge(changes, cur, clocks, n_clocks, out):
    """Merge the log's ``changes`` (code = signal id; signal ``s`` gets code ``n_clocks + s``)
    with the ``clocks``' edges in time order, keep the last change per signal and instant, drop
    repeats of the current value (``cur``: values at the window's start, updated), and store the
    events left in ``out``; at one instant clocks come first, then signals by id. Returns the
    number of events."""
    times, ids, values = changes
    ctimes, ccode, cval = clocks
    ev_time, ev_code, ev_value = out
    n = times.shape[0]
    m = ctimes.shape[0]
    nsig = cur.shape[0]
    touched = np.zeros(nsig, dtype=np.bool_)
    pending = np.zeros(nsig, dtype=np.uint64)
    group = np.empty(nsig, dtype=np.int64)
    e = 0
    i = 0
    j = 0
    while i < n or j < m:
        if i < n and (j >= m or times[i] <= ctimes[j]):
            t = times[i]
        else:
            t = ctimes[j]
        while j < m and ctimes[j] == t:
            ev_time[e] = t
            ev_code[e] = ccode[j]
            ev_value[e] = cval[j]
            e += 1
            j += 1
        k = 0
        while i < n and times[i] == t:
            s = ids[i]
            if not touched[s]:
                touched[s] = True
                group[k] = s
                k += 1
            pending[s] = values[i]
            i += 1
        for a in range(1, k):  # insertion sort: groups are short and usually sorted already
            x = group[a]
            b = a - 1
            while b >= 0 and group[b] > x:
                group[b + 1] = group[b]
                b -= 1
            group[b + 1] = x
        for a in range(k):
            s = group[a]
            touched[s] = False
            v = pending[s]
            if v != cur[s]:
                cur[s] = v
                ev_time[e] = t
                ev_code[e] = n_clocks + s
                ev_value[e] = v
                e += 1
    return e


@njit(cache=True)
def _bit_length(v):
    # Binary digits of v, at least 1. LLVM turns this loop into a count-leading-zeros.
    one = np.uint64(1)
    nb = 1
    x = v >> one
    while x != 0:
        nb += 1
        x >>= one
    return nb


@njit(cache=True)
def _decimal_digits(t):
    nd = 1
    x = t // 10
    while x > 0:
        nd += 1
        x //= 10
    return nd


@njit(cache=True)
def _format_size(ev_time, ev_code, ev_value, code_width, code_len):
    """Bytes of the body: a ``#t`` line per instant, a value line per event."""
    size = 0
    last = -1
    for e in range(ev_time.shape[0]):
        t = ev_time[e]
        if t != last:
            size += _decimal_digits(t) + 2
            last = t
        c = ev_code[e]
        if code_width[c] == 1:
            size += code_len[c] + 2
        else:
            size += _bit_length(ev_value[e]) + code_len[c] + 3
    return size


@njit(cache=True)
def _format(ev_time, ev_code, ev_value, code_width, codes, code_len, out):
    """Write the body into ``out`` (sized by :func:`_format_size`); returns the bytes written."""
    one = np.uint64(1)
    pos = 0
    last = -1
    for e in range(ev_time.shape[0]):
        t = ev_time[e]
        if t != last:
            nd = _decimal_digits(t)
            out[pos] = 35  # '#'
            x = t
            for q in range(nd):
                out[pos + nd - q] = 48 + x % 10
                x //= 10
            out[pos + nd + 1] = 10
            pos += nd + 2
            last = t
        c = ev_code[e]
        v = ev_value[e]
        if code_width[c] == 1:
            out[pos] = 48 + np.uint8(v)
            pos += 1
        else:
            nb = _bit_length(v)
            out[pos] = 98  # 'b'
            x = v
            for q in range(nb):
                out[pos + nb - q] = 48 + np.uint8(x & one)
                x >>= one
            out[pos + nb + 1] = 32
            pos += nb + 2
        for q in range(code_len[c]):
            out[pos + q] = codes[c, q]
        pos += code_len[c]
        out[pos] = 10
        pos += 1
    return pos


def _events(kernel_args):
    """The events of the body (see :func:`_merge`) as three arrays."""
    times, ids, values, state, ct, cc, cv, n_clocks = kernel_args[:8]
    cap = times.size + ct.size
    ev_time = np.empty(cap, dtype=np.int64)
    ev_code = np.empty(cap, dtype=np.int64)
    ev_value = np.empty(cap, dtype=np.uint64)
    n = _merge(Events(times, ids.astype(np.int64), values), state.copy(), Events(ct, cc, cv),
               n_clocks, Events(ev_time, ev_code, ev_value))
    return ev_time[:n], ev_code[:n], ev_value[:n]


def _vcd_buffer(log: TraceLog, date: str | None, version: str | None) -> np.ndarray:
    validate(log)
    head, tail, kernel_args = _head_and_tail(log, date, version)
    code_width, codes, code_len = kernel_args[8:]
    ev = _events(kernel_args)
    n_body = int(_format_size(*ev, code_width, code_len))
    buf = np.empty(len(head) + n_body + len(tail), dtype=np.uint8)
    buf[: len(head)] = np.frombuffer(head, dtype=np.uint8)
    written = _format(*ev, code_width, codes, code_len, buf[len(head) : len(head) + n_body])
    assert written == n_body, "VCD body: the sizing and formatting passes disagree"
    buf[len(head) + n_body :] = np.frombuffer(tail, dtype=np.uint8)
    return buf


def vcd_bytes(log: TraceLog, *, date: str | None = None, version: str | None = None) -> bytes:
    """The VCD of ``log`` as bytes (fast writer). ``date``: the ``$date`` text (omitted when
    None, the default, so that the output depends on the log alone); ``version``: the
    ``$version`` text (default ``stereosim <package version>``)."""
    return _vcd_buffer(log, date, version).tobytes()


def write_vcd(path: str | os.PathLike, log: TraceLog, *, date: str | None = None,
              version: str | None = None) -> int:
    """Write the VCD of ``log`` to ``path`` atomically; return its size in bytes."""
    buf = _vcd_buffer(log, date, version)
    atomic_write_bytes(path, memoryview(buf))
    return int(buf.size)


def estimate_vcd_bytes(log: TraceLog) -> int:
    """The size of :func:`vcd_bytes`'s output (default date and version), computed without
    formatting it: the header, and a counting pass over the changes (repeats dropped)."""
    validate(log)
    head, tail, kernel_args = _head_and_tail(log, None, None)
    code_width, _, code_len = kernel_args[8:]
    return len(head) + int(_format_size(*_events(kernel_args), code_width, code_len)) + len(tail)


def bound_vcd_bytes(signals: list[Signal], clocks: list[Clock], start_fs: int, end_fs: int) -> int:
    """An upper bound of the VCD size for a window, known before a run: every signal changes at
    every rising edge of its domain's clock (of the fastest clock if its domain has none) and
    every vector value is written at full width. Engines change a signal at most once per
    cycle of its domain, at a rising edge, so the real dump is never larger."""
    log = TraceLog(
        signals=list(signals), clocks=list(clocks), start_fs=start_fs, end_fs=end_fs,
        initial=np.zeros(len(signals), dtype=np.uint64), times_fs=np.zeros(0, np.int64),
        ids=np.zeros(0, np.int32), values=np.zeros(0, np.uint64),
    )
    validate(log)
    head, tail, _ = _head_and_tail(log, None, None)
    head_size = len(head) + sum(s.width - 1 for s in signals if s.width > 1)  # full-width dumpvars
    line_time = len(str(end_fs)) + 2  # "#<t>\n"
    code_len = len(identifier_code(max(len(clocks) + len(signals) - 1, 0)))
    rises = {}
    size = head_size + len(tail)
    for clk in clocks:
        _, t, v = clock_edges(clk, start_fs, end_fs)
        rises[clk.name] = int(v.sum())
        size += t.size * (line_time + 2 + code_len)  # each edge at an instant of its own
    for sig in signals:
        if sig.domain not in rises:
            raise ConfigError(
                f"signal '{sig.path}' is in clock domain '{sig.domain}', which has no clock: "
                "the bound counts the cycles of each signal's clock"
            )
        line = (2 + code_len) if sig.width == 1 else (3 + sig.width + code_len)
        size += rises[sig.domain] * line
    return int(size)


# ---- reference writer ---------------------------------------------------------------------------


def vcd_text_pyvcd(log: TraceLog, *, date: str = "", version: str | None = None) -> str:
    """The same dump written with pyvcd's ``VCDWriter`` (slower; the reference the fast writer is
    tested against). pyvcd orders scopes and identifiers its own way, so the two files differ
    in bytes but not in what a reader sees."""
    from vcd import VCDWriter

    validate(log)
    out = io.StringIO()
    writer = VCDWriter(
        out, timescale=TIMESCALE, date=date, version=version or f"stereosim {_package_version()}",
        init_timestamp=log.start_fs,
    )
    clock_vars, edge_t, edge_v, edge_var = [], [], [], []
    for j, clk in enumerate(log.clocks):
        v0, t, v = clock_edges(clk, log.start_fs, log.end_fs)
        clock_vars.append(writer.register_var(CLOCK_SCOPE, clk.name, "wire", size=1, init=v0))
        edge_t.append(t)
        edge_v.append(v.astype(np.uint64))
        edge_var.append(np.full(t.size, j, dtype=np.int64))
    sig_vars = []
    for i, sig in enumerate(log.signals):
        scope, name = sig.path.rsplit(".", 1)
        sig_vars.append(
            writer.register_var(scope, name, "wire", size=sig.width, init=int(log.initial[i]))
        )
    all_vars = clock_vars + sig_vars
    # The log's semantics, plainly: the last change of a signal at an instant wins.
    last: dict[tuple[int, int], int] = {}
    for t, i, v in zip(log.times_fs.tolist(), log.ids.tolist(), log.values.tolist()):
        last[(t, i)] = v
    events = [(t, len(clock_vars) + i, v) for (t, i), v in last.items()]
    for t, k, v in zip(np.concatenate(edge_t).tolist() if edge_t else [],
                       np.concatenate(edge_var).tolist() if edge_var else [],
                       np.concatenate(edge_v).tolist() if edge_v else []):
        events.append((t, k, v))
    events.sort()  # by time, clocks (lower index) first
    for t, k, v in events:
        writer.change(all_vars[k], t, v)
    writer.close(log.end_fs)
    return out.getvalue()
