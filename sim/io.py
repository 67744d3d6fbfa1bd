"""Reading and writing images, disparity maps, ground truth and masks.

Everything here works on plain numpy arrays with fixed dtypes:

- images are ``uint8``, ``(H, W)`` grey or ``(H, W, 3)`` **RGB** (OpenCV's BGR order never leaks
  out of this module);
- disparity maps and ground truth are ``float32`` ``(H, W)`` in pixels, with a non-finite value
  (``inf`` in ground truth) meaning "unknown" or "invalid";
- masks are ``uint8`` ``(H, W)`` grey levels.

Anything wrong with a file the user handed in (missing, corrupt, wrong bit depth or format) raises
:class:`sim.errors.InputError` with one line naming the file and saying how to fix it. Files are
written atomically (:func:`sim.outputs.atomic_write_bytes`) so a reader never sees half a file,
and PNG output is byte-identical for identical input.
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import cv2
import numpy as np

from sim.errors import ConfigError, InputError
from sim.outputs import atomic_write_bytes

# Integer BT.601 luma weights in 1/256: 77 + 150 + 29 == 256, so white stays 255.
_LUMA_R, _LUMA_G, _LUMA_B = 77, 150, 29

# The largest image (in pixels) `stereosim run`/`eval` and `sim.run` accept unless told otherwise
# (--max-pixels / max_pixels=): 4096 x 4096, about twice 4K UHD. A cycle-model frame of 4K UHD
# peaks at ~354 MiB; the cap keeps a small file that claims a huge image from taking gigabytes.
MAX_PIXELS = 1 << 24

# zlib level for PNG output; fixed so that output does not depend on OpenCV's default.
_PNG_COMPRESSION = 3


def _read_bytes(path: str | os.PathLike, what: str) -> bytes:
    """The bytes of ``path``, or an InputError naming the file if it is missing or unreadable."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"{what} file {p} not found: check the path (and the scene folder)")
    if not p.is_file():
        raise InputError(f"{what} path {p} is not a file: give the path of a file")
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise InputError(
            f"cannot read {what} file {p} ({exc.strerror}): check its permissions"
        ) from exc
    if not data:
        raise InputError(f"{what} file {p} is empty: replace it with a valid file")
    return data


def _decode(data: bytes, flags: int, path: str | os.PathLike, what: str) -> np.ndarray:
    """Decode an encoded image with OpenCV; InputError naming the file if it cannot be decoded."""
    try:
        img = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), flags)
    except cv2.error:
        img = None
    if img is None:
        raise InputError(
            f"{what} file {Path(path)} is corrupt or not an image format OpenCV can read: "
            "replace it with a valid PNG"
        )
    return img


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read an 8-bit image as ``uint8`` ``(H, W)`` grey or ``(H, W, 3)`` RGB.

    An alpha channel is dropped; palette images come out as RGB. 16-bit (or floating-point)
    images are refused because the chip's input is 8 bits per sample.
    """
    img = _decode(_read_bytes(path, "image"), cv2.IMREAD_UNCHANGED, path, "image")
    if img.dtype != np.uint8:
        raise InputError(
            f"image {Path(path)} has {img.dtype} samples but 8-bit is needed: "
            "convert it to an 8-bit PNG"
        )
    if img.ndim == 2:
        return img
    channels = img.shape[2]
    if channels == 1:
        return np.ascontiguousarray(img[:, :, 0])
    if channels == 2:  # grey + alpha
        return np.ascontiguousarray(img[:, :, 0])
    if channels == 3:
        return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    if channels == 4:
        return cv2.cvtColor(img, cv2.COLOR_BGRA2RGB)
    raise InputError(f"image {Path(path)} has {channels} channels: use a grey or RGB image")


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
        rgb = img.astype(np.uint32)
        y = (_LUMA_R * rgb[:, :, 0] + _LUMA_G * rgb[:, :, 1] + _LUMA_B * rgb[:, :, 2] + 128) >> 8
        return y.astype(np.uint8)
    if img.ndim == 3:
        raise InputError(
            f"image has {img.shape[2]} channels: give a grey (H, W) or RGB (H, W, 3) image"
        )
    raise InputError(f"image has shape {img.shape}: give a grey (H, W) or RGB (H, W, 3) image")


def _pfm_token(data: bytes, pos: int, path: Path) -> tuple[bytes, int]:
    """Skip whitespace from ``pos`` and return the next header token and the position after it."""
    n = len(data)
    while pos < n and data[pos : pos + 1].isspace():
        pos += 1
    start = pos
    while pos < n and not data[pos : pos + 1].isspace():
        pos += 1
    if start == pos or pos - start > 64:
        raise InputError(f"PFM file {path} has a truncated or corrupt header: replace the file")
    return data[start:pos], pos


def read_pfm(path: str | os.PathLike) -> np.ndarray:
    """Read a grey PFM (``Pf``) as ``float32`` ``(H, W)`` with row 0 at the top.

    Follows the Middlebury / netpbm convention: header ``Pf``, ``W H``, then a scale whose sign
    gives the byte order (negative = little-endian, positive = big-endian) and whose magnitude is
    **ignored** (OpenCV divides the data by it; Middlebury's files say -0.003922, which would make
    every disparity 255x too large). Rows are stored bottom-to-top. ``inf`` and ``nan`` are kept.
    """
    p = Path(path)
    data = _read_bytes(p, "PFM")
    if data[:2] == b"PF":
        raise InputError(
            f"PFM file {p} is a colour (PF) image: a grey (Pf) disparity map is needed"
        )
    if data[:2] != b"Pf" or len(data) < 3 or not data[2:3].isspace():
        raise InputError(
            f"file {p} is not a grey PFM (it does not start with 'Pf'): check the path"
        )
    pos = 2
    try:
        width_tok, pos = _pfm_token(data, pos, p)
        height_tok, pos = _pfm_token(data, pos, p)
        scale_tok, pos = _pfm_token(data, pos, p)
        width, height, scale = int(width_tok), int(height_tok), float(scale_tok)
    except ValueError:
        raise InputError(
            f"PFM file {p} has a corrupt header (size or scale): replace the file"
        ) from None
    if width <= 0 or height <= 0:
        raise InputError(f"PFM file {p} declares a size of {width}x{height}: replace the file")
    if scale == 0 or not np.isfinite(scale):
        raise InputError(
            f"PFM file {p} has scale {scale_tok.decode(errors='replace')}, which gives no byte "
            "order (negative = little-endian, positive = big-endian): fix its header"
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
            f"PFM file {p} holds {max(got, 0)} data bytes but {width}x{height} float32 needs "
            f"{expected}: the file is truncated or corrupt, replace it"
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


def read_gt(path: str | os.PathLike, scale: float | None = None) -> np.ndarray:
    """Read ground-truth disparity as ``float32`` ``(H, W)`` in pixels, ``inf`` where unknown.

    - ``.pfm``: :func:`read_pfm`, divided by ``scale`` if given (Middlebury 2014 PFMs are in
      pixels already, scale 1); non-finite values stay unknown.
    - ``.png``: 8- or 16-bit grey; 0 means unknown (becomes ``inf``), any other value ``v``
      becomes ``v / scale``. The scale depends on the dataset (Middlebury 2005/2006 ThirdSize 3,
      2003 quarter size 4, KITTI 256), so it must be given.
    """
    p = Path(path)
    if scale is not None and not (np.isfinite(scale) and scale > 0):
        raise InputError(f"GT scale for {p} is {scale}: give a positive number (--gt-scale)")
    ext = p.suffix.lower()
    if ext == ".pfm":
        gt = read_pfm(p)
        if scale is not None and scale != 1:
            gt = (gt / np.float32(scale)).astype(np.float32)
        gt[~np.isfinite(gt)] = np.inf
        return gt
    if ext == ".png":
        if scale is None:
            raise InputError(
                f"GT {p} is a PNG whose disparity scale is unknown: pass --gt-scale "
                "(Middlebury 2005/2006 ThirdSize 3, 2003 quarter 4, KITTI 256)"
            )
        raw = _decode(_read_bytes(p, "GT"), cv2.IMREAD_UNCHANGED, p, "GT")
        if raw.ndim == 3:
            if not all(np.array_equal(raw[:, :, 0], raw[:, :, c]) for c in range(raw.shape[2])):
                raise InputError(f"GT {p} is a colour PNG: a grey 8- or 16-bit PNG is needed")
            raw = raw[:, :, 0]
        if raw.dtype not in (np.uint8, np.uint16):
            raise InputError(f"GT {p} has {raw.dtype} samples: an 8- or 16-bit PNG is needed")
        gt = raw.astype(np.float32) / np.float32(scale)
        gt[raw == 0] = np.inf
        return gt
    raise InputError(f"GT {p} has extension '{p.suffix}': give a .pfm or .png ground-truth file")


def read_mask(path: str | os.PathLike) -> np.ndarray:
    """Read a mask as ``uint8`` ``(H, W)`` grey levels (palette PNGs are expanded to grey)."""
    return _decode(_read_bytes(path, "mask"), cv2.IMREAD_GRAYSCALE, path, "mask")


def open_npz(name: str, what: str, fix: str):
    """Open an .npz archive for reading; a missing, unreadable or single-array file raises
    :class:`ConfigError` naming ``what`` and the file, ending with ``fix``."""
    if not os.path.isfile(name):
        raise ConfigError(f"{what} {name!r} not found; give the path of an .npz file")
    try:
        archive = np.load(name, allow_pickle=False)
    except (OSError, ValueError, zipfile.BadZipFile) as err:
        raise ConfigError(f"{what} {name!r} is not a readable .npz archive ({err}); {fix}") from None
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise ConfigError(f"{what} {name!r} holds a single array, not an .npz archive; {fix}")
    return archive
