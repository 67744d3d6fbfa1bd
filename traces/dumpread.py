"""Read a waveform dump back, VCD or FST, into one :class:`~traces.vcdread.VcdData`.

:func:`read_dump` tells the formats apart by the first byte: an FST file starts with a block
type byte, 0 (its header block) or 254 (a whole file compressed into one wrapper block), which no
VCD -- ASCII text -- can start with; anything else goes to the VCD reader. The file name does not
matter.

* **VCD** goes through the project's own reader (:mod:`traces.vcdread`). pywellen reads VCD too,
  but leniently: it drops the value changes written on the line of ``$enddefinitions``, reads a
  30-digit timestamp as 2**64 - 1, skips a time that goes back with a warning on stderr and
  aborts on a malformed vector with a Rust panic; the project's reader refuses each of those
  with one line.
* **FST** goes through pywellen (Surfer's reader; libfst's own reader exits the process on a
  corrupt block), after :func:`traces.fstcheck.checked_fst` has checked its blocks' types and
  declared lengths (the reader allocates what a block declares, and aborts the process when
  it cannot) and inflated a wrapped file in bounded chunks: a file that fails is refused with
  one line before pywellen sees it. Its first and last instants are the header's start and
  end times -- the last instant of a stereosim dump carries no value change (it marks the
  window's end), so the instants that hold changes would lose it. Values are integers, or
  None for unknown bits (``x``, ``z``, ...) and real values, as the VCD reader gives them. A
  corrupt FST makes pywellen raise, or panic; both become an :class:`core.errors.InputError`
  with one line, and what the panic prints on the process's stderr is swallowed
  (:func:`_stderr_swallowed`).
"""

from __future__ import annotations

import contextlib
import os
import struct
import sys
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

from stereosim.core.errors import InputError, UserError
from stereosim.traces.fstcheck import checked_fst
from stereosim.traces.vcdread import MAX_TIME, VcdData, VcdVar, read_vcd

#: FST block types a file may start with (libfst's FST_BL_HDR and FST_BL_ZWRAPPER).
FST_HEADER_BLOCK, FST_WRAPPER_BLOCK = 0, 254
#: The header block: type (1 byte), section length, start time, end time (big-endian uint64).
_HEADER = struct.Struct(">BQQQ")


def read_dump(path: str | os.PathLike, select: Callable | None = None) -> VcdData:
    """Parse the VCD or FST at ``path``; ``select`` as in :func:`traces.vcdread.read_vcd`."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"dump file {p} not found: check the path")
    try:
        with open(p, "rb") as f:
            first = f.read(1)
    except OSError as exc:
        raise InputError(
            f"cannot read dump file {p} ({exc.strerror}): check its permissions"
        ) from exc
    if first and first[0] in (FST_HEADER_BLOCK, FST_WRAPPER_BLOCK):
        return read_fst(p, select)
    return read_vcd(p, select)


@contextlib.contextmanager
def _stderr_swallowed() -> Iterator[None]:
    """Send what is written to file descriptor 2 to a scratch file while the block runs: a Rust
    panic in pywellen prints its message (and a backtrace under RUST_BACKTRACE) there, below
    Python, and the command's promise is one line on stderr."""
    if sys.stderr is not None:
        sys.stderr.flush()
    try:
        saved = os.dup(2)
    except OSError:  # no stderr at all (2>&-): nothing to keep clean
        yield
        return
    try:
        with tempfile.TemporaryFile() as scratch:
            os.dup2(scratch.fileno(), 2)
            try:
                yield
            finally:
                os.dup2(saved, 2)
    finally:
        os.close(saved)


def _is_reader_failure(exc: BaseException) -> bool:
    """pywellen's errors on a bad file: RuntimeError (and OSError, ValueError), and pyo3's
    PanicException -- a subclass of BaseException, not of Exception, that pyo3 does not
    export. Anything else (a bug of ours) is not called a corrupt file."""
    return (isinstance(exc, (RuntimeError, OSError, ValueError))
            or type(exc).__name__ == "PanicException")


def _time_range(p: Path, unwrapped: Path) -> tuple[int, int]:
    """The start and end times of the FST's header block (``unwrapped``: the file, or what its
    wrapper held, already checked by :func:`traces.fstcheck.checked_fst`); InputError if the
    header is not there."""
    try:
        with open(unwrapped, "rb") as f:
            head = f.read(_HEADER.size)
    except OSError as exc:
        raise InputError(f"FST file {p} is corrupt ({exc}): replace it") from None
    if len(head) < _HEADER.size or head[0] != FST_HEADER_BLOCK:
        raise InputError(f"FST file {p} has no header block: it is truncated, replace it")
    _, _, start, end = _HEADER.unpack(head)
    if not start <= end <= MAX_TIME:
        raise InputError(
            f"FST file {p} declares the times {start} to {end}: the end must not come before "
            f"the start, nor pass 2**63 - 1; replace it"
        )
    return start, end


def _unit_fs(wave, p: Path) -> int:
    """Femtoseconds per time unit of the FST's timescale (1 fs to 100 s, as the VCD reader)."""
    scale = wave.timescale
    if scale is None:
        return 10**6  # 1 ns, as the VCD reader assumes for a dump that declares none
    exponent = scale.unit.to_exponent() + 15
    if scale.factor not in (1, 10, 100) or not 0 <= exponent <= 15:
        raise InputError(f"FST file {p} has the timescale {scale}: expected 1 fs to 100 s")
    return scale.factor * 10**exponent


def read_fst(path: str | os.PathLike, select: Callable | None = None) -> VcdData:
    """Parse the FST at ``path`` (see the module docstring); ``select`` as in
    :func:`traces.vcdread.read_vcd`. Variable codes are the signal ids pywellen gives, so
    two names of one signal share their changes, as two VCD variables of one code do."""
    p = Path(path)
    with checked_fst(p) as unwrapped:
        return _read_checked_fst(p, unwrapped, select)


def _read_checked_fst(p: Path, unwrapped: Path, select: Callable | None) -> VcdData:
    """:func:`read_fst` of the file ``p``, its layout checked and unwrapped at ``unwrapped``."""
    import pywellen

    first, last = _time_range(p, unwrapped)
    try:
        with _stderr_swallowed():
            wave = pywellen.Waveform(str(unwrapped), multi_threaded=False)
            unit_fs = _unit_fs(wave, p)
            handles = list(wave.all_vars())
            variables = [
                # a real variable has no bit width: drawn as a bus of unknown value
                VcdVar(h.full_name, h.bitwidth or 64, str(h.signal_id)) for h in handles
            ]
            if not variables:
                raise InputError(f"FST file {p} declares no variables")
            keep = {v.code for v in (variables if select is None else select(variables))}
            changes: dict[str, tuple[list[int], list[int | None]]] = {c: ([], []) for c in keep}
            # pywellen streams each signal once per Waveform: ask for every kept one together
            wanted, seen = [], set()
            for h, v in zip(handles, variables):
                if v.code in keep and v.code not in seen:
                    seen.add(v.code)
                    wanted.append(h)

            def change(t: int, signal, value) -> None:
                times, values = changes[str(signal)]
                times.append(t)
                values.append(value if isinstance(value, int) else None)

            if wanted:
                wave.stream_changes(change, wanted)
    except UserError:  # (select's, or ours)
        raise
    except BaseException as exc:
        if not _is_reader_failure(exc):
            raise
        text = "".join(c if c.isprintable() else "?" for c in " ".join(str(exc).split()))
        why = text[:200] or type(exc).__name__
        raise InputError(f"FST file {p} is corrupt ({why}): replace it") from None
    for times, _ in changes.values():
        if times and not first <= times[0] <= times[-1] <= last:
            raise InputError(
                f"FST file {p} has a value change at {times[0] if times[0] < first else times[-1]}"
                f", outside its declared times {first} to {last}: it is corrupt, replace it"
            )
    return VcdData(unit_fs=unit_fs, vars=variables, first_time=first, last_time=last,
                   changes=changes)
