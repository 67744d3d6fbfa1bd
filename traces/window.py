"""The one window syntax of ``stereosim run --trace-window`` and ``stereosim wave --window``.

A window is ``A:B``, optionally after a kind: ``KIND:A:B``. A missing bound is the start or the
end (of the frame for ``run``, of the dump for ``wave``).

* **Times**: bounds with a unit -- ``fs``, ``ps``, ``ns``, ``us``, ``ms``, ``s`` -- and decimals
  allowed: ``0:100us``, ``1.5ns:2.25ns``, ``:40us``, ``2us:``. A bare ``0`` may stand for the
  time zero (``0:100us``); any other bare number beside a time is refused, since it is unclear
  what it counts.
* **Cycles**: ``nna:A:B``, ``sva:A:B``, ``camera:A:B`` -- whole clock cycles of that domain,
  cycle ``k`` starting at the domain's rising edge ``k`` (``wave`` reads the clock's period and
  phase off the dump's clock wire).
* **Rows**: ``rows:A:B`` -- image rows (``run`` only: ``wave`` refuses it).
* **Bare numbers**: ``A:B`` without units or kind means the command's default: SVA cycles for
  ``run``, the dump's time unit (fs for stereosim's dumps) for ``wave``.

:func:`parse_window` turns the text into a :class:`Window`; each command resolves it against
what it knows (a chip plan's clocks, a dump's time unit and clock wires). Errors are one-line
ConfigErrors that name the option and show valid examples.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from fractions import Fraction

from stereosim.core.errors import ConfigError

UNIT_FS = {"fs": 1, "ps": 10**3, "ns": 10**6, "us": 10**9, "ms": 10**12, "s": 10**15}
DOMAINS = ("sva", "nna", "camera")
TIME, ROWS, UNITS = "time", "rows", "units"
_BOUND = re.compile(r"(\d+(?:\.\d*)?|\.\d+)\s*(fs|ps|ns|us|ms|s)?")
#: The largest bound: 2**63 - 1 (femtoseconds for a time, else cycles, rows or time units),
#: the largest instant a dump holds (traces.vcdread.MAX_TIME).
MAX_BOUND = 2**63 - 1
#: A bound's number has at most this many characters (2**63 - 1 has 19 digits; decimals
#: finer than 1 fs round away).
MAX_BOUND_CHARS = 40
EXAMPLES = "e.g. 0:100us, 1.5ns:2us, sva:0:3000, nna:100:400 or rows:0:12"
TIME_EXAMPLES = "e.g. 0:40us, 1.5ns:2us or :500ns"


@dataclass(frozen=True)
class Window:
    """A parsed window: ``kind`` is ``"time"`` (bounds in fs, exact fractions rounded to whole
    fs), a clock domain name (bounds in cycles), ``"rows"`` (image rows) or ``"units"`` (bare
    numbers in the dump's time unit); ``None`` is an open bound."""

    kind: str
    start: int | None
    end: int | None

    @property
    def is_time(self) -> bool:
        return self.kind == TIME


def _shown(spec: str) -> str:
    """``spec`` as an error message quotes it: cut to 60 characters."""
    return repr(spec) if len(spec) <= 60 else f"{spec[:60]!r}... ({len(spec)} characters)"


def _bound(text: str, spec: str, option: str, examples: str) -> tuple[Fraction, str | None] | None:
    """``(number, unit or None)`` of one bound, None when empty."""
    text = text.strip()
    if not text:
        return None
    m = _BOUND.fullmatch(text)
    if m and len(m.group(1)) > MAX_BOUND_CHARS:
        raise ConfigError(
            f"{option} {_shown(spec)}: a bound of {len(m.group(1))} characters, more than a "
            f"window can span (at most 2**63 - 1 fs); {examples}"
        )
    if not m:
        raise ConfigError(
            f"{option} {_shown(spec)}: bound {_shown(text)} is not a number with an optional unit "
            f"(fs, ps, ns, us, ms, s); {examples}"
        )
    return Fraction(m.group(1)), m.group(2)


def parse_window(spec: str | None, *, default: str = "sva", option: str = "--trace-window",
                 kinds: tuple[str, ...] = (*DOMAINS, ROWS)) -> Window:
    """Parse ``spec`` (see the module docstring). ``default`` is the kind of bare numbers
    (a domain name, or ``"units"``); ``kinds`` the prefixes the command accepts. ``None`` is the
    whole run: ``Window(default, None, None)``."""
    if spec is None:
        return Window(default, None, None)
    examples = EXAMPLES if kinds else TIME_EXAMPLES
    parts = spec.split(":")
    kind = None
    if len(parts) == 3:
        kind, parts = parts[0].strip(), parts[1:]
        if kind not in kinds:
            want = (f"A:B or KIND:A:B with KIND one of {', '.join(kinds)}" if kinds else
                    "a time window A:B (cycle and row windows need stereosim run --trace-window)")
            raise ConfigError(f"{option} {_shown(spec)}: expected {want}; {examples}")
    if len(parts) != 2:
        raise ConfigError(
            f"{option} {_shown(spec)}: expected A:B (a start and an end); {examples}")
    bounds = [_bound(p, spec, option, examples) for p in parts]
    timed = [b is not None and b[1] is not None for b in bounds]
    if kind is not None or not any(timed):
        kind = kind or default
        values = []
        for b in bounds:
            if b is not None and (b[1] is not None or b[0].denominator != 1):
                what = "cycles" if kind in DOMAINS else "rows" if kind == ROWS else "time units"
                raise ConfigError(
                    f"{option} {_shown(spec)}: {kind} bounds count {what}, so they are whole "
                    f"numbers without a unit; for times write A:B with units, e.g. 0:100us"
                )
            values.append(None if b is None else int(b[0]))
    else:
        kind, values = TIME, []
        for b in bounds:
            if b is None:
                values.append(None)
            elif b[1] is None and b[0] != 0:
                raise ConfigError(
                    f"{option} {_shown(spec)} mixes a time and a bare number: give both bounds a "
                    f"unit, e.g. 100ns:2us"
                )
            else:
                values.append(round(b[0] * UNIT_FS[b[1] or "fs"]))
    start, end = values
    for value in values:
        if value is not None and value > MAX_BOUND:
            what = ("fs" if kind == TIME else "cycles" if kind in DOMAINS else
                    "time units" if kind == UNITS else kind)
            raise ConfigError(
                f"{option} {_shown(spec)}: a bound of {value} {what} is above 2**63 - 1; "
                f"{examples}"
            )
    if start is not None and end is not None and not start < end:
        raise ConfigError(f"{option} {_shown(spec)} is empty: need 0 <= A < B")
    return Window(kind, start, end)
