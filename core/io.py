"""Reading and writing images, disparity maps, ground truth and masks (``.npz`` archives:
:mod:`core.npz`, on this module's bounded file reader).

Everything here works on plain numpy arrays with fixed dtypes:

- images are ``uint8``, ``(H, W)`` grey or ``(H, W, 3)`` **RGB** (OpenCV's BGR order never leaks
  out of this module);
- disparity maps and ground truth are ``float32`` ``(H, W)`` in pixels, with a non-finite value
  (``inf`` in ground truth) meaning "unknown" or "invalid";
- masks are ``uint8`` ``(H, W)`` grey levels.

Anything wrong with a file the user handed in (missing, unreadable, a folder, a path too long,
corrupt, too large, wrong bit depth or format) raises :class:`core.errors.InputError` with one line
naming the file and saying how to fix it: no ``OSError`` gets out, and what OpenCV, libpng, libjpeg
(and FFmpeg, for videos) print on stderr is caught (:func:`native_stderr_caught`). Every read is
bounded before memory is committed: an image, GT or mask holds at most ``max_pixels`` pixels
(:data:`MAX_PIXELS`), read from the PNG or JPEG header before decoding (other formats: after);
a PFM's declared size is checked the same way.

Files are written atomically (:func:`core.outputs.atomic_write_bytes`) so a reader never sees half
a file, and PNG output is byte-identical for identical input.
"""

from __future__ import annotations

import contextlib
import errno
import numbers
import os
import stat
import sys
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from stereosim.core import signals
from stereosim.core.errors import InputError
from stereosim.core.outputs import atomic_write_bytes, describe_os_error, path_text

# Integer BT.601 luma weights in 1/256: 77 + 150 + 29 == 256, so white stays 255.
_LUMA_R, _LUMA_G, _LUMA_B = 77, 150, 29

# The largest image (in pixels) `stereosim run`/`eval` and `stereosim.run` accept unless told
# otherwise (--max-pixels / max_pixels=): 4096 x 4096, about twice 4K UHD. A cycle-model frame of 4K
# UHD peaks at ~354 MiB; the cap keeps a small file that claims a huge image from taking gigabytes.
MAX_PIXELS = 1 << 24
# The cap of "no cap" (--max-pixels 0, max_pixels=None or 0): more pixels than any image has.
NO_PIXEL_CAP = 1 << 40

# Room for metadata (ICC profiles, EXIF, text chunks) in an image file beyond its pixel data.
_IMAGE_FILE_SLACK_BYTES = 16 << 20
# A PFM header is three short lines; anything longer is not a PFM.
_PFM_HEADER_BYTES = 4096
# A known ground-truth disparity is at most this many times the map's width. A pixel whose match
# lies in the other view has |d| < W; the factor leaves room for crops of a wider scene, and
# still refuses what a corrupt file or a wrong --gt-scale gives (1e30, 65535 / 1 on a 450 px map).
GT_MAX_WIDTHS = 4
# A calib.txt is a dozen short lines.
MAX_TEXT_FILE_BYTES = 1 << 20

# zlib level for PNG output; fixed so that output does not depend on OpenCV's default.
_PNG_COMPRESSION = 3

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# JPEG frame headers: SOF0..SOF15 except DHT (C4), JPG (C8) and DAC (CC).
_JPEG_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
# JPEG markers without a length field: TEM and RST0..RST7 (SOI is handled before the loop).
_JPEG_STANDALONE = frozenset([0x01, *range(0xD0, 0xD8)])

_READ_HINTS = {
    errno.EACCES: "check its permissions",
    errno.EPERM: "check its permissions",
    errno.ENAMETOOLONG: "use a shorter path",
    errno.EISDIR: "give the path of a file, not a folder",
    errno.ENOTDIR: "a part of the path is a file, not a folder",
    errno.ELOOP: "the path runs in a loop of symbolic links",
}

# What native libraries print is kept off stderr by pointing file descriptor 2 elsewhere,
# which is process wide: one image decode or video read at a time.
_STDERR_LOCK = threading.Lock()


# ---------------------------------------------------------------------------------------------
# paths and files


def mib(n_bytes: int) -> str:
    return f"{n_bytes} bytes" if n_bytes < 1 << 20 else f"{n_bytes / 2**20:.1f} MiB"


def _os_failure(noun: str, shown: str, exc: OSError) -> str:
    """``cannot read <noun> <path> (<reason>): <hint>``."""
    hint = _READ_HINTS.get(exc.errno, "check the path")
    return f"cannot read {noun} {shown} ({describe_os_error(exc)}): {hint}"


def path_kind(path: str | os.PathLike, what: str) -> str | None:
    """``"file"``, ``"folder"`` or ``"other"`` for what ``path`` is, ``None`` when nothing is
    there; any other failure of ``stat`` (permission denied, a path too long, a loop of links)
    raises InputError naming ``what`` and the path, where ``Path.is_file`` would raise OSError."""
    try:
        mode = os.stat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):
        return None
    except OSError as exc:
        raise InputError(_os_failure(what, path_text(path), exc)) from None
    except ValueError:  # an embedded NUL byte
        raise InputError(f"{what} {path_text(path)} is not a valid path: check it") from None
    if stat.S_ISDIR(mode):
        return "folder"
    return "file" if stat.S_ISREG(mode) else "other"


def is_file(path: str | os.PathLike, what: str) -> bool:
    """``Path.is_file`` that turns a failing ``stat`` into an InputError (:func:`path_kind`)."""
    return path_kind(path, what) == "file"


def is_folder(path: str | os.PathLike, what: str) -> bool:
    """``Path.is_dir`` that turns a failing ``stat`` into an InputError (:func:`path_kind`)."""
    return path_kind(path, what) == "folder"


def sub_folders(path: str | os.PathLike, what: str) -> list[Path]:
    """The sub-folders of a folder, sorted by name, hidden ones (``.name``) left out; a folder
    that cannot be listed raises InputError naming ``what`` and the path."""
    root = Path(path)
    try:
        names = sorted(entry.name for entry in os.scandir(root))
    except OSError as exc:
        raise InputError(_os_failure(what, path_text(root), exc)) from None
    return [root / n for n in names if not n.startswith(".") and is_folder(root / n, what)]


@contextlib.contextmanager
def open_file(path, noun: str, error: type = InputError, shown: str | None = None):
    """Open a regular file for reading and yield ``(file, size in bytes)``; a missing file, a
    folder, a device or pipe (opened non-blocking: a FIFO cannot hang the open) and every
    ``OSError``, here or while the caller reads, raise ``error`` with one line naming ``noun`` and
    the path (``shown``, by default :func:`path_text`)."""
    shown = path_text(path) if shown is None else shown
    # the descriptor changes hands whole: a signal waits for the end of the stretch (a SIGTERM
    # just after fdopen once closed it here and again in the file object: "Bad file
    # descriptor", exit 2, instead of the signal's line)
    with signals.held():
        try:
            fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
        except FileNotFoundError:
            raise error(f"{noun} {shown} not found: check the path") from None
        except OSError as exc:
            raise error(_os_failure(noun, shown, exc)) from None
        except ValueError:  # an embedded NUL byte
            raise error(f"{noun} path {shown} is not a valid path: check it") from None
        try:
            st = os.fstat(fd)
            if stat.S_ISDIR(st.st_mode):
                raise error(f"{noun} path {shown} is a folder: give the path of a file")
            if not stat.S_ISREG(st.st_mode):
                raise error(
                    f"{noun} path {shown} is not a regular file (a device, pipe or socket): "
                    "give the path of a file"
                )
            f = os.fdopen(fd, "rb")
        except BaseException:
            os.close(fd)
            raise
    with f:
        try:
            yield f, st.st_size
        except OSError as exc:
            raise error(_os_failure(noun, shown, exc)) from None


def _read_bytes(path: str | os.PathLike, what: str, max_bytes: int, too_big: str) -> bytes:
    """The bytes of ``path`` (at most ``max_bytes``; ``too_big`` is the fix printed beyond),
    or an InputError naming the file if it is missing, unreadable, empty or too large."""
    with open_file(path, f"{what} file") as (f, size):
        if size > max_bytes:
            raise InputError(
                f"{what} file {path_text(path)} is {mib(size)}, more than the "
                f"{mib(max_bytes)} allowed: {too_big}"
            )
        chunks, got = [], 0
        while got <= max_bytes:  # in chunks: the cap may be far above what is there
            chunk = f.read(min(1 << 20, max_bytes + 1 - got))
            if not chunk:
                break
            chunks.append(chunk)
            got += len(chunk)
        data = b"".join(chunks)
    if len(data) > max_bytes:
        raise InputError(f"{what} file {path_text(path)} grew while it was read: read it again")
    if not data:
        raise InputError(f"{what} file {path_text(path)} is empty: replace it with a valid file")
    return data


def read_text(
    path: str | os.PathLike, what: str, max_bytes: int = MAX_TEXT_FILE_BYTES, encoding="ascii"
) -> str:
    """A text file of at most ``max_bytes`` in ``encoding``; InputError naming the file otherwise
    (missing, unreadable, a folder, empty, too long, or not text in that encoding)."""
    data = _read_bytes(path, what, max_bytes, "it is not a text file of this kind")
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as exc:
        raise InputError(
            f"{what} file {path_text(path)} is not {encoding} text (byte {exc.start} is "
            f"0x{data[exc.start]:02x}): replace it"
        ) from None


# ---------------------------------------------------------------------------------------------
# image sizes from headers


def pixel_cap(max_pixels: int | None) -> int:
    """The pixel cap for a user's ``max_pixels`` (``--max-pixels``, ``max_pixels=``): 0 and
    None mean no cap (:data:`NO_PIXEL_CAP`), as on the command line; anything but a whole
    number >= 0 raises InputError."""
    if max_pixels is None or (not isinstance(max_pixels, bool) and max_pixels == 0):
        return NO_PIXEL_CAP
    if isinstance(max_pixels, bool) or not isinstance(max_pixels, numbers.Integral) \
            or max_pixels < 0:
        raise InputError(f"max_pixels must be a whole number >= 0 (0 or None: no cap); got "
                         f"{max_pixels!r}")
    return int(max_pixels)


def max_image_file_bytes(max_pixels: int) -> int:
    """The longest image file read for a pixel cap: 8 bytes a pixel (16-bit RGBA stored
    uncompressed, the largest PNG) plus 16 MiB of metadata."""
    return 8 * max_pixels + _IMAGE_FILE_SLACK_BYTES


def _png_size(data: bytes) -> tuple[int, int] | None:
    """(width, height) from a PNG's IHDR chunk, or None if ``data`` does not start like a PNG."""
    if len(data) < 24 or data[:8] != _PNG_SIGNATURE or data[12:16] != b"IHDR":
        return None
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


def _jpeg_size(data: bytes) -> tuple[int, int] | None:
    """(width, height) from a JPEG's frame header (SOFn), or None if it is not found before the
    scan data (then the decoder decides; a height of 0, defined later by a DNL marker, too)."""
    if data[:2] != b"\xff\xd8":
        return None
    pos, n = 2, len(data)
    while pos + 4 <= n:
        if data[pos] != 0xFF:
            return None
        marker = data[pos + 1]
        if marker == 0xFF:  # fill byte
            pos += 1
            continue
        if marker in _JPEG_STANDALONE:
            pos += 2
            continue
        if marker in (0xD9, 0xDA):  # end of image, start of scan: no frame header before
            return None
        length = int.from_bytes(data[pos + 2 : pos + 4], "big")
        if marker in _JPEG_SOF:
            if length < 8 or pos + 9 > n:
                return None
            height = int.from_bytes(data[pos + 5 : pos + 7], "big")
            width = int.from_bytes(data[pos + 7 : pos + 9], "big")
            return (width, height) if height else None
        if length < 2:
            return None
        pos += 2 + length
    return None


def png_size(path: str | os.PathLike, what: str = "image") -> tuple[int, int]:
    """(width, height) of a PNG from its IHDR chunk, reading 24 bytes (no decoding)."""
    with open_file(path, f"{what} file") as (f, _):
        head = f.read(24)
    size = _png_size(head)
    if size is None:
        raise InputError(f"{what} {path_text(path)} is not a valid PNG file: replace it")
    return size


def _check_pixels(width: int, height: int, max_pixels: int, what: str, path) -> None:
    if width * height > max_pixels:
        raise InputError(
            f"{what} {path_text(path)} is {width}x{height} ({width * height / 1e6:.1f} M "
            f"pixels), above the {max_pixels / 1e6:.1f} M-pixel cap: downsample it or raise "
            "the cap with --max-pixels"
        )


# ---------------------------------------------------------------------------------------------
# decoding


@contextlib.contextmanager
def native_stderr_caught() -> Iterator[list[str]]:
    """Keep what native libraries print off stderr for the duration: OpenCV's log is switched
    off and file descriptor 2, where libpng, libjpeg and FFmpeg write, points at a temporary
    file (put back in a ``finally``; without one, nothing is caught). Yields a list that holds,
    once the block is left, the last line written there (none if nothing was), made fit for a
    one-line message. Process wide, so one block at a time."""
    said: list[str] = []
    with _STDERR_LOCK:
        level = cv2.utils.logging.getLogLevel()
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
        try:
            with contextlib.ExitStack() as stack:
                sink = saved = None
                with contextlib.suppress(OSError):
                    sink = stack.enter_context(tempfile.TemporaryFile())
                    saved = os.dup(2)
                try:
                    if saved is not None:
                        with contextlib.suppress(Exception):
                            sys.stderr.flush()  # Python's buffered text goes out first
                        os.dup2(sink.fileno(), 2)
                    yield said
                finally:
                    if saved is not None:
                        os.dup2(saved, 2)
                        os.close(saved)
                    if sink is not None:  # the last 4 KiB hold the last line
                        sink.seek(max(0, sink.seek(0, os.SEEK_END) - 4096))
                        text = sink.read().decode("utf-8", "replace")
                        lines = [line.strip() for line in text.splitlines() if line.strip()]
                        said += [path_text(lines[-1])[:120]] if lines else []
        finally:
            cv2.utils.logging.setLogLevel(level)


def _imdecode_quietly(data: bytes, flags: int) -> tuple[np.ndarray | None, str]:
    """``cv2.imdecode`` returning ``(image or None, the last line printed on stderr)``
    (:func:`native_stderr_caught`)."""
    buf = np.frombuffer(data, dtype=np.uint8)
    with native_stderr_caught() as said:
        try:
            img = cv2.imdecode(buf, flags)
        except cv2.error:
            img = None
    return img, (said[-1] if said else "")


def _decode(data: bytes, flags: int, path, what: str, max_pixels: int) -> np.ndarray:
    """Decode an encoded image with OpenCV, refusing one above ``max_pixels`` -- before decoding
    when its PNG or JPEG header gives the size; InputError naming the file if it cannot be
    decoded."""
    size = _png_size(data) or _jpeg_size(data)
    if size is not None:
        _check_pixels(*size, max_pixels, what, path)
    img, said = _imdecode_quietly(data, flags)
    if img is None:
        reason = f" ({said})" if said else ""
        raise InputError(
            f"{what} file {path_text(path)} is corrupt or not an image format OpenCV can "
            f"read{reason}: replace it with a valid PNG"
        )
    _check_pixels(img.shape[1], img.shape[0], max_pixels, what, path)
    return img


def _read_encoded(path, what: str, max_pixels: int) -> bytes:
    return _read_bytes(
        path,
        what,
        max_image_file_bytes(max_pixels),
        "no image of the pixel cap is that long; downsample it or raise the cap with --max-pixels",
    )


def read_image(path: str | os.PathLike, *, max_pixels: int = MAX_PIXELS) -> np.ndarray:
    """Read an 8-bit image as ``uint8`` ``(H, W)`` grey or ``(H, W, 3)`` RGB.

    An alpha channel is dropped; palette images come out as RGB. 16-bit (or floating-point)
    images are refused because the chip's input is 8 bits per sample. An image of more than
    ``max_pixels`` pixels is refused (before decoding for PNG and JPEG).
    """
    data = _read_encoded(path, "image", max_pixels)
    img = _decode(data, cv2.IMREAD_UNCHANGED, path, "image", max_pixels)
    if img.dtype != np.uint8:
        raise InputError(
            f"image {path_text(path)} has {img.dtype} samples but 8-bit is needed: "
            "convert it to an 8-bit PNG"
        )
    if img.ndim == 2:
        return img
    channels = img.shape[2]
    if channels in (1, 2):  # grey (+ alpha)
        return np.ascontiguousarray(img[:, :, 0])
    if channels == 3:
        return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    if channels == 4:
        return cv2.cvtColor(img, cv2.COLOR_BGRA2RGB)
    raise InputError(f"image {path_text(path)} has {channels} channels: use a grey or RGB image")


def to_grey(img: np.ndarray) -> np.ndarray:
    """Convert an image to ``uint8`` ``(H, W)`` grey, exactly and identically on every machine.

    Accepts ``uint8`` ``(H, W)``, ``(H, W, 1)`` or ``(H, W, 3)`` RGB. RGB uses the integer BT.601
    luma formula::

        Y = (77*R + 150*G + 29*B + 128) >> 8

    (weights in 1/256 that sum to 256, rounded to nearest). Grey input is returned unchanged
    (as a contiguous array).
    """
    img = np.asarray(img)
    if img.dtype != np.uint8:
        raise InputError(
            f"image has dtype {img.dtype} but uint8 is needed: convert it to uint8 (0..255) first"
        )
    if img.ndim == 2:
        return np.ascontiguousarray(img)
    if img.ndim == 3 and img.shape[2] == 1:
        return np.ascontiguousarray(img[:, :, 0])
    if img.ndim == 3 and img.shape[2] == 3:
        # in uint16, in place: the sum is at most 256 * 255 + 128 < 2^16 (3.4x faster than in
        # uint32 at 720p)
        y = img[:, :, 0].astype(np.uint16)
        y *= _LUMA_R
        for channel, weight in ((1, _LUMA_G), (2, _LUMA_B)):
            term = img[:, :, channel].astype(np.uint16)
            term *= weight
            y += term
        y += 128
        y >>= 8
        return y.astype(np.uint8)
    if img.ndim == 3:
        raise InputError(
            f"image has {img.shape[2]} channels: give a grey (H, W) or RGB (H, W, 3) image"
        )
    raise InputError(f"image has shape {img.shape}: give a grey (H, W) or RGB (H, W, 3) image")


def _pfm_token(data: bytes, pos: int, path) -> tuple[bytes, int]:
    """Skip whitespace from ``pos`` and return the next header token and the position after it."""
    n = len(data)
    while pos < n and data[pos : pos + 1].isspace():
        pos += 1
    start = pos
    while pos < n and not data[pos : pos + 1].isspace():
        pos += 1
    if start == pos or pos - start > 64:
        raise InputError(
            f"PFM file {path_text(path)} has a truncated or corrupt header: replace the file"
        )
    return data[start:pos], pos


def read_pfm(path: str | os.PathLike, *, max_pixels: int = MAX_PIXELS) -> np.ndarray:
    """Read a grey PFM (``Pf``) as ``float32`` ``(H, W)`` with row 0 at the top.

    Follows the Middlebury / netpbm convention: header ``Pf``, ``W H``, then a scale whose sign
    gives the byte order (negative = little-endian, positive = big-endian) and whose magnitude is
    **ignored** (OpenCV divides the data by it; Middlebury's files say -0.003922, which would make
    every disparity 255x too large). Rows are stored bottom-to-top. ``inf`` and ``nan`` are kept.
    A map of more than ``max_pixels`` pixels is refused (the file is at most 4 bytes a pixel and
    a short header long, so nothing larger is read).
    """
    p = Path(path)
    shown = path_text(p)
    data = _read_bytes(
        p,
        "PFM",
        4 * max_pixels + _PFM_HEADER_BYTES,
        "no float32 map of the pixel cap is that long; downsample it or raise the cap with "
        "--max-pixels",
    )
    if data[:2] == b"PF":
        raise InputError(
            f"PFM file {shown} is a colour (PF) image: a grey (Pf) disparity map is needed"
        )
    if data[:2] != b"Pf" or len(data) < 3 or not data[2:3].isspace():
        raise InputError(
            f"file {shown} is not a grey PFM (it does not start with 'Pf'): check the path"
        )
    pos = 2
    try:
        width_tok, pos = _pfm_token(data, pos, p)
        height_tok, pos = _pfm_token(data, pos, p)
        scale_tok, pos = _pfm_token(data, pos, p)
        width, height, scale = int(width_tok), int(height_tok), float(scale_tok)
    except ValueError:
        raise InputError(
            f"PFM file {shown} has a corrupt header (size or scale): replace the file"
        ) from None
    if width <= 0 or height <= 0:
        raise InputError(f"PFM file {shown} declares a size of {width}x{height}: replace the file")
    _check_pixels(width, height, max_pixels, "PFM file", p)
    if scale == 0 or not np.isfinite(scale):
        raise InputError(
            f"PFM file {shown} has scale {scale_tok.decode(errors='replace')}, which gives no "
            "byte order (negative = little-endian, positive = big-endian): fix its header"
        )
    # Exactly one whitespace byte ends the header; accept a CRLF pair written on Windows.
    if data[pos : pos + 2] == b"\r\n":
        pos += 2
    else:
        pos += 1
    expected = width * height * 4
    got = len(data) - pos
    if got != expected:
        raise InputError(
            f"PFM file {shown} holds {max(got, 0)} data bytes but {width}x{height} float32 "
            f"needs {expected}: the file is truncated or corrupt, replace it"
        )
    dtype = "<f4" if scale < 0 else ">f4"
    rows_bottom_up = np.frombuffer(data, dtype=dtype, count=width * height, offset=pos)
    # Always a fresh, writable, native-endian array (frombuffer's view is read-only).
    return np.array(rows_bottom_up.reshape(height, width)[::-1], dtype=np.float32, order="C")


def pfm_bytes(arr: np.ndarray) -> bytes:
    """Encode a 2-D array as a little-endian grey PFM (scale -1.0, rows bottom-to-top)."""
    a = np.asarray(arr)
    if a.ndim != 2 or a.size == 0:
        raise InputError(f"a PFM holds a non-empty 2-D array but got shape {a.shape}")
    if not (np.issubdtype(a.dtype, np.floating) or np.issubdtype(a.dtype, np.integer)):
        raise InputError(f"cannot write dtype {a.dtype} to a PFM: give a float32 array")
    height, width = a.shape
    header = f"Pf\n{width} {height}\n-1.0\n".encode("ascii")
    return header + np.ascontiguousarray(a[::-1], dtype="<f4").tobytes()


def write_pfm(path: str | os.PathLike, arr: np.ndarray) -> None:
    """Write a 2-D array atomically as a float32 grey PFM (little-endian, scale -1.0)."""
    atomic_write_bytes(path, pfm_bytes(arr))


def encode_png(img: np.ndarray) -> bytes:
    """Encode ``uint8``/``uint16`` ``(H, W)`` grey or ``(H, W, 3)`` RGB as PNG bytes.

    The output is deterministic: the same array gives the same bytes (fixed compression level,
    no timestamps or other metadata).
    """
    a = np.asarray(img)
    if a.dtype not in (np.uint8, np.uint16):
        raise InputError(f"cannot write dtype {a.dtype} to a PNG: convert it to uint8 or uint16")
    if a.ndim == 3 and a.shape[2] == 3:
        a = cv2.cvtColor(np.ascontiguousarray(a), cv2.COLOR_RGB2BGR)
    elif a.ndim == 3 and a.shape[2] == 1:
        a = a[:, :, 0]
    elif a.ndim != 2:
        raise InputError(f"cannot write shape {a.shape} to a PNG: give (H, W) or (H, W, 3) RGB")
    if a.size == 0:
        raise InputError("cannot write an empty image to a PNG")
    ok, buf = cv2.imencode(
        ".png", np.ascontiguousarray(a), [cv2.IMWRITE_PNG_COMPRESSION, _PNG_COMPRESSION]
    )
    if not ok:
        raise InputError(f"OpenCV could not encode a {a.shape} {a.dtype} image as PNG")
    return buf.tobytes()


def disparity_to_colour(disp: np.ndarray, dmax: float) -> np.ndarray:
    """Colour a disparity map: ``uint8`` ``(H, W, 3)`` RGB with OpenCV's TURBO colour map.

    Disparity 0 (and below) is the dark blue end, ``dmax`` (and above) the dark red end; the level
    is ``floor(255 * clip(d / dmax, 0, 1) + 0.5)``. Invalid (non-finite) pixels are black.
    """
    d = np.asarray(disp, dtype=np.float64)
    if d.ndim != 2:
        raise InputError(f"a disparity map is 2-D but got shape {d.shape}")
    if not (np.isfinite(dmax) and dmax > 0):
        raise InputError(f"dmax for the disparity colour map is {dmax}: give a positive number")
    finite = np.isfinite(d)
    level = np.floor(255.0 * np.clip(np.where(finite, d, 0.0) / dmax, 0.0, 1.0) + 0.5)
    bgr = cv2.applyColorMap(level.astype(np.uint8), cv2.COLORMAP_TURBO)
    rgb = np.ascontiguousarray(bgr[:, :, ::-1])
    rgb[~finite] = 0
    return rgb


def write_disparity_png(path: str | os.PathLike, disp: np.ndarray, dmax: float) -> None:
    """Write a colour-mapped disparity map (:func:`disparity_to_colour`) as a PNG, atomically."""
    atomic_write_bytes(path, encode_png(disparity_to_colour(disp, dmax)))


def check_gt_values(gt: np.ndarray, source: str) -> None:
    """Refuse disparities no scene can have (:data:`GT_MAX_WIDTHS`); non-finite ones are
    unknown and pass. ``source`` names the GT in the message (``"GT file x.pfm"``)."""
    limit = GT_MAX_WIDTHS * gt.shape[1]
    finite = np.isfinite(gt)
    bad = finite & ((gt < 0) | (gt > limit))
    if not bad.any():
        return
    y, x = divmod(int(np.argmax(bad.ravel())), gt.shape[1])
    value = float(gt[y, x])
    where = f"at row {y}, column {x}"
    if value < 0:
        raise InputError(
            f"{source} holds the negative disparity {value:g} {where}: "
            "disparities are >= 0 (unknown is inf in a PFM, 0 in a PNG); fix the file"
        )
    raise InputError(
        f"{source} holds the disparity {value:g} {where}, more than {GT_MAX_WIDTHS} "
        f"x its width {gt.shape[1]} = {limit} px, which no scene can have: the file is corrupt "
        "or its scale is wrong (--gt-scale)"
    )


def read_gt(
    path: str | os.PathLike, scale: float | None = None, *, max_pixels: int = MAX_PIXELS
) -> np.ndarray:
    """Read ground-truth disparity as ``float32`` ``(H, W)`` in pixels, ``inf`` where unknown.

    - ``.pfm``: :func:`read_pfm`, divided by ``scale`` if given (Middlebury 2014 PFMs are in
      pixels already, scale 1); non-finite values stay unknown.
    - ``.png``: 8- or 16-bit grey; 0 means unknown (becomes ``inf``), any other value ``v``
      becomes ``v / scale``. The scale depends on the dataset (Middlebury 2005/2006 ThirdSize 3,
      2003 quarter size 4, KITTI 256), so it must be given.

    A known disparity must be in ``0 .. GT_MAX_WIDTHS * W`` (:data:`GT_MAX_WIDTHS`); a map of
    more than ``max_pixels`` pixels is refused before it is decoded.
    """
    p = Path(path)
    if scale is not None and not (np.isfinite(scale) and scale > 0):
        raise InputError(
            f"GT scale for {path_text(p)} is {scale}: give a positive number (--gt-scale)"
        )
    ext = p.suffix.lower()
    if ext == ".pfm":
        gt = read_pfm(p, max_pixels=max_pixels)
        if scale is not None and scale != 1:
            gt = (gt / np.float32(scale)).astype(np.float32)
        gt[~np.isfinite(gt)] = np.inf
        check_gt_values(gt, f"GT {path_text(p)}")
        return gt
    if ext == ".png":
        if scale is None:
            raise InputError(
                f"GT {path_text(p)} is a PNG whose disparity scale is unknown: pass --gt-scale "
                "(Middlebury 2005/2006 ThirdSize 3, 2003 quarter 4, KITTI 256)"
            )
        data = _read_encoded(p, "GT", max_pixels)
        raw = _decode(data, cv2.IMREAD_UNCHANGED, p, "GT", max_pixels)
        if raw.ndim == 3:
            if not all(np.array_equal(raw[:, :, 0], raw[:, :, c]) for c in range(raw.shape[2])):
                raise InputError(
                    f"GT {path_text(p)} is a colour PNG: a grey 8- or 16-bit PNG is needed"
                )
            raw = raw[:, :, 0]
        if raw.dtype not in (np.uint8, np.uint16):
            raise InputError(
                f"GT {path_text(p)} has {raw.dtype} samples: an 8- or 16-bit PNG is needed"
            )
        gt = raw.astype(np.float32) / np.float32(scale)
        gt[raw == 0] = np.inf
        check_gt_values(gt, f"GT {path_text(p)}")
        return gt
    raise InputError(
        f"GT {path_text(p)} has extension '{p.suffix}': give a .pfm or .png ground-truth file"
    )


def read_mask(path: str | os.PathLike, *, max_pixels: int = MAX_PIXELS) -> np.ndarray:
    """Read a mask as ``uint8`` ``(H, W)`` grey levels (palette PNGs are expanded to grey); a
    mask of more than ``max_pixels`` pixels is refused before it is decoded."""
    data = _read_encoded(path, "mask", max_pixels)
    return _decode(data, cv2.IMREAD_GRAYSCALE, path, "mask", max_pixels)
