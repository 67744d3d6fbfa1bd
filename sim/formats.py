"""Disparity in the formats other tools already read: KITTI PNG, OpenCV fixed point, depth in
millimetres, PLY point clouds, and the MiddEval3 results layout.

Every converter is a pure function of a ``float32`` disparity map (pixels, non-finite = invalid,
as :func:`sim.api.run` returns it) and gives an array or the bytes of a file; nothing here writes
to disk. The CLI adds the bytes to a run's published set (:func:`core.outputs.publish`), so they
are written atomically with the rest and listed in ``report.json``'s ``files``. Every output is
deterministic: the same map gives the same bytes. ``docs/outputs.md`` describes each file and
how to load it.

Rounding is half up (``floor(v + 0.5)``) everywhere, so a value exactly between two codes goes
to the larger one whatever its parity.
"""

from __future__ import annotations

import io
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from plyfile import PlyData, PlyElement

from stereosim.core.datasets import parse_calib
from stereosim.core.errors import ConfigError, InputError
from stereosim.core.io import encode_png, pfm_bytes
from stereosim.core.outputs import path_text

# --save-as name -> the file it writes in the output folder (in this order).
SAVE_FORMATS = {
    "kitti": "disparity_kitti.png",
    "opencv16": "disparity_opencv16.npy",
    "depth": "depth_mm.png",
    "ply": "points.ply",
}
# The formats that turn disparity into distance and so need the camera calibration.
NEEDS_CALIBRATION = ("depth", "ply")

KITTI_SCALE = 256  # KITTI 2012/2015 disparity PNG: uint16 = d * 256
OPENCV_SCALE = 16  # cv2.StereoSGBM / StereoBM: int16 = d * 16 (4 fractional bits)
UINT16_MAX = 65535
PLY_COMMENT = (
    "stereosim point cloud: x y z in mm, left camera frame (x right, y down, "
    "z forward); colour of the left image"
)

# MiddEval3 algorithm names become part of file names (disp0<NAME>.pfm).
_ALGO_NAME = re.compile(r"[A-Za-z0-9_-]{1,40}")
DEFAULT_ALGO_NAME = "stereosim"


def _round_half_up(values: np.ndarray) -> np.ndarray:
    return np.floor(values + 0.5)


def _disparity(disp) -> np.ndarray:
    d = np.asarray(disp)
    if d.ndim != 2 or d.size == 0 or not np.issubdtype(d.dtype, np.floating):
        raise InputError(
            f"a disparity map is a non-empty 2-D float array, got {d.dtype} of shape {d.shape}"
        )
    return d.astype(np.float64)


# ----------------------------------------------------------------------------------------------
# disparity encodings


def kitti_u16(disp) -> np.ndarray:
    """KITTI's disparity encoding: ``uint16 = round(d * 256)``, clipped to 65535.

    Invalid pixels (NaN, infinite or negative disparity) are 0, which KITTI reads as "no
    disparity". A valid disparity below 1/512 px also rounds to 0 and so reads as invalid: the
    format cannot hold it. Decode with ``d = u16 / 256`` where ``u16 > 0``.
    """
    d = _disparity(disp)
    valid = np.isfinite(d) & (d >= 0)
    codes = _round_half_up(np.where(valid, d, 0.0) * KITTI_SCALE)
    return np.clip(codes, 0, UINT16_MAX).astype(np.uint16)


def kitti_png_bytes(disp) -> bytes:
    """:func:`kitti_u16` as a 16-bit grey PNG (OpenCV's encoder, fixed compression level)."""
    return encode_png(kitti_u16(disp))


def opencv16_i16(disp, min_disparity: int = 0) -> np.ndarray:
    """OpenCV's fixed-point disparity (what ``cv2.StereoSGBM.compute`` returns):
    ``int16 = round(d * 16)``, clipped to the int16 range.

    Invalid pixels (non-finite, or below ``min_disparity``) get OpenCV's own marker
    ``(min_disparity - 1) * 16``: -16 for the usual ``min_disparity`` 0. Decode with
    ``d = i16 / 16`` where ``i16 >= min_disparity * 16``.
    """
    d = _disparity(disp)
    valid = np.isfinite(d) & (d >= min_disparity)
    codes = _round_half_up(np.where(valid, d, 0.0) * OPENCV_SCALE)
    codes = np.where(valid, codes, (min_disparity - 1) * OPENCV_SCALE)
    return np.clip(codes, -32768, 32767).astype(np.int16)


def npy_bytes(arr: np.ndarray) -> bytes:
    """``arr`` as a ``.npy`` file (numpy's own format, loaded with ``np.load``)."""
    buf = io.BytesIO()
    np.save(buf, np.ascontiguousarray(arr), allow_pickle=False)
    return buf.getvalue()


# ----------------------------------------------------------------------------------------------
# calibration


@dataclass(frozen=True, slots=True)
class Calibration:
    """What depth needs from a Middlebury ``calib.txt``.

    ``fx_px``/``fy_px``: focal lengths of the left camera (``cam0[0,0]``, ``cam0[1,1]``, pixels);
    ``cx_px``/``cy_px``: its principal point (``cam0[0,2]``, ``cam0[1,2]``); ``doffs_px``: the
    right camera's principal point minus the left's along x (``doffs``); ``baseline_mm``: the
    distance between the camera centres. ``width``/``height``: the image size the numbers are
    for, when the file says.
    """

    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    doffs_px: float
    baseline_mm: float
    width: int | None = None
    height: int | None = None


def _matrix(text, key: str, source: str) -> np.ndarray:
    """A ``[a b c; d e f; g h i]`` matrix of a calib.txt as a 3x3 float array."""
    rows = str(text).strip().removeprefix("[").removesuffix("]").split(";")
    try:
        m = np.array([[float(v) for v in row.split()] for row in rows], dtype=np.float64)
    except ValueError:
        m = np.empty(0)
    if m.shape != (3, 3) or not np.isfinite(m).all():
        raise InputError(
            f"{source}: {key} is not a 3x3 matrix like [f 0 cx; 0 f cy; 0 0 1]: fix the file"
        )
    return m


def _positive(calib: dict, key: str, source: str) -> float:
    value = calib[key]
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise InputError(f"{source}: {key}={value} must be a positive number: fix the file")
    return float(value)


def read_calibration(path: str | os.PathLike) -> Calibration:
    """Read a Middlebury ``calib.txt`` (``cam0=[f 0 cx; 0 f cy; 0 0 1]``, ``doffs=``,
    ``baseline=`` in mm, optional ``cam1=``, ``width=``, ``height=`` and others, ignored).

    ``doffs`` may be left out when ``cam1`` is given: it is then ``cam1[0,2] - cam0[0,2]``. A
    missing, unreadable or malformed file, or a missing key, raises a one-line InputError.
    """
    source = path_text(path)
    calib = parse_calib(path)
    missing = [k for k in ("cam0", "baseline") if k not in calib]
    if "doffs" not in calib and "cam1" not in calib:
        missing.append("doffs")
    if missing:
        raise InputError(
            f"{source} has no {', '.join(missing)}: give a Middlebury calib.txt with cam0, "
            "doffs and baseline"
        )
    cam0 = _matrix(calib["cam0"], "cam0", source)
    if "doffs" in calib:
        doffs = calib["doffs"]
        if not (isinstance(doffs, (int, float)) and math.isfinite(doffs)):
            raise InputError(f"{source}: doffs={doffs} must be a number: fix the file")
    else:
        doffs = _matrix(calib["cam1"], "cam1", source)[0, 2] - cam0[0, 2]
    if not (cam0[0, 0] > 0 and cam0[1, 1] > 0):
        raise InputError(f"{source}: cam0's focal lengths must be positive: fix the file")
    size = {}
    for key in ("width", "height"):
        if key in calib:
            value = calib[key]
            if isinstance(value, float) and value.is_integer():
                value = int(value)
            if not isinstance(value, int) or value < 1:
                raise InputError(f"{source}: {key}={value} must be a whole number >= 1")
            size[key] = value
    return Calibration(
        fx_px=float(cam0[0, 0]),
        fy_px=float(cam0[1, 1]),
        cx_px=float(cam0[0, 2]),
        cy_px=float(cam0[1, 2]),
        doffs_px=float(doffs),
        baseline_mm=_positive(calib, "baseline", source),
        **size,
    )


# ----------------------------------------------------------------------------------------------
# depth and points


def depth_mm(disp, calib: Calibration) -> np.ndarray:
    """Depth along the optical axis in millimetres: ``Z = baseline * fx / (d + doffs)``
    (``float64``; NaN where ``d`` is not finite or ``d + doffs <= 0``, the point at or beyond
    infinity)."""
    d = _disparity(disp)
    denom = d + calib.doffs_px
    valid = np.isfinite(d) & (denom > 0)
    return np.where(valid, calib.baseline_mm * calib.fx_px / np.where(valid, denom, 1.0), np.nan)


def depth_png_u16(disp, calib: Calibration) -> np.ndarray:
    """:func:`depth_mm` rounded to whole millimetres as ``uint16``; 0 = invalid.

    A depth that does not fit (65535.5 mm or more, i.e. beyond about 65 m) is written as 0 rather
    than clipped, so every non-zero value is a true depth.
    """
    z = _round_half_up(depth_mm(disp, calib))
    fits = np.isfinite(z) & (z <= UINT16_MAX)
    return np.where(fits, z, 0).astype(np.uint16)


def point_cloud(disp, calib: Calibration, left) -> np.ndarray:
    """The valid pixels as 3-D points in the left camera's frame (x right, y down, z forward),
    millimetres, in row-major pixel order, as a record array with fields ``x y z`` (float32) and
    ``red green blue`` (uint8, the left image's colour; a grey image gives r = g = b).

    For pixel ``(x, y)`` with depth ``Z`` (:func:`depth_mm`): ``X = (x - cx) * Z / fx``,
    ``Y = (y - cy) * Z / fy``. Pixels without a finite depth are left out.
    """
    z = depth_mm(disp, calib)
    img = np.asarray(left)
    if img.shape[:2] != z.shape or img.dtype != np.uint8 or img.ndim not in (2, 3):
        raise InputError(
            f"the left image ({img.dtype}, {img.shape}) must be uint8 grey or RGB of the "
            f"disparity map's size {z.shape}"
        )
    rgb = np.repeat(img[:, :, None], 3, axis=2) if img.ndim == 2 else img[:, :, :3]
    ys, xs = np.nonzero(np.isfinite(z))
    zv = z[ys, xs]
    points = np.empty(
        len(zv),
        dtype=[
            ("x", "<f4"),
            ("y", "<f4"),
            ("z", "<f4"),
            ("red", "u1"),
            ("green", "u1"),
            ("blue", "u1"),
        ],
    )
    points["x"] = (xs - calib.cx_px) * zv / calib.fx_px
    points["y"] = (ys - calib.cy_px) * zv / calib.fy_px
    points["z"] = zv
    for k, name in enumerate(("red", "green", "blue")):
        points[name] = rgb[ys, xs, k]
    return points


def ply_bytes(points: np.ndarray) -> bytes:
    """:func:`point_cloud`'s points as a binary little-endian PLY (written by ``plyfile``), one
    ``vertex`` element, no faces; the header names the units and axes in a comment."""
    data = PlyData(
        [PlyElement.describe(points, "vertex")],
        text=False,
        byte_order="<",
        comments=[PLY_COMMENT],
    )
    buf = io.BytesIO()
    data.write(buf)
    return buf.getvalue()


# ----------------------------------------------------------------------------------------------
# stereosim run --save-as


@dataclass(frozen=True, slots=True)
class SaveRequest:
    """What ``stereosim run --save-as`` writes: the formats (in :data:`SAVE_FORMATS` order) and
    the calibration that depth and points need (None when no format needs it)."""

    formats: tuple[str, ...] = ()
    calibration: Calibration | None = None
    calib_source: str | None = None

    def planned(self, out_dir: Path) -> list[tuple[Path, str]]:
        """The files to check before the run, as ``(path, label)``."""
        return [(out_dir / SAVE_FORMATS[f], f"--save-as {f}") for f in self.formats]

    def check_size(self, shape: tuple[int, ...]) -> None:
        """Refuse (before the run) a calib.txt made for another image size."""
        c = self.calibration
        if c is None:
            return
        h, w = shape[:2]
        if (c.width is not None and c.width != w) or (c.height is not None and c.height != h):
            raise InputError(
                f"{self.calib_source} is for {c.width or '?'}x{c.height or '?'} images but the "
                f"pair is {w}x{h}: give the calib.txt of this image size (--calib)"
            )

    def files(self, out_dir: Path, disp, left) -> dict[Path, bytes]:
        """Every requested file by path."""
        make = {
            "kitti": lambda: kitti_png_bytes(disp),
            "opencv16": lambda: npy_bytes(opencv16_i16(disp)),
            "depth": lambda: encode_png(depth_png_u16(disp, self.calibration)),
            "ply": lambda: ply_bytes(point_cloud(disp, self.calibration, left)),
        }
        return {out_dir / SAVE_FORMATS[f]: make[f]() for f in self.formats}


def save_request(save_as: str | None, calib: str | None, scene: str | None) -> SaveRequest:
    """Parse ``--save-as`` (a comma list of :data:`SAVE_FORMATS` names) and read the calibration
    that depth and points need: ``--calib FILE``, else the scene folder's ``calib.txt``."""
    valid = ", ".join(SAVE_FORMATS)
    if save_as is None:
        if calib is not None:
            raise ConfigError("--calib is used by --save-as depth or ply: add one of them")
        return SaveRequest()
    names = [n.strip() for n in save_as.split(",") if n.strip()]
    if not names:
        raise ConfigError(f"--save-as is empty: give a comma list of {valid}")
    unknown = [n for n in names if n not in SAVE_FORMATS]
    if unknown:
        raise ConfigError(f"unknown --save-as format {unknown[0]!r}: choose from {valid}")
    formats = tuple(f for f in SAVE_FORMATS if f in names)
    needs = [f for f in formats if f in NEEDS_CALIBRATION]
    if not needs:
        if calib is not None:
            raise ConfigError("--calib is used by --save-as depth or ply: add one of them")
        return SaveRequest(formats)
    path = Path(calib) if calib is not None else None
    if path is None and scene is not None and (Path(scene) / "calib.txt").is_file():
        path = Path(scene) / "calib.txt"
    if path is None:
        raise ConfigError(
            f"--save-as {'/'.join(needs)} needs the focal length, baseline and doffs: give "
            "--calib FILE (a Middlebury calib.txt)"
        )
    return SaveRequest(formats, read_calibration(path), path_text(path))


# ----------------------------------------------------------------------------------------------
# stereosim eval --save: the MiddEval3 results layout


def check_algo_name(name: str) -> str:
    """An algorithm name for MiddEval3 file names: 1-40 letters, digits, '_' or '-'."""
    if not _ALGO_NAME.fullmatch(name):
        raise ConfigError(
            f"--algo-name {name!r} must be 1-40 letters, digits, '_' or '-' (it becomes part "
            "of the file names disp0NAME.pfm and timeNAME.txt)"
        )
    return name


def middeval3_paths(
    save_dir: str | os.PathLike, name: str, scenes: list[str]
) -> list[tuple[Path, str]]:
    """``DIR/<Scene>/disp0<NAME>.pfm`` and ``DIR/<Scene>/time<NAME>.txt`` of every scene, as
    ``(path, label)`` pairs to check before the first scene runs."""
    root = Path(save_dir)
    return [
        (root / s / f, "--save") for s in scenes for f in (f"disp0{name}.pfm", f"time{name}.txt")
    ]


def runtime_seconds(report: dict, estimate_ms: float) -> tuple[float, str]:
    """The run time written to ``time<NAME>.txt`` and what it is: the simulated chip's frame
    time, the figure a hardware submission reports -- measured by the cycle model (the
    report's ``latency.frame_ms``), else (``--mode functional``) the analytic estimate's,
    ``estimate_ms`` (:func:`sim.cycle.estimate.estimate`). Either is the same from run to run.
    Returns ``(seconds, "chip" | "estimate")``.
    """
    frame_ms = (report.get("latency") or {}).get("frame_ms")
    if frame_ms is not None:
        return float(frame_ms) * 1e-3, "chip"
    return float(estimate_ms) * 1e-3, "estimate"


def time_text(seconds: float, source: str) -> str:
    """The contents of a MiddEval3 ``time<NAME>.txt``: one plain number of seconds and a newline
    (6 significant digits, never in exponent notation; ``source`` is what
    :func:`runtime_seconds` says it is)."""
    return np.format_float_positional(seconds, precision=6, fractional=False, trim="-") + "\n"


def middeval3_files(
    save_dir: str | os.PathLike, name: str, results: dict[str, tuple[np.ndarray, dict, float]]
) -> dict[Path, bytes]:
    """Every scene's ``disp0<NAME>.pfm`` (float32, scale -1 little-endian, bottom row first,
    ``inf`` = invalid, as the MiddEval3 SDK reads it) and ``time<NAME>.txt``;
    ``results``: scene -> (disparity, report, the estimate's frame time in ms)."""
    root = Path(save_dir)
    files: dict[Path, bytes] = {}
    for scene, (disp, report, estimate_ms) in sorted(results.items()):
        d = _disparity(disp)
        files[root / scene / f"disp0{name}.pfm"] = pfm_bytes(np.where(np.isfinite(d), d, np.inf))
        files[root / scene / f"time{name}.txt"] = time_text(
            *runtime_seconds(report, estimate_ms)
        ).encode()
    return files


def middeval3_note(
    save_dir: str | os.PathLike, name: str, results: dict[str, tuple[np.ndarray, dict, float]]
) -> str:
    """The line ``stereosim eval --save`` prints: what was written and what the times are."""
    sources = {runtime_seconds(report, ms)[1] for _, report, ms in results.values()}
    what = (
        "the simulated chip's frame time"
        if sources == {"chip"}
        else "the chip's frame time as the analytic estimate gives it"
        if sources == {"estimate"}
        else "the chip's frame time, simulated or estimated"
    )
    return (
        f"wrote disp0{name}.pfm and time{name}.txt ({what}) for {len(results)} scene(s) "
        f"into {path_text(save_dir)}"
    )
