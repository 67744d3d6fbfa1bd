"""Read a VCD file back (any IEEE 1364 four-state dump, not only stereosim's).

:func:`read_vcd` returns the variables (dotted path, width) and, for the variables asked for, their
value changes; ``x``/``z`` digits make a value unknown (``None``) and real values are read as
unknown too. Anything that is not a readable VCD raises :class:`core.errors.InputError` with one
line naming the file; so does a timestamp above :data:`MAX_TIME` (2**63 - 1 time units, the
largest instant numpy's int64 and FST's times hold). :mod:`traces.dumpread` reads FST files
into the same :class:`VcdData`.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from stereosim.core.errors import InputError

_UNITS_FS = {"s": 10**15, "ms": 10**12, "us": 10**9, "ns": 10**6, "ps": 10**3, "fs": 1}
_RANGE = re.compile(r"\[[^\]]*\]$")
MAX_TIME = 2**63 - 1


@dataclass
class VcdVar:
    path: str  # dotted scope path and name, without a bit range
    width: int
    code: str


@dataclass
class VcdData:
    """A parsed dump (a VCD, or an FST read by :mod:`traces.dumpread`): ``unit_fs``
    femtoseconds per time unit, the variables, the first and last timestamps, and
    ``changes[code] = (times, values)`` for the variables read."""

    unit_fs: int
    vars: list[VcdVar]
    first_time: int
    last_time: int
    changes: dict[str, tuple[list[int], list[int | None]]] = field(default_factory=dict)


def timescale_fs(text: str, path: Path) -> int:
    """Femtoseconds a unit of a VCD's ``$timescale`` ``text`` (of ``path``), e.g. ' 1 ns '."""
    m = re.fullmatch(r"\s*(1|10|100)\s*(s|ms|us|ns|ps|fs)\s*", text)
    if not m:
        raise InputError(f"VCD file {path} has the timescale '{text.strip()}': expected e.g. 1 ns")
    return int(m.group(1)) * _UNITS_FS[m.group(2)]


def _parse_header(header: str, path: Path) -> tuple[int, list[VcdVar]]:
    tokens = header.split()
    unit_fs = 10**6  # 1 ns if the dump declares none
    scopes: list[str] = []
    out: list[VcdVar] = []
    k = 0
    try:
        while k < len(tokens):
            tok = tokens[k]
            end = tokens.index("$end", k + 1) if tok.startswith("$") else k + 1
            args = tokens[k + 1 : end]
            if tok == "$scope":
                scopes.append(args[1])
            elif tok == "$upscope":
                scopes.pop()
            elif tok == "$timescale":
                unit_fs = timescale_fs(" ".join(args), path)
            elif tok == "$var":
                width, code, name = int(args[1]), args[2], "".join(args[3:])
                if width < 1:
                    raise ValueError(tok)
                name = _RANGE.sub("", name)
                out.append(VcdVar(".".join([*scopes, name]), width, code))
            elif not tok.startswith("$"):
                raise ValueError(tok)
            k = end + 1
    except InputError:
        raise
    except (ValueError, IndexError):
        raise InputError(
            f"VCD file {path} has a corrupt header near token {k} ('{tokens[k][:20]}'): "
            "replace the file"
        ) from None
    return unit_fs, out


def _timestamp(tok: str) -> int:
    """The time of ``#digits``; ValueError (a corrupt dump) for anything else or above
    :data:`MAX_TIME` (checked on the digit count first: int() refuses 4300 digits)."""
    digits = tok[1:]
    if not (digits.isascii() and digits.isdigit()):
        raise ValueError(f"bad timestamp '{tok[:20]}'")
    if len(digits) > len(str(MAX_TIME)) or int(digits) > MAX_TIME:
        raise ValueError(f"timestamp #{digits[:12]}... has {len(digits)} digits, above "
                         "2**63 - 1, the largest time a dump may hold")
    return int(digits)


def read_vcd(path: str | os.PathLike, select: Callable | None = None) -> VcdData:
    """Parse ``path``. ``select(vars) -> vars`` chooses, once the header is read, the variables
    whose changes are kept (all when None); it may raise to stop early."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"VCD file {p} not found: check the path")
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise InputError(
            f"cannot read VCD file {p} ({exc.strerror}): check its permissions"
        ) from exc
    try:
        text = data.decode("ascii")
    except UnicodeDecodeError:
        raise InputError(
            f"dump file {p} is not ASCII text, nor an FST: it is not a dump, replace it"
        ) from None
    head, sep, body = text.partition("$enddefinitions")
    if not sep:
        raise InputError(f"VCD file {p} has no $enddefinitions: it is not a VCD or is truncated")
    unit_fs, variables = _parse_header(head, p)
    if not variables:
        raise InputError(f"VCD file {p} declares no variables")
    keep = {v.code for v in (variables if select is None else select(variables))}
    changes: dict[str, tuple[list[int], list[int | None]]] = {c: ([], []) for c in keep}
    tokens = body.split()
    if not tokens or tokens[0] != "$end":
        raise InputError(f"VCD file {p}: $enddefinitions is not closed by $end")
    now = first = None
    k, n = 1, len(tokens)
    try:
        while k < n:
            tok = tokens[k]
            c0 = tok[0]
            if c0 == "#":
                t = _timestamp(tok)
                if now is not None and t < now:
                    raise ValueError(f"time goes back from #{now} to #{t}")
                now = t
                if first is None:
                    first = t
                k += 1
                continue
            if c0 == "$":
                if tok == "$comment":
                    k = tokens.index("$end", k + 1)
                k += 1
                continue
            if now is None:
                raise ValueError("a value change before the first timestamp")
            if c0 in "bBrR":
                code = tokens[k + 1]
                if code in keep:
                    digits = tok[1:]
                    value = int(digits, 2) if c0 in "bB" and digits.isdigit() else None
                    if value is None and c0 in "bB" and not set(digits) <= set("01xXzZ"):
                        raise ValueError(f"bad vector value '{tok[:20]}'")
                    changes[code][0].append(now)
                    changes[code][1].append(value)
                k += 2
                continue
            if c0 in "01xXzZ":
                code = tok[1:]
                if not code:
                    raise ValueError(f"value '{tok}' without an identifier")
                if code in keep:
                    changes[code][0].append(now)
                    changes[code][1].append(int(c0) if c0 in "01" else None)
                k += 1
                continue
            raise ValueError(f"unexpected token '{tok[:20]}'")
    except (ValueError, IndexError) as exc:
        raise InputError(
            f"VCD file {p} is corrupt in its value changes ({exc}): replace it"
        ) from None
    if now is None:
        raise InputError(f"VCD file {p} has no timestamp: it holds no values")
    return VcdData(unit_fs=unit_fs, vars=variables, first_time=first, last_time=now,
                   changes=changes)


def value_at(times: list[int], values: list, t: int):
    """The value at time ``t`` of a change list (None before the first change)."""
    from bisect import bisect_right

    k = bisect_right(times, t)
    return values[k - 1] if k else None
