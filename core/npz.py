"""Reading ``.npz`` archives (NNA weights, quantized artifacts, float models) bounded before
anything is inflated: the zip directory and every member's ``.npy`` header are checked first
(:func:`open_npz`), so an empty file, a header claiming 10^13 elements, a member that is not an
``.npy`` or a zip bomb is one :class:`core.errors.ConfigError` line naming the file."""

from __future__ import annotations

import math
import os
import zipfile
import zlib

import numpy as np

from stereosim.core.errors import ConfigError
from stereosim.core.io import mib, open_file, path_text

# The largest total of array bytes an .npz archive may hold: 256 MiB, over 2000 times the
# largest file the project writes (the shipped layer is 11 KB, a float mccnn4 model 112 KB).
MAX_NPZ_BYTES = 256 << 20
# The most members an .npz archive may have (a 4-layer quantized artifact has 29).
MAX_NPZ_MEMBERS = 1024
# Deflate shrinks real weights 1-3x and at most ~1032x (long runs of one byte): a member larger
# than _NPZ_RATIO_FLOOR_BYTES that is more than MAX_NPZ_RATIO times smaller in the archive is
# refused as a zip bomb, even when it is under MAX_NPZ_BYTES.
MAX_NPZ_RATIO = 100
_NPZ_RATIO_FLOOR_BYTES = 1 << 20


# ---------------------------------------------------------------------------------------------
# .npz archives


class NpzArrays(dict):
    """The arrays of an ``.npz`` archive, name -> array, read in full by :func:`open_npz`.

    Shaped like numpy's ``NpzFile``: :attr:`files` lists the names and ``with open_npz(...) as
    archive:`` works (the file is closed already). :meth:`field` and :meth:`scalar` fetch a
    value or raise a one-line ConfigError naming the file.
    """

    def __init__(self, name: str, what: str, arrays: dict[str, np.ndarray]):
        super().__init__(arrays)
        self.name, self.what, self.files = name, what, list(arrays)

    def __enter__(self) -> NpzArrays:  # noqa: PYI034 (not subclassed)
        return self

    def __exit__(self, *exc) -> None:
        return None

    def field(self, key: str) -> np.ndarray:
        """The array ``key``; ConfigError ``<what> <file> lacks the field <key>`` if absent."""
        if key not in self:
            raise ConfigError(f"{self.what} {path_text(self.name)!r} lacks the field {key!r}")
        return self[key]

    def scalar(self, key: str, kinds: str):
        """The 0-d array ``key`` of a dtype kind in ``kinds`` (``"iu"``, ``"f"``, ``"U"``...)
        as a Python value; ConfigError if it is missing, not 0-d or of another kind."""
        value = self.field(key)
        if value.shape != () or value.dtype.kind not in kinds:
            raise ConfigError(
                f"{self.what} {path_text(self.name)!r}: {key} must be a scalar, got "
                f"{value.dtype} {value.shape}"
            )
        return value.item()


# What a damaged zip or .npy header can raise from zipfile, zlib and numpy's header parser.
_NPZ_ERRORS = (OSError, ValueError, EOFError, OverflowError, RuntimeError, zlib.error)
_NPZ_ERRORS += (zipfile.BadZipFile,)
# Room for the zip's own headers on disk beyond MAX_NPZ_BYTES of members.
_NPZ_FILE_SLACK_BYTES = 64 << 20


def _npy_header(member) -> tuple[tuple, np.dtype, int]:
    """(shape, dtype, header length in bytes) of an ``.npy`` stream, from its header only."""
    version = np.lib.format.read_magic(member)
    if version == (1, 0):
        shape, _, dtype = np.lib.format.read_array_header_1_0(member)
    elif version == (2, 0):
        shape, _, dtype = np.lib.format.read_array_header_2_0(member)
    else:
        raise ValueError(f".npy format version {version[0]}.{version[1]} is not read here")
    return shape, dtype, member.tell()


def _checked_members(archive: zipfile.ZipFile, refuse) -> dict[str, zipfile.ZipInfo]:
    """Array name -> member of a zip, each member checked from the zip directory and its
    ``.npy`` header before anything is unpacked (:func:`open_npz`)."""
    infos = archive.infolist()
    total = sum(info.file_size for info in infos)
    if len(infos) > MAX_NPZ_MEMBERS or total > MAX_NPZ_BYTES:
        raise refuse(
            f"holds {len(infos)} members of {mib(total)} unpacked, more than the "
            f"{MAX_NPZ_MEMBERS} members and {mib(MAX_NPZ_BYTES)} allowed"
        )
    out: dict[str, zipfile.ZipInfo] = {}
    for info in infos:
        member, size, packed = repr(path_text(info.filename)), info.file_size, info.compress_size
        key = info.filename.removesuffix(".npy")
        if info.is_dir() or key == info.filename or key in out:
            raise refuse(f"holds {member}, which is not an .npy array of its own name")
        if info.flag_bits & 0x1 or info.compress_type not in (
            zipfile.ZIP_STORED,
            zipfile.ZIP_DEFLATED,
        ):
            raise refuse(f"member {member} is encrypted or packed otherwise than numpy does")
        if info.compress_type == zipfile.ZIP_STORED and packed != size:
            raise refuse(f"member {member} is stored with two different sizes: it is damaged")
        if size > _NPZ_RATIO_FLOOR_BYTES and size > MAX_NPZ_RATIO * packed:
            raise refuse(
                f"member {member} unpacks {size / max(packed, 1):.0f}x ({mib(size)} from "
                f"{mib(packed)}), beyond the {MAX_NPZ_RATIO}x of real arrays: a zip bomb?"
            )
        with archive.open(info) as stream:
            shape, dtype, header_bytes = _npy_header(stream)
        if dtype.hasobject:
            raise refuse(f"member {member} holds Python objects ({dtype}), which are never loaded")
        nbytes = math.prod(shape) * dtype.itemsize
        if min(shape, default=0) < 0 or nbytes > MAX_NPZ_BYTES or header_bytes + nbytes != size:
            raise refuse(
                f"member {member} claims {shape} {dtype} = {mib(nbytes)} in its header, but the "
                f"zip directory gives it {mib(size - header_bytes)} (and at most "
                f"{mib(MAX_NPZ_BYTES)} is read): it is damaged"
            )
        out[key] = info
    return out


def open_npz(name: str, what: str, fix: str) -> NpzArrays:
    """Read an ``.npz`` archive in full, each array checked before it is allocated.

    Checked first, from the zip directory: every member an ``.npy`` (stored or deflated, not
    encrypted), at most :data:`MAX_NPZ_MEMBERS` of them and :data:`MAX_NPZ_BYTES` unpacked in
    all, none over 1 MiB unpacking more than :data:`MAX_NPZ_RATIO` times; then from each
    member's ``.npy`` header (format 1.0 or 2.0): no object dtype, and shape x itemsize is what
    the directory says the member holds. Only then are the arrays read (``allow_pickle=False``);
    zipfile never inflates a member past its stated size and checks its CRC.

    Every problem (missing, unreadable, a folder, empty, a single ``.npy``, not a zip, a member
    that fails a check) raises :class:`ConfigError` naming ``what`` and the file, ending ``fix``.
    """
    shown = repr(path_text(name))

    def refuse(reason: str) -> ConfigError:
        return ConfigError(f"{what} {shown} {reason}; {fix}")

    with open_file(name, what, ConfigError, shown) as (f, size):
        head = f.read(6)
        if not head:
            raise refuse("is empty")
        if head == b"\x93NUMPY":
            raise refuse("holds a single array, not an .npz archive")
        if head[:4] not in (b"PK\x03\x04", b"PK\x05\x06"):
            raise refuse("is not a readable .npz archive (it is not a zip file)")
        if size > MAX_NPZ_BYTES + _NPZ_FILE_SLACK_BYTES:
            raise refuse(f"is {mib(size)}, more than an archive of {mib(MAX_NPZ_BYTES)} can be")
        try:
            f.seek(0)
            with zipfile.ZipFile(f) as archive:
                arrays = {}
                for key, info in _checked_members(archive, refuse).items():
                    with archive.open(info) as stream:
                        arrays[key] = np.lib.format.read_array(stream, allow_pickle=False)
        except ConfigError:
            raise
        except _NPZ_ERRORS as err:
            text = " ".join(str(err).split())[:160] or type(err).__name__
            raise refuse(f"is not a readable .npz archive ({text})") from None
    return NpzArrays(os.fsdecode(os.fspath(name)), what, arrays)
