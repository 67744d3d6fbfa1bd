"""A whole-frame timeline as Chrome/Perfetto trace-event JSON (open it at ui.perfetto.dev or in
chrome://tracing).

Conventions the input :class:`~traces.log.TraceLog` follows:

* **Block status.** A signal whose path ends in ``.status`` is the activity of the block named by
  the rest of the path (``top.nna.left.sub0.status`` is block ``top.nna.left.sub0``), as an
  enumeration: ``0`` idle, ``1`` busy, ``2`` starved (waits for data from an input FIFO), ``3``
  blocked (waits for space in an output FIFO) -- the kernel's four activities. The value logged
  at a clock edge is the block's activity in the cycle that starts at that edge.
* **FIFO occupancy.** A signal whose path ends in ``.occupancy`` is the number of items a FIFO
  holds (``top.fifo.nna_left_to_sva.occupancy``).
* Other signals are ignored.

What is written (``{"traceEvents": [...], "displayTimeUnit": "ns"}``):

* one process (``pid``, from 1) per unit -- the first two components of the path (``top.nna``),
  named by its last component (``nna``) -- in order of first appearance, and in it one thread
  (``tid``, from 1) per block, named by the block's path below the unit (``left.sub0``);
  ``"M"`` metadata events name and order them;
* per block, ``"X"`` complete events, one per run of equal status, named ``idle`` / ``busy`` /
  ``starved`` / ``blocked``; together they cover the window ``[start_fs, end_fs)`` without
  overlap. ``args.cycles`` is the number of the block's clock cycles the span holds (when the
  signal's domain names a clock of the log);
* per FIFO, ``"C"`` counter events on its unit's process, named by the FIFO's path below the unit,
  with ``args.occupancy``: the value at the window's start, at every change, and again at the
  window's end so that the counter track spans the window.

Timestamps (``ts``) and durations (``dur``) are microseconds, as the format requires:
``t_fs / 1e9``, the double nearest to the exact decimal, so nanosecond differences survive.
Events are sorted by time, then process, thread and kind; the JSON is written with fixed key
order and separators, so the same log gives the same bytes.
"""

from __future__ import annotations

import json
import os

import numpy as np

from stereosim.core.errors import ConfigError
from stereosim.core.outputs import atomic_write_bytes
from stereosim.traces.gtkw import STATUS_NAMES, STATUS_SUFFIX, unit_of
from stereosim.traces.log import TraceLog, changes_of, validate

OCCUPANCY_SUFFIX = ".occupancy"
FS_PER_US = 10**9


def _us(t_fs: int) -> float:
    return t_fs / FS_PER_US


def _edges_before(t_fs: int, period_fs: int, phase_fs: int) -> int:
    """Rising edges strictly before ``t_fs``."""
    return 0 if t_fs <= phase_fs else (t_fs - phase_fs - 1) // period_fs + 1


def timeline_events(log: TraceLog) -> list[dict]:
    """The trace events (metadata first, then by time), as plain dicts."""
    validate(log)
    clocks = {c.name: c for c in log.clocks}
    pids: dict[str, int] = {}
    tids: dict[tuple[int, str], int] = {}
    meta, timed = [], []

    def pid_of(unit: str) -> int:
        if unit not in pids:
            pids[unit] = len(pids) + 1
            label = unit.rsplit(".", 1)[-1]
            meta.append({"name": "process_name", "ph": "M", "pid": pids[unit], "tid": 0,
                         "args": {"name": label}})
            meta.append({"name": "process_sort_index", "ph": "M", "pid": pids[unit], "tid": 0,
                         "args": {"sort_index": pids[unit]}})
        return pids[unit]

    for i, sig in enumerate(log.signals):
        path = sig.path
        if path.endswith(STATUS_SUFFIX) and path.count(".") >= 2:
            block = path[: -len(STATUS_SUFFIX)]
            unit = unit_of(path)
            pid = pid_of(unit)
            name = block[len(unit) + 1 :] if block.startswith(unit + ".") else block
            tid = tids.setdefault((pid, name), sum(1 for p, _ in tids if p == pid) + 1)
            meta.append({"name": "thread_name", "ph": "M", "pid": pid, "tid": tid,
                         "args": {"name": name}})
            meta.append({"name": "thread_sort_index", "ph": "M", "pid": pid, "tid": tid,
                         "args": {"sort_index": tid}})
            t, v = changes_of(log, i)
            if int(v.max()) >= len(STATUS_NAMES):
                k = int(np.argmax(v >= len(STATUS_NAMES)))
                raise ConfigError(
                    f"status signal '{path}' is {int(v[k])} at {int(t[k])} fs; a status is "
                    "0 idle, 1 busy, 2 starved or 3 blocked"
                )
            ends = np.append(t[1:], log.end_fs)
            clk = clocks.get(sig.domain)
            for t0, t1, s in zip(t.tolist(), ends.tolist(), v.tolist()):
                ev = {"name": STATUS_NAMES[s], "cat": "status", "ph": "X", "ts": _us(t0),
                      "dur": _us(t1 - t0), "pid": pid, "tid": tid}
                if clk is not None:
                    cycles = (_edges_before(t1, clk.period_fs, clk.phase_fs)
                              - _edges_before(t0, clk.period_fs, clk.phase_fs))
                    ev["args"] = {"cycles": cycles}
                timed.append(((t0, pid, tid, 1), ev))
        elif path.endswith(OCCUPANCY_SUFFIX) and path.count(".") >= 2:
            unit = unit_of(path)
            pid = pid_of(unit)
            fifo = path[: -len(OCCUPANCY_SUFFIX)]
            name = fifo[len(unit) + 1 :] if fifo.startswith(unit + ".") else fifo
            t, v = changes_of(log, i)
            for t0, occ in zip([*t.tolist(), log.end_fs], [*v.tolist(), int(v[-1])]):
                ev = {"name": name, "cat": "fifo", "ph": "C", "ts": _us(t0), "pid": pid,
                      "args": {"occupancy": occ}}
                timed.append(((t0, pid, 0, 0, name), ev))
    meta.sort(key=lambda e: (e["pid"], e["tid"], e["name"]))
    timed.sort(key=lambda item: item[0])
    return meta + [ev for _, ev in timed]


def timeline_bytes(log: TraceLog) -> bytes:
    """The trace-event JSON of ``log``: one event per line, deterministic bytes."""
    events = timeline_events(log)
    body = ",\n".join(json.dumps(ev, separators=(",", ":")) for ev in events)
    return ('{"displayTimeUnit":"ns","traceEvents":[\n' + body + "\n]}\n").encode("ascii")


def write_timeline(path: str | os.PathLike, log: TraceLog) -> int:
    """Write the timeline JSON atomically; return its size in bytes."""
    data = timeline_bytes(log)
    atomic_write_bytes(path, data)
    return len(data)
