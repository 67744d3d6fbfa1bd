"""Stereo scenes on disk: finding them, reading them and the masks they are evaluated on.

Three Middlebury folder layouts are recognised from the files present (names as Middlebury
ships them; see ``shared/data/README.md``):

- ``2014``: ``im0.png`` / ``im1.png``, GT ``disp0GT.pfm`` (scale 1, ``inf`` = unknown), mask
  ``mask0nocc.png`` (255 nonocc, 128 occluded, 0 no GT), ``calib.txt`` (``ndisp``), and
  ``disp1GT.pfm`` if present;
- ``2005/2006``: ``view1.png`` / ``view5.png``, GT ``disp1.png`` (x3, 0 = unknown), right-view GT
  ``disp5.png``, no mask files;
- ``2003``: ``im2.png`` / ``im6.png``, GT ``disp2.png`` (x4, 0 = unknown), right-view GT
  ``disp6.png``, masks ``nonocc.png`` and ``all.png`` (255 = evaluated).

The PNG scales 3 and 4 hold for the ThirdSize (2005/2006) and quarter-size (2003) versions only;
other sizes use other factors, so for those layouts the image width is checked and a scene of
another size needs an explicit ``gt_scale``.

Masks (boolean, True = evaluated) are named ``nonocc`` and ``all``. For 2005/2006, which ships no
mask files, ``nonocc`` is derived by a left/right cross-check of the two GT maps
(:func:`occluded_by_cross_check`).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stereosim.core.errors import InputError
from stereosim.core.io import (
    MAX_PIXELS,
    is_file,
    is_folder,
    path_text,
    png_size,
    read_gt,
    read_image,
    read_mask,
    read_text,
    sub_folders,
)

LAYOUT_2014 = "2014"
LAYOUT_2005 = "2005/2006"
LAYOUT_2003 = "2003"

# (layout, left, right, GT, GT scale, mask, right-view GT) in detection order.
_LAYOUTS = (
    (LAYOUT_2014, "im0.png", "im1.png", "disp0GT.pfm", 1.0, "mask0nocc.png", "disp1GT.pfm"),
    (LAYOUT_2005, "view1.png", "view5.png", "disp1.png", 3.0, None, "disp5.png"),
    (LAYOUT_2003, "im2.png", "im6.png", "disp2.png", 4.0, "nonocc.png", "disp6.png"),
)

# Image widths for which the default PNG GT scale is right: Middlebury 2005/2006 ThirdSize is
# 413..465 px wide, 2003 quarter size 450 px. Half and full sizes are about 2x and 3-4x wider.
_DEFAULT_SCALE_WIDTHS = {LAYOUT_2005: (380, 520), LAYOUT_2003: (380, 520)}

_EXPECTED = (
    "im0.png + im1.png (+ disp0GT.pfm, mask0nocc.png, calib.txt) for Middlebury 2014, "
    "view1.png + view5.png (+ disp1.png, disp5.png) for 2005/2006, or "
    "im2.png + im6.png (+ disp2.png, disp6.png, nonocc.png) for 2003"
)

# Largest |left GT - right GT| (pixels) at which a 2005/2006 pixel still counts as visible.
CROSS_CHECK_TOLERANCE_PX = 1.0


@dataclass(frozen=True, slots=True)
class Scene:
    """Where the files of one stereo scene are; nothing is read until :func:`load_scene`."""

    name: str
    layout: str
    left: Path
    right: Path
    gt: Path | None
    gt_scale: float
    mask: Path | None
    gt_right: Path | None
    ndisp: int | None

    @property
    def files(self) -> tuple[Path, ...]:
        """Every file of the scene a command may read (the pair, the GTs, the masks,
        ``calib.txt``): no output may replace one of them."""
        folder = self.left.parent
        named = (self.left, self.right, self.gt, self.mask, self.gt_right, folder / "calib.txt",
                 folder / "all.png" if self.layout == LAYOUT_2003 else None)
        return tuple(p for p in named if p is not None)


def shared_data_dir() -> Path | None:
    """The folder of the shared Middlebury data, or None when it is not there.

    ``$STEREOSIM_DATA`` if set, else ``shared/data`` beside the repository (``../shared/data``
    seen from the repository root).
    """
    env = os.environ.get("STEREOSIM_DATA")
    if env:
        candidate = Path(env)
    else:
        candidate = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
    candidate = candidate.resolve()
    return candidate if is_folder(candidate, "shared data folder ($STEREOSIM_DATA)") else None


def find_scene(folder: str | os.PathLike, gt_scale: float | None = None) -> Scene:
    """Detect the layout of one scene folder and return where its files are.

    ``gt_scale`` overrides the layout's GT scale (needed for PNG ground truth of a size other than
    2005/2006 ThirdSize or 2003 quarter size).
    """
    folder = Path(folder)
    if not is_folder(folder, "scene folder"):
        raise InputError(
            f"scene folder {path_text(folder)} not found: give a folder holding a stereo pair"
        )
    if gt_scale is not None and not (math.isfinite(gt_scale) and gt_scale > 0):
        raise InputError(f"GT scale is {gt_scale}: give a positive number (--gt-scale)")
    for layout, left, right, gt, scale, mask, gt_right in _LAYOUTS:
        if not (is_file(folder / left, "image") and is_file(folder / right, "image")):
            continue
        gt_path = folder / gt if is_file(folder / gt, "GT") else None
        if gt_scale is not None:
            scale = float(gt_scale)
        elif gt_path is not None and layout in _DEFAULT_SCALE_WIDTHS:
            lo, hi = _DEFAULT_SCALE_WIDTHS[layout]
            width = png_size(folder / left)[0]
            if not lo <= width <= hi:
                raise InputError(
                    f"scene {path_text(folder)} ({layout} layout) is {width} px wide, not the "
                    f"{lo}..{hi} px of the size whose GT scale is {scale:g}: pass the scale of "
                    "its PNG GT with --gt-scale (e.g. 2 for HalfSize, 1 for full size)"
                )
        ndisp = None
        calib = folder / "calib.txt"
        if layout == LAYOUT_2014 and is_file(calib, "calibration file"):
            value = parse_calib(calib).get("ndisp")
            if value is not None:
                if isinstance(value, str) or not float(value).is_integer():
                    raise InputError(
                        f"{path_text(calib)} has ndisp={value}: it must be a whole number"
                    )
                ndisp = int(value)
        return Scene(
            name=folder.name,
            layout=layout,
            left=folder / left,
            right=folder / right,
            gt=gt_path,
            gt_scale=float(scale),
            mask=folder / mask if mask and is_file(folder / mask, "mask") else None,
            gt_right=folder / gt_right if is_file(folder / gt_right, "GT") else None,
            ndisp=ndisp,
        )
    scenes = [d.name for d in _scene_subfolders(folder)]
    if scenes:
        raise InputError(
            f"{path_text(folder)} is a folder of {len(scenes)} scenes ({', '.join(scenes[:3])}"
            f"{', ...' if len(scenes) > 3 else ''}), not one scene: run one of them "
            f"(stereosim run {path_text(folder / scenes[0])}) or score them all (stereosim eval "
            f"{path_text(folder)})")
    raise InputError(f"{path_text(folder)} is not a scene folder: expected {_EXPECTED}")


def _scene_subfolders(folder: Path) -> list[Path]:
    """The sub-folders of ``folder`` that are scenes (none if it cannot be listed)."""
    try:
        return [d for d in sub_folders(folder, "dataset folder") if _is_scene(d)]
    except InputError:
        return []


def scene_files(scenes) -> list[tuple[Path, str]]:
    """The files of these scenes (:class:`Scene` objects or folders) as ``(path, "scene file")``
    inputs for :func:`core.outputs.check_outputs`: no output may replace one."""
    return [(p, "scene file") for s in scenes
            for p in (s if isinstance(s, Scene) else find_scene(s)).files]


def _is_scene(folder: Path) -> bool:
    return any(
        is_file(folder / lt, "image") and is_file(folder / rt, "image")
        for _, lt, rt, *_ in _LAYOUTS
    )


def find_scenes(dataset_dir: str | os.PathLike, gt_scale: float | None = None) -> list[Scene]:
    """All scenes of a dataset folder: its sub-folders that are scenes, sorted by name.

    A folder that is itself a scene gives a list of that one scene.
    """
    root = Path(dataset_dir)
    if not is_folder(root, "dataset folder"):
        raise InputError(f"dataset folder {path_text(root)} not found: check the path")
    if _is_scene(root):
        return [find_scene(root, gt_scale)]
    subs = sub_folders(root, "dataset folder")
    scenes = [find_scene(d, gt_scale) for d in subs if _is_scene(d)]
    if not scenes:
        raise InputError(
            f"no scene folders found in {path_text(root)}: each scene needs {_EXPECTED}"
        )
    return scenes


def _number(text: str) -> int | float | str:
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def parse_calib(path: str | os.PathLike) -> dict[str, int | float | str]:
    """Parse a Middlebury ``calib.txt``: ``key=value`` lines.

    Numbers become ``int`` or ``float``; anything else (the ``cam0``/``cam1`` matrices such as
    ``[999.421 0 294.182; 0 999.421 252.932; 0 0 1]``) stays a string. Spaces around the key and
    the value are ignored; blank lines are skipped. The file is ASCII and at most
    :data:`core.io.MAX_TEXT_FILE_BYTES` long.
    """
    p = Path(path)
    text = read_text(p, "calibration")
    result: dict[str, int | float | str] = {}
    for lineno, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if not line:
            continue
        key, sep, value = line.partition("=")
        key = key.strip()
        if not sep or not key:
            raise InputError(
                f"{path_text(p)} line {lineno} is not 'key=value': {line[:40]!r}; fix the file"
            )
        value = value.strip()
        result[key] = value if key in ("cam0", "cam1") else _number(value)
    return result


def legal_disparities(ndisp: int) -> int:
    """The chip's disparity count D for a search range [0, ndisp): ndisp rounded up to a multiple
    of 16, at least 16 and at most 256."""
    if isinstance(ndisp, bool) or not isinstance(ndisp, (int, np.integer)) or ndisp < 1:
        raise InputError(f"ndisp is {ndisp!r}: give a positive whole number of disparities")
    if ndisp > 256:
        raise InputError(
            f"ndisp {ndisp} is more than the chip's 256 disparities: downsample the images"
        )
    return max(16, -(-int(ndisp) // 16) * 16)


def occluded_by_cross_check(
    gt_left: np.ndarray, gt_right: np.ndarray, tolerance_px: float = CROSS_CHECK_TOLERANCE_PX
) -> np.ndarray:
    """Left-view pixels with known GT that are occluded in the right view (boolean ``(H, W)``).

    A left pixel ``(x, y)`` with GT ``d`` maps to right pixel ``x' = floor(x - d + 0.5)``. It is
    occluded if ``x'`` is outside the image, the right GT there is unknown, or
    ``|gt_right(x', y) - d| > tolerance_px``. Pixels with unknown left GT are never occluded.
    """
    gl = np.asarray(gt_left, dtype=np.float64)
    gr = np.asarray(gt_right, dtype=np.float64)
    if gl.ndim != 2 or gl.shape != gr.shape:
        raise InputError(
            f"left GT {gl.shape} and right GT {gr.shape} must be 2-D of the same shape"
        )
    width = gl.shape[1]
    known = np.isfinite(gl)
    x_right = np.floor(np.arange(width)[None, :] - np.where(known, gl, 0.0) + 0.5)
    inside = known & (x_right >= 0) & (x_right <= width - 1)
    cols = np.clip(x_right, 0, width - 1).astype(np.intp)
    d_right = np.take_along_axis(gr, cols, axis=1)
    both = inside & np.isfinite(d_right)
    diff = np.abs(np.where(both, d_right, 0.0) - np.where(both, gl, 0.0))
    visible = both & (diff <= tolerance_px)
    return known & ~visible


def _check_shape(what: str, arr: np.ndarray, shape: tuple[int, int], path: Path) -> None:
    if arr.shape[:2] != shape:
        raise InputError(
            f"{what} {path_text(path)} is {arr.shape[1]}x{arr.shape[0]} but the left image is "
            f"{shape[1]}x{shape[0]}: use files of the same scene and size"
        )


def load_scene(scene: Scene, *, max_pixels: int = MAX_PIXELS) -> dict:
    """Read a scene's images, GT and masks (each at most ``max_pixels`` pixels).

    Returns a dict with ``name``, ``layout``, ``left`` and ``right`` (``uint8`` grey or RGB),
    ``gt`` (``float32``, pixels, ``inf`` = unknown; None without GT), ``masks`` (name -> boolean
    array; ``nonocc`` and/or ``all``), ``ndisp`` (from calib.txt, or None) and ``note`` (how the
    masks were made when that is not obvious, else None).
    """
    left = read_image(scene.left, max_pixels=max_pixels)
    right = read_image(scene.right, max_pixels=max_pixels)
    shape = left.shape[:2]
    if right.shape != left.shape:
        raise InputError(
            f"right image {path_text(scene.right)} has shape {right.shape} but the left image has "
            f"{left.shape}: use a rectified pair of the same size and colour format"
        )
    result = {
        "name": scene.name,
        "layout": scene.layout,
        "left": left,
        "right": right,
        "gt": None,
        "masks": {},
        "ndisp": scene.ndisp,
        "note": None,
    }
    if scene.gt is None:
        result["note"] = "no ground truth in the scene folder: nothing to evaluate"
        return result
    gt = read_gt(scene.gt, scene.gt_scale, max_pixels=max_pixels)
    _check_shape("GT", gt, shape, scene.gt)
    finite = np.isfinite(gt)
    result["gt"] = gt
    masks: dict[str, np.ndarray] = {}
    mask = None
    if scene.mask is not None:
        mask = read_mask(scene.mask, max_pixels=max_pixels)
        _check_shape("mask", mask, shape, scene.mask)
    if scene.layout == LAYOUT_2014 and mask is not None:
        masks["nonocc"] = mask == 255
        masks["all"] = mask != 0
    elif scene.layout == LAYOUT_2003 and mask is not None:
        masks["nonocc"] = mask == 255
        all_path = scene.mask.parent / "all.png"
        if is_file(all_path, "mask"):
            all_mask = read_mask(all_path, max_pixels=max_pixels)
            _check_shape("mask", all_mask, shape, all_path)
            masks["all"] = all_mask == 255
        else:
            masks["all"] = finite
    else:
        masks["all"] = finite
        if scene.gt_right is not None:
            gt_right = read_gt(scene.gt_right, scene.gt_scale, max_pixels=max_pixels)
            _check_shape("right-view GT", gt_right, shape, scene.gt_right)
            masks["nonocc"] = finite & ~occluded_by_cross_check(gt, gt_right)
            result["note"] = (
                f"nonocc derived by a left/right cross-check of {scene.gt.name} and "
                f"{scene.gt_right.name} (tolerance {CROSS_CHECK_TOLERANCE_PX:g} px)"
            )
        else:
            result["note"] = (
                "no occlusion mask or right-view GT: only 'all' (finite GT) is evaluated"
            )
    result["masks"] = {name: masks[name] for name in ("nonocc", "all") if name in masks}
    return result


def default_scene() -> dict:
    """The Middlebury 2014 Motorcycle pair bundled with scikit-image, shaped like
    :func:`load_scene`'s result (741x500 RGB; GT float32 in pixels)."""
    from skimage.data import stereo_motorcycle

    left, right, disp = stereo_motorcycle()
    # The docstring says NaN marks unknown GT but the bundled file uses inf: treat any
    # non-finite value as unknown.
    gt = np.where(np.isfinite(disp), disp, np.inf).astype(np.float32)
    return {
        "name": "Motorcycle (scikit-image)",
        "layout": "scikit-image",
        "left": np.ascontiguousarray(left, dtype=np.uint8),
        "right": np.ascontiguousarray(right, dtype=np.uint8),
        "gt": gt,
        "masks": {"all": np.isfinite(gt)},
        "ndisp": None,
        "note": "scikit-image ships no occlusion mask: only 'all' (finite GT) is evaluated",
    }
