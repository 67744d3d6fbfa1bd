"""The columnar trace log: what an engine records and every trace writer reads.

A :class:`TraceLog` is engine-agnostic: a list of :class:`Signal`\\ s (the signal id is the index),
the :class:`Clock`\\ s of the chip, a dumped window ``[start_fs, end_fs)`` in kernel time
(integer femtoseconds), the value of every signal when the window opens (``initial``), and three
parallel arrays of value changes (``times_fs``, ``ids``, ``values``) in non-decreasing time order.

Semantics, which every writer follows:

* ``initial[i]`` is signal ``i``'s value *entering* the window, before any change listed at
  ``start_fs`` is applied; changes at ``start_fs`` are applied on top (a VCD's ``$dumpvars``
  holds the result).
* Several changes of one signal at one instant: the last one (in array order) wins.
* A change to the value the signal already has is a no-op; writers drop it (engines may log a
  signal's value every cycle without checking).

Signal paths are dotted hierarchies, ``top.<unit>.<block>...<signal>`` (e.g.
``top.nna.left.sub0.line_buffer.fill``, ``top.fifo.nna_left_to_sva.occupancy``); each component
is a Verilog simple identifier (letters, digits, ``_`` and ``$``, not starting with a digit or
``$``) and a path has at least two components (a scope and a name). The top-level scope
``clocks`` is reserved for the clock wires the VCD writer adds.

:class:`TraceRecorder` builds a log from the readable engine's ``trace`` hook; :func:`select`
and :func:`window` scope a log to glob patterns and a time window.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from fnmatch import fnmatchcase

import numpy as np

from stereosim.core.errors import ConfigError

CLOCK_SCOPE = "clocks"
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_$]*\Z")
_CHUNK = 1 << 16


@dataclass(frozen=True)
class Signal:
    """One traced signal: dotted ``path``, ``width`` in bits (1..64), clock ``domain`` name."""

    path: str
    width: int
    domain: str


@dataclass(frozen=True)
class Clock:
    """A clock: rising edges at ``phase_fs + k * period_fs``, falling ``period_fs // 2`` later."""

    name: str
    period_fs: int
    phase_fs: int


@dataclass
class TraceLog:
    """Signals, clocks, the window ``[start_fs, end_fs)``, initial values and the value changes
    (``times_fs`` int64 non-decreasing, ``ids`` int32, ``values`` uint64). See the module
    docstring for the semantics."""

    signals: list[Signal]
    clocks: list[Clock]
    start_fs: int
    end_fs: int
    initial: np.ndarray
    times_fs: np.ndarray
    ids: np.ndarray
    values: np.ndarray

    @property
    def n_changes(self) -> int:
        return int(self.times_fs.shape[0])


def _is_int(v) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))


def check_path(path) -> list[str]:
    """The components of a valid signal path, or a ConfigError saying what is wrong."""
    if not isinstance(path, str) or not path:
        raise ConfigError(f"signal path must be a non-empty string; got {path!r}")
    parts = path.split(".")
    if len(parts) < 2:
        raise ConfigError(
            f"signal path '{path}' has no scope: use a dotted path like 'top.block.signal'"
        )
    for part in parts:
        if not _IDENT.match(part):
            raise ConfigError(
                f"signal path '{path}' has the component '{part}', which is not an identifier "
                "(letters, digits, _ and $, not starting with a digit or $)"
            )
    if parts[0] == CLOCK_SCOPE:
        raise ConfigError(
            f"signal path '{path}' is under the scope '{CLOCK_SCOPE}', which is reserved for the "
            "clock wires; rename its top scope"
        )
    return parts


def _check_signals(signals) -> None:
    if not isinstance(signals, list):
        raise ConfigError(
            f"trace log signals must be a list of Signal; got {type(signals).__name__}"
        )
    seen: set[str] = set()
    scopes: set[str] = set()
    for i, sig in enumerate(signals):
        if not isinstance(sig, Signal):
            raise ConfigError(f"trace log signal {i} must be a Signal; got {sig!r}")
        parts = check_path(sig.path)
        if not _is_int(sig.width) or not 1 <= sig.width <= 64:
            raise ConfigError(
                f"signal '{sig.path}': width must be an integer from 1 to 64 bits; "
                f"got {sig.width!r}"
            )
        if not isinstance(sig.domain, str):
            raise ConfigError(
                f"signal '{sig.path}': domain must be a clock domain name; got {sig.domain!r}"
            )
        if sig.path in seen:
            raise ConfigError(f"signal path '{sig.path}' appears twice; give each signal one path")
        seen.add(sig.path)
        scopes.update(".".join(parts[:k]) for k in range(1, len(parts)))
    clash = sorted(seen & scopes)
    if clash:
        raise ConfigError(
            f"'{clash[0]}' is both a signal and the scope of other signals; rename one of them"
        )


def _check_clocks(clocks) -> None:
    if not isinstance(clocks, list):
        raise ConfigError(f"trace log clocks must be a list of Clock; got {type(clocks).__name__}")
    names: set[str] = set()
    for i, clk in enumerate(clocks):
        if not isinstance(clk, Clock):
            raise ConfigError(f"trace log clock {i} must be a Clock; got {clk!r}")
        if not isinstance(clk.name, str) or not _IDENT.match(clk.name):
            raise ConfigError(f"clock name {clk.name!r} is not an identifier (letters, digits, _)")
        if clk.name in names:
            raise ConfigError(f"clock '{clk.name}' appears twice; give each clock one entry")
        names.add(clk.name)
        if not _is_int(clk.period_fs) or clk.period_fs < 2:
            raise ConfigError(
                f"clock '{clk.name}': period_fs must be an integer >= 2 (a rising and a falling "
                f"edge); got {clk.period_fs!r}"
            )
        if not _is_int(clk.phase_fs) or clk.phase_fs < 0:
            raise ConfigError(
                f"clock '{clk.name}': phase_fs must be an integer >= 0; got {clk.phase_fs!r}"
            )


def _check_array(name: str, arr, dtype, ndim: int = 1) -> None:
    if not isinstance(arr, np.ndarray):
        raise ConfigError(f"trace log {name} must be a numpy array; got {type(arr).__name__}")
    if arr.dtype != dtype:
        raise ConfigError(f"trace log {name} has dtype {arr.dtype}; it must be {np.dtype(dtype)}")
    if arr.ndim != ndim:
        raise ConfigError(f"trace log {name} has shape {arr.shape}; it must be 1-D")


def _check_fit(what: str, values: np.ndarray, sig_ids: np.ndarray, signals) -> None:
    """Every value fits the width of its signal (``sig_ids`` per value)."""
    widths = np.array([s.width for s in signals], dtype=np.int64)[sig_ids]
    narrow = widths < 64
    if not narrow.any():
        return
    over = np.zeros(values.shape, dtype=bool)
    over[narrow] = (values[narrow] >> widths[narrow].astype(np.uint64)) != 0
    if over.any():
        k = int(np.argmax(over))
        sig = signals[int(sig_ids[k])]
        raise ConfigError(
            f"trace log {what} {k} is {int(values[k])}, which does not fit the {sig.width} bits "
            f"of signal '{sig.path}'"
        )


def validate(log) -> TraceLog:
    """Check a :class:`TraceLog` completely; return it, or raise a one-line ConfigError."""
    if not isinstance(log, TraceLog):
        raise ConfigError(f"expected a TraceLog; got {type(log).__name__}")
    _check_signals(log.signals)
    _check_clocks(log.clocks)
    if not _is_int(log.start_fs) or log.start_fs < 0:
        raise ConfigError(f"trace log start_fs must be an integer >= 0; got {log.start_fs!r}")
    if not _is_int(log.end_fs) or log.end_fs <= log.start_fs:
        raise ConfigError(
            f"trace log end_fs must be an integer after start_fs={log.start_fs}; got {log.end_fs!r}"
        )
    n_sig = len(log.signals)
    _check_array("initial", log.initial, np.uint64)
    if log.initial.shape != (n_sig,):
        raise ConfigError(
            f"trace log initial has {log.initial.shape[0]} values for {n_sig} signals"
        )
    _check_array("times_fs", log.times_fs, np.int64)
    _check_array("ids", log.ids, np.int32)
    _check_array("values", log.values, np.uint64)
    n = log.times_fs.shape[0]
    if log.ids.shape[0] != n or log.values.shape[0] != n:
        raise ConfigError(
            f"trace log times_fs, ids and values must have one length; got {n}, "
            f"{log.ids.shape[0]} and {log.values.shape[0]}"
        )
    _check_fit("initial value", log.initial, np.arange(n_sig), log.signals)
    if n:
        t = log.times_fs
        if t[0] < log.start_fs or t[-1] >= log.end_fs:
            raise ConfigError(
                f"trace log times_fs run from {int(t[0])} to {int(t[-1])}, outside the window "
                f"[{log.start_fs}, {log.end_fs}) fs"
            )
        back = np.flatnonzero(t[1:] < t[:-1])
        if back.size:
            k = int(back[0]) + 1
            raise ConfigError(
                f"trace log times_fs go backwards at change {k} ({int(t[k - 1])} then "
                f"{int(t[k])} fs); sort the changes by time"
            )
        lo, hi = int(log.ids.min()), int(log.ids.max())
        if lo < 0 or hi >= n_sig:
            bad = lo if lo < 0 else hi
            raise ConfigError(f"trace log ids contain {bad}; signal ids run from 0 to {n_sig - 1}")
        _check_fit("value at change", log.values, log.ids, log.signals)
    return log


def _state_before(log: TraceLog, t_fs: int) -> np.ndarray:
    """Every signal's value after all changes strictly before ``t_fs``."""
    state = log.initial.copy()
    k = int(np.searchsorted(log.times_fs, t_fs, side="left"))
    if k:
        ids_rev = log.ids[:k][::-1]
        uniq, first_rev = np.unique(ids_rev, return_index=True)
        state[uniq] = log.values[:k][::-1][first_rev]
    return state


def window(log: TraceLog, start_fs: int, end_fs: int) -> TraceLog:
    """The part of ``log`` in ``[start_fs, end_fs)``, with ``initial`` recomputed.

    The window must lie inside the log's own window; ConfigError otherwise.
    """
    if not (_is_int(start_fs) and _is_int(end_fs)):
        raise ConfigError(f"trace window bounds must be integers (fs); got {start_fs!r}:{end_fs!r}")
    if not log.start_fs <= start_fs < end_fs <= log.end_fs:
        raise ConfigError(
            f"trace window [{start_fs}, {end_fs}) fs is empty or outside the recorded window "
            f"[{log.start_fs}, {log.end_fs}) fs"
        )
    a = int(np.searchsorted(log.times_fs, start_fs, side="left"))
    b = int(np.searchsorted(log.times_fs, end_fs, side="left"))
    return TraceLog(
        signals=list(log.signals),
        clocks=list(log.clocks),
        start_fs=int(start_fs),
        end_fs=int(end_fs),
        initial=_state_before(log, start_fs),
        times_fs=log.times_fs[a:b].copy(),
        ids=log.ids[a:b].copy(),
        values=log.values[a:b].copy(),
    )


def parse_patterns(items: Sequence[str] | None, option: str = "--signals") -> tuple[str, ...]:
    """The glob patterns of a repeatable, comma-separated option (``--signals 'a.*,b.*'
    --signals c``), blanks dropped: ``()`` when the option was not given (every signal). Given
    with no pattern at all (``--signals ''``, ``' , '``) it is a ConfigError, for ``run`` and
    ``wave`` alike: an empty list reads as "nothing", yet would trace everything."""
    if not items:
        return ()
    patterns = tuple(p.strip() for item in items for p in item.split(",") if p.strip())
    if not patterns:
        raise ConfigError(
            f"{option} {', '.join(repr(i) for i in items)[:60]} holds no pattern: give glob "
            "patterns, e.g. 'top.sva.*', or leave the option out to keep every signal"
        )
    return patterns


def match_paths(paths: Sequence[str], patterns: Iterable[str]) -> list[int]:
    """Indices of the paths matched by any glob pattern (``fnmatch``, case-sensitive; ``*``
    also matches dots). A pattern that matches nothing is a ConfigError naming a few paths."""
    patterns = list(patterns)
    if not patterns:
        raise ConfigError("no signal pattern given: give at least one glob, e.g. 'top.sva.*'")
    keep = np.zeros(len(paths), dtype=bool)
    for pat in patterns:
        if not isinstance(pat, str) or not pat:
            raise ConfigError(f"signal pattern must be a non-empty string; got {pat!r}")
        hit = np.array([fnmatchcase(p, pat) for p in paths], dtype=bool)
        if not hit.any():
            some = ", ".join(paths[:5]) + (", ..." if len(paths) > 5 else "")
            raise ConfigError(
                f"signal pattern '{pat}' matches no signal (there are {len(paths)}: "
                f"{some or 'none'})"
            )
        keep |= hit
    return [int(i) for i in np.flatnonzero(keep)]


def select(log: TraceLog, patterns: Iterable[str]) -> TraceLog:
    """The signals of ``log`` whose path matches any of the glob ``patterns`` (ids renumbered,
    order kept; clocks are always kept)."""
    keep = match_paths([s.path for s in log.signals], patterns)
    remap = np.full(len(log.signals), -1, dtype=np.int32)
    remap[keep] = np.arange(len(keep), dtype=np.int32)
    mask = remap[log.ids] >= 0 if log.ids.size else np.zeros(0, dtype=bool)
    return TraceLog(
        signals=[log.signals[i] for i in keep],
        clocks=list(log.clocks),
        start_fs=log.start_fs,
        end_fs=log.end_fs,
        initial=log.initial[keep].copy(),
        times_fs=log.times_fs[mask],
        ids=remap[log.ids[mask]],
        values=log.values[mask],
    )


class TraceRecorder:
    """Accumulates value changes from Python callbacks into a :class:`TraceLog`.

    An instance is a valid ``trace`` hook of :class:`sim.cycle.readable.kernel.Simulator`:
    ``recorder(time_fs, {domain: cycle}, {name: value})``. ``names`` gives the hook's key for
    each signal (default: the signal's path). Changes before ``start_fs`` only update the state
    that becomes ``initial``; changes at or after ``end_fs`` are ignored, so a run can be scoped
    while it runs. Keys that name no signal raise ConfigError, unless ``strict=False`` (then they
    are skipped: record a selection of signals). Changes go to Python lists that are packed into
    numpy chunks every 65536 changes.
    """

    def __init__(
        self,
        signals: Sequence[Signal],
        clocks: Sequence[Clock],
        *,
        names: Sequence[str] | None = None,
        initial: Mapping[str, int] | None = None,
        start_fs: int = 0,
        end_fs: int | None = None,
        strict: bool = True,
    ):
        self.signals = list(signals)
        self.clocks = list(clocks)
        _check_signals(self.signals)
        _check_clocks(self.clocks)
        keys = [s.path for s in self.signals] if names is None else list(names)
        if len(keys) != len(self.signals):
            raise ConfigError(f"{len(keys)} names given for {len(self.signals)} signals")
        self._index = {k: i for i, k in enumerate(keys)}
        if len(self._index) != len(keys):
            raise ConfigError("two signals share one hook name; give each a distinct name")
        if not _is_int(start_fs) or start_fs < 0:
            raise ConfigError(f"recorder start_fs must be an integer >= 0; got {start_fs!r}")
        if end_fs is not None and (not _is_int(end_fs) or end_fs <= start_fs):
            raise ConfigError(f"recorder end_fs must be an integer after start_fs; got {end_fs!r}")
        self.start_fs = int(start_fs)
        self.end_fs = end_fs
        self.strict = strict
        self._state = [0] * len(self.signals)
        for key, v in (initial or {}).items():
            self._state[self._lookup(key)] = v
        self._ids: list[int] = []
        self._values: list[int] = []
        self._call_times: list[int] = []
        self._call_counts: list[int] = []
        self._chunks: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._last_fs: int | None = None

    def _lookup(self, key) -> int:
        i = self._index.get(key)
        if i is None:
            raise ConfigError(f"trace hook reported unknown signal '{key}'")
        return i

    def __call__(self, time_fs: int, cycles: Mapping[str, int], changes: Mapping[str, int]) -> None:
        if self._last_fs is not None and time_fs < self._last_fs:
            raise ConfigError(f"trace hook time went back from {self._last_fs} to {time_fs} fs")
        self._last_fs = time_fs
        index = self._index
        if time_fs < self.start_fs:
            for key, v in changes.items():
                i = index.get(key)
                if i is None:
                    if self.strict:
                        self._lookup(key)
                    continue
                self._state[i] = v
            return
        if self.end_fs is not None and time_fs >= self.end_fs:
            return
        ids, values = self._ids, self._values
        before = len(ids)
        for key, v in changes.items():
            i = index.get(key)
            if i is None:
                if self.strict:
                    self._lookup(key)
                continue
            ids.append(i)
            values.append(v)
        k = len(ids) - before
        if k:
            self._call_times.append(time_fs)
            self._call_counts.append(k)
            if len(ids) >= _CHUNK:
                self._pack()

    def _pack(self) -> None:
        if not self._ids:
            return
        try:
            values = np.array(self._values, dtype=np.uint64)
        except (OverflowError, TypeError, ValueError):
            bad = next(v for v in self._values if not _is_int(v) or not 0 <= v < 1 << 64)
            raise ConfigError(
                f"trace value {bad!r} is not an unsigned integer below 2**64"
            ) from None
        times = np.repeat(
            np.array(self._call_times, dtype=np.int64), np.array(self._call_counts, dtype=np.int64)
        )
        self._chunks.append((times, np.array(self._ids, dtype=np.int32), values))
        self._ids, self._values, self._call_times, self._call_counts = [], [], [], []

    def log(self, end_fs: int | None = None) -> TraceLog:
        """The recorded :class:`TraceLog`, validated. ``end_fs`` defaults to the recorder's
        ``end_fs``, else to one femtosecond after the last reported instant."""
        self._pack()
        if end_fs is None:
            end_fs = self.end_fs
        if end_fs is None:
            last = self._last_fs if self._last_fs is not None else self.start_fs
            end_fs = max(last, self.start_fs) + 1
        if self._chunks:
            times, ids, values = (np.concatenate(c) for c in zip(*self._chunks))
        else:
            times = np.zeros(0, np.int64)
            ids = np.zeros(0, np.int32)
            values = np.zeros(0, np.uint64)
        try:
            initial = np.array(self._state, dtype=np.uint64)
        except (OverflowError, TypeError, ValueError):
            raise ConfigError(
                "an initial trace value is not an unsigned integer below 2**64"
            ) from None
        keep = times < end_fs
        return validate(TraceLog(
            signals=list(self.signals), clocks=list(self.clocks), start_fs=self.start_fs,
            end_fs=int(end_fs), initial=initial, times_fs=times[keep], ids=ids[keep],
            values=values[keep],
        ))


def changes_of(log: TraceLog, sig_id: int) -> tuple[np.ndarray, np.ndarray]:
    """Signal ``sig_id``'s value at ``start_fs`` and at each real change after it: instants
    (int64, the first is ``start_fs``) and values (uint64), with the log's semantics applied
    (the last change at an instant wins, repeats are dropped)."""
    sel = log.ids == sig_id
    t = log.times_fs[sel]
    v = log.values[sel]
    if t.size:
        last = np.ones(t.size, dtype=bool)
        last[:-1] = t[1:] != t[:-1]
        t, v = t[last], v[last]
    if t.size and t[0] == log.start_fs:
        t, v = t.copy(), v.copy()
    else:
        t = np.concatenate([np.array([log.start_fs], np.int64), t])
        v = np.concatenate([log.initial[sig_id : sig_id + 1], v])
    keep = np.ones(t.size, dtype=bool)
    keep[1:] = v[1:] != v[:-1]
    return t[keep], v[keep]
