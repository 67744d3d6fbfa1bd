"""An FST file's block layout, checked before the reader library (pywellen) opens it.

The reader trusts the lengths a file declares: it allocates a block's declared uncompressed
size, and a declared count of signals or instants, before it reads a byte of them, and an
allocation it cannot make aborts the whole process (SIGABRT, no line at all); a wrapper block
(a whole file compressed with gzip) it inflates whole to a scratch file. So :func:`checked_fst`
walks the blocks first and refuses, with one line, a file whose

* block has a type FST does not define, or a length that runs past the file's end (or, for
  the header block, is not the header's 329 bytes; a file has one header, first);
* declared uncompressed sizes -- of the value-change blocks' time tables and first frames, of
  the geometry and the hierarchy -- add up to more than :data:`MAX_UNPACKED_BYTES`, or whose
  declared counts (signals, instants, blackouts) exceed what the block's bytes can hold or
  :data:`MAX_SIGNALS`;
* value-change block's parts (first frame, signal table, time table) do not fit in it, or whose
  signal table lists more signals than the block declares.

A wrapped file is inflated here, in chunks of :data:`CHUNK_BYTES`, into a private scratch file
that is then checked as above and is what the reader opens (it never sees the wrapper): one
that declares more than :data:`MAX_FST_BYTES`, or inflates to more or less than it declares,
is refused as soon as that is known, so neither memory nor disk grows past the cap.

The layout (block types, the fields of each block) is FST's as GTKWave's ``fstapi`` writes it
and its documentation describes; every integer of a block's head is big-endian, the lengths
inside value-change blocks are LEB128 varints.
"""

from __future__ import annotations

import contextlib
import os
import struct
import tempfile
import zlib
from collections.abc import Iterator
from pathlib import Path

from stereosim.core.errors import InputError

#: The most a wrapped file may inflate to (on disk, in a scratch file).
MAX_FST_BYTES = 1 << 30
#: The most the blocks of a file may declare to be uncompressed to, all together (in memory).
MAX_UNPACKED_BYTES = 1 << 28
#: The most signals (and blackout entries) a file may declare.
MAX_SIGNALS = 1 << 20
#: What the wrapper's inflation reads and writes at a time.
CHUNK_BYTES = 1 << 20

HEADER, VC_DATA, BLACKOUT, GEOMETRY, HIERARCHY = 0, 1, 2, 3, 4
VC_DATA_ALIAS, HIERARCHY_LZ4, HIERARCHY_LZ4_DUO, VC_DATA_ALIAS2 = 5, 6, 7, 8
WRAPPER, SKIP = 254, 255
BLOCK_NAMES = {
    HEADER: "header", VC_DATA: "value-change", BLACKOUT: "blackout", GEOMETRY: "geometry",
    HIERARCHY: "hierarchy", VC_DATA_ALIAS: "value-change", HIERARCHY_LZ4: "hierarchy",
    HIERARCHY_LZ4_DUO: "hierarchy", VC_DATA_ALIAS2: "value-change", SKIP: "skip",
}
VC_BLOCKS = (VC_DATA, VC_DATA_ALIAS, VC_DATA_ALIAS2)
HIERARCHY_BLOCKS = (HIERARCHY, HIERARCHY_LZ4, HIERARCHY_LZ4_DUO)
#: The header block's length field: the header is 329 bytes after its type byte.
HEADER_LENGTH = 329
_U64 = struct.Struct(">Q")
_WRAPPER_HEAD = struct.Struct(">BQQ")  # type, section length, uncompressed length
_VARINT_MAX_BYTES = 10


def _corrupt(p: Path, why: str) -> InputError:
    return InputError(f"FST file {p} is corrupt ({why}): replace it")


def _too_large(p: Path, what: str, cap: int) -> InputError:
    return InputError(
        f"FST file {p} {what}, above the {cap:,} that stereosim reads: it is corrupt or too "
        "large; replace it, or trace a narrower window"
    )


class _Reader:
    """Random access to the file's bytes, each read checked against the block it belongs to."""

    def __init__(self, f, size: int, p: Path):
        self.f, self.size, self.p = f, size, p

    def read(self, at: int, n: int, end: int, what: str) -> bytes:
        if at < 0 or n < 0 or at + n > end:
            raise _corrupt(self.p, f"{what} at byte {at} does not fit in its block")
        self.f.seek(at)
        data = self.f.read(n)
        if len(data) != n:
            raise _corrupt(self.p, f"{what} at byte {at} is cut short")
        return data

    def u64(self, at: int, end: int, what: str) -> int:
        return _U64.unpack(self.read(at, 8, end, what))[0]

    def varint(self, at: int, end: int, what: str) -> tuple[int, int]:
        """An unsigned LEB128 varint at ``at``: ``(value, the byte after it)``."""
        data = self.read(at, min(_VARINT_MAX_BYTES, end - at), end, what) if at < end else b""
        value = 0
        for i, byte in enumerate(data):
            value |= (byte & 0x7F) << (7 * i)
            if not byte & 0x80:
                return value, at + i + 1
        raise _corrupt(self.p, f"{what} at byte {at} is not a number")


def _chain_entries(chain: bytes, alias2: bool) -> int:
    """How many signals a value-change block's signal table lists: an entry is one signal,
    except an even number ``2k`` that stands for ``k`` signals without changes (in the older
    format an entry 0 is followed by the signal it aliases; in the newer, ``alias2``, an entry
    is one signal when its first byte is odd)."""
    entries = i = 0
    n = len(chain)

    def varint() -> int:
        nonlocal i
        value = shift = 0
        while i < n:
            byte = chain[i]
            i += 1
            value |= (byte & 0x7F) << shift
            shift += 7
            if not byte & 0x80:
                return value
        return value

    while i < n:
        if alias2:
            odd = chain[i] & 1
            value = varint()
            entries += 1 if odd else value >> 1
        else:
            value = varint()
            if value == 0:
                varint()  # an alias of an earlier signal
                entries += 1
            else:
                entries += 1 if value & 1 else value >> 1
    return entries


def _check_vc(r: _Reader, start: int, end: int, kind: int, signals: int | None) -> int:
    """A value-change block (its length field at ``start``); returns the bytes it declares
    uncompressed."""
    p = r.p
    # the time table's three lengths close the block: uncompressed, compressed, instants
    t_raw, t_packed, instants = (r.u64(end - 24 + 8 * k, end, "a time table length")
                                 for k in range(3))
    # the head: length, start time, end time, memory needed (4 x 8 bytes), then the frame
    frame_at = start + 32
    if t_packed > end - 24 - frame_at:
        raise _corrupt(p, f"a value-change block at byte {start - 1} declares a time table of "
                          f"{t_packed} bytes, more than the block holds")
    if instants > t_raw:
        raise _corrupt(p, f"a value-change block at byte {start - 1} declares {instants} "
                          f"instants in a time table of {t_raw} bytes")
    f_raw, q = r.varint(frame_at, end, "a frame length")
    f_packed, q = r.varint(q, end, "a frame length")
    f_signals, q = r.varint(q, end, "a frame's signal count")
    q += f_packed
    vc_signals, q = r.varint(q, end, "a signal count")
    for count in (f_signals, vc_signals):
        if count > MAX_SIGNALS:
            raise _too_large(p, f"declares {count:,} signals in a value-change block",
                             MAX_SIGNALS)
        if signals is not None and count > signals:
            raise _corrupt(p, f"a value-change block at byte {start - 1} declares {count} "
                              f"signals, the geometry only {signals}")
    vc_start = q  # the pack type byte, then each signal's changes, then the signal table
    chain_len_at = end - 24 - t_packed - 8
    if chain_len_at < vc_start + 1:
        raise _corrupt(p, f"the parts of the value-change block at byte {start - 1} overlap")
    chain_len = r.u64(chain_len_at, end, "a signal table length")
    if chain_len > chain_len_at - vc_start or chain_len > _VARINT_MAX_BYTES * vc_signals + 10:
        raise _corrupt(p, f"a value-change block at byte {start - 1} declares a signal table "
                          f"of {chain_len} bytes, more than its {vc_signals} signals need")
    chain = r.read(chain_len_at - chain_len, chain_len, end, "a signal table")
    listed = _chain_entries(chain, kind == VC_DATA_ALIAS2)
    if listed > vc_signals:
        raise _corrupt(p, f"a value-change block at byte {start - 1} lists {listed} signals "
                          f"in its table, more than the {vc_signals} it declares")
    return t_raw + f_raw


def check_blocks(f, size: int, p: Path) -> None:
    """Walk the (unwrapped) FST of open binary file ``f`` of ``size`` bytes; InputError naming
    ``p`` for a block the reader library must not be given (see the module docstring)."""
    r = _Reader(f, size, p)
    blocks = []
    pos = 0
    while pos < size:
        kind = r.read(pos, 1, size, "a block type")[0]
        if kind not in BLOCK_NAMES:
            raise _corrupt(p, f"the block at byte {pos} has the type {kind}, which FST does not "
                              "define" + (" there" if kind == WRAPPER else ""))
        name = BLOCK_NAMES[kind]
        if size - pos < 9:
            raise _corrupt(p, f"the {name} block at byte {pos} is cut short")
        length = r.u64(pos + 1, size, "a block length")
        if length < 8 or length > size - pos - 1:
            raise _corrupt(p, f"the {name} block at byte {pos} declares {length} bytes, past "
                              f"the file's end at byte {size}")
        if kind == HEADER and (pos != 0 or length != HEADER_LENGTH):
            raise _corrupt(p, f"a header block at byte {pos} of {length} bytes (one header "
                              f"of {HEADER_LENGTH} bytes, first)")
        blocks.append((kind, pos + 1, pos + 1 + length))
        pos += 1 + length
    if not blocks or blocks[0][0] != HEADER:
        raise _corrupt(p, "it has no header block")
    if sum(kind in HIERARCHY_BLOCKS for kind, _, _ in blocks) > 1:
        raise _corrupt(p, "it has more than one hierarchy block")
    unpacked = 0
    signals = None
    # the geometry (how many signals) first: it follows the value changes in the file
    for kind, start, end in blocks:
        if kind == GEOMETRY:
            raw = r.u64(start + 8, end, "the geometry's length")
            count = r.u64(start + 16, end, "the geometry's signal count")
            if count > MAX_SIGNALS:
                raise _too_large(p, f"declares {count:,} signals", MAX_SIGNALS)
            if count > raw:
                raise _corrupt(p, f"its geometry declares {count} signals in {raw} bytes")
            signals = count if signals is None else signals
            unpacked += raw
        elif kind in HIERARCHY_BLOCKS:
            unpacked += r.u64(start + 8, end, "the hierarchy's length")
            if kind == HIERARCHY_LZ4_DUO:
                unpacked += r.varint(start + 16, end, "the hierarchy's length")[0]
        elif kind == BLACKOUT:
            count, _ = r.varint(start + 8, end, "the blackout count")
            if count > (end - start - 8) // 2:
                raise _corrupt(p, f"its blackout block declares {count} entries, more than it "
                                  "holds")
        if unpacked > MAX_UNPACKED_BYTES:
            break
    for kind, start, end in blocks:
        if unpacked > MAX_UNPACKED_BYTES:
            break
        if kind in VC_BLOCKS:
            unpacked += _check_vc(r, start, end, kind, signals)
    if unpacked > MAX_UNPACKED_BYTES:
        raise _too_large(p, f"declares {unpacked:,} bytes of uncompressed data (or more)",
                         MAX_UNPACKED_BYTES)


def _unwrap(f, size: int, p: Path, out) -> None:
    """Inflate the wrapper block of open file ``f`` into ``out`` in bounded chunks."""
    f.seek(0)
    head = f.read(_WRAPPER_HEAD.size)
    if len(head) < _WRAPPER_HEAD.size:
        raise _corrupt(p, "its wrapper block is cut short")
    _, length, declared = _WRAPPER_HEAD.unpack(head)
    if length == 0:
        raise _corrupt(p, "its wrapper block was never finished")
    if length < 16 or length > size - 1:
        raise _corrupt(p, f"the wrapper block declares {length} bytes, past the file's end at "
                          f"byte {size}")
    if declared > MAX_FST_BYTES:
        raise _too_large(p, f"declares {declared:,} bytes inside its wrapper block",
                         MAX_FST_BYTES)
    left = length - 16
    inflate = zlib.decompressobj(wbits=16 + zlib.MAX_WBITS)  # a gzip stream
    pending = b""
    written = 0
    try:
        while not inflate.eof:
            if not pending and left:
                pending = f.read(min(CHUNK_BYTES, left))
                left = left - len(pending) if pending else 0
            piece = inflate.decompress(pending, CHUNK_BYTES)
            pending = inflate.unconsumed_tail
            if not piece and not pending and not left:
                break
            written += len(piece)
            if written > declared:
                raise _corrupt(p, f"its wrapper block inflates past the {declared:,} bytes it "
                                  "declares")
            out.write(piece)
    except zlib.error as exc:
        raise _corrupt(p, f"its wrapper block: {exc}") from None
    if not inflate.eof or written != declared:
        raise _corrupt(p, f"its wrapper block inflates to {written:,} bytes, not the "
                          f"{declared:,} it declares")


def _unwrapped(p: Path) -> Path | None:
    """Check the file at ``p``: None when it is not wrapped, else the path of a new scratch
    file holding what its wrapper held (checked too; the caller removes it)."""
    scratch = None
    try:
        with open(p, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            if f.read(1) != bytes([WRAPPER]):
                f.seek(0)
                check_blocks(f, size, p)
                return None
            fd, scratch = tempfile.mkstemp(suffix=".fst")
            with os.fdopen(fd, "w+b") as out:
                _unwrap(f, size, p, out)
                out.flush()
                check_blocks(out, out.tell(), p)
            return Path(scratch)
    except BaseException as exc:
        if scratch is not None:
            os.unlink(scratch)
        if isinstance(exc, OSError):
            raise InputError(
                f"cannot read FST file {p} ({exc.strerror or exc}): check the file and the "
                "free space of the temporary folder"
            ) from None
        raise


@contextlib.contextmanager
def checked_fst(path: str | os.PathLike) -> Iterator[Path]:
    """Within the block, the path of an FST file whose layout passed :func:`check_blocks`:
    ``path`` itself, or for a wrapped file a private scratch file holding what the wrapper
    held (removed on leaving the block). InputError with one line otherwise."""
    p = Path(path)
    scratch = _unwrapped(p)
    try:
        yield p if scratch is None else scratch
    finally:
        if scratch is not None:
            os.unlink(scratch)
