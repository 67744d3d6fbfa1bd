"""What the learned descriptor is trained on: the scenes, their usable pixels and the batches.

The training scenes are Middlebury 2005 (without Art, which is MiddEval3's ArtL) and 2006
ThirdSize (:func:`training_scene_dirs`); MiddEval3 is the evaluation set and is never read here,
nor used to calibrate the quantizer (:func:`calibration_scene_dirs`).

Objective ``curve`` draws strips of reference pixels of either view with the crops of both
views they need (:class:`StripSet`, :func:`sample_strips`); objective ``triplet`` draws a left
patch with a positive and a negative right patch (:class:`TrainingSet`, :func:`sample_batch`).
Each view gets its own photometric change -- defocus, gain, offset, gamma and sensor noise,
then rounding and clipping to 0..255 -- and the other view a small vertical misalignment, so the
descriptor learns to ignore what differs between two real cameras (:mod:`nna.training.augment`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stereosim.core.datasets import find_scene, find_scenes, load_scene, occluded_by_cross_check
from stereosim.core.errors import ConfigError, InputError
from stereosim.core.io import (
    is_folder,
    path_kind,
    path_text,
    read_gt,
    read_image,
    sub_folders,
    to_grey,
)
from stereosim.nna.training.augment import photometric, rows_at, vertical_offsets
from stereosim.nna.training.trainconfig import TrainConfig, receptive_field

# Training collections under the shared data folder and the scenes left out of them.
TRAIN_COLLECTIONS = ("middlebury2005_third", "middlebury2006_third")
EXCLUDED_SCENES = {"middlebury2005_third": ("Art",)}  # = MiddEval3 ArtL, an evaluation scene
EVALUATION_COLLECTION = "middlebury2014_trainingQ"


@dataclass(frozen=True, slots=True)
class TrainingSet:
    """All views flattened into one array, and every usable left pixel as a candidate sample.

    ``pixels`` float32 (N,): left and right images of every scene, row-major, one after the
    other; ``left_base``/``right_base``/``widths`` int64 per scene; candidates ``scene``, ``y``,
    ``x`` int64 and ``disp`` float32 per usable pixel; ``names`` the scenes used.
    """

    pixels: np.ndarray
    left_base: np.ndarray
    right_base: np.ndarray
    widths: np.ndarray
    scene: np.ndarray
    y: np.ndarray
    x: np.ndarray
    disp: np.ndarray
    names: tuple


def training_scene_dirs(data_dir) -> list[Path]:
    """The scene folders to train on under ``data_dir`` (the shared data folder)."""
    root = Path(data_dir)
    if not is_folder(root, "training data folder"):
        raise InputError(f"training data folder {path_text(root)} not found: give --data DIR")
    if root.name == EVALUATION_COLLECTION or path_kind(root / "mask0nocc.png", "mask"):
        raise InputError(f"{path_text(root)} is MiddEval3, the evaluation set: never train on it")
    dirs = []
    for coll in TRAIN_COLLECTIONS:
        folder = root / coll
        if not is_folder(folder, "training collection"):
            continue
        skip = EXCLUDED_SCENES.get(coll, ())
        dirs.extend(p for p in sub_folders(folder, "training collection") if p.name not in skip)
    if not dirs:
        raise InputError(
            f"{root} holds no training scenes: expected {' and '.join(TRAIN_COLLECTIONS)} "
            "folders of Middlebury 2005/2006 ThirdSize scenes"
        )
    return dirs


def cv_folds(names, folds: int) -> list[int]:
    """Each scene name's cross-validation fold: scene i of the sorted distinct names is in fold
    i mod ``folds`` (the tuning's folds, benchmarks/tune_defaults.py, and --leave-out-fold's)."""
    return [sorted(set(names)).index(name) % folds for name in names]


def leave_fold_out(scene_dirs, fold: int, folds: int) -> list[Path]:
    """``scene_dirs`` without fold ``fold`` of ``folds`` (:func:`cv_folds` of the folder names)."""
    dirs = [Path(d) for d in scene_dirs]
    if not 2 <= folds <= len(dirs) or not 0 <= fold < folds:
        raise ConfigError(f"fold {fold} of {folds}: need 2 <= folds <= {len(dirs)} (the "
                          f"scenes) and 0 <= fold < folds, e.g. --leave-out-fold 0/5")
    return [d for d, f in zip(dirs, cv_folds([d.name for d in dirs], folds), strict=True)
            if f != fold]


def load_training_set(scene_dirs, cfg: TrainConfig) -> TrainingSet:
    """Read the scenes and list the left pixels a triplet may be centred on: known,
    non-occluded ground truth d, with the patches and the negative's reach inside the image
    (objective ``triplet``, :mod:`nna.training.train`)."""

    r = patch_size(cfg) // 2
    reach = cfg.neg_high + r + 2  # how far the right patch may reach from x - d
    chunks, bases_l, bases_r, widths = [], [], [], []
    cand = {"scene": [], "y": [], "x": [], "disp": []}
    names = []
    pos = 0
    for i, folder in enumerate(scene_dirs):
        data = load_scene(find_scene(folder))
        left, right = to_grey(data["left"]), to_grey(data["right"])
        gt = data["gt"]
        mask = data["masks"].get("nonocc", data["masks"]["all"])
        h, w = left.shape
        ys, xs = np.nonzero(mask & np.isfinite(gt))
        d = gt[ys, xs]
        ok = (ys >= r) & (ys < h - r) & (xs - d - reach >= 0) & (xs - d + reach <= w - 1)
        ok &= (xs >= r) & (xs < w - r)
        names.append(f"{folder.parent.name}/{folder.name}")
        chunks += [left.ravel(), right.ravel()]
        bases_l.append(pos)
        bases_r.append(pos + h * w)
        widths.append(w)
        pos += 2 * h * w
        cand["scene"].append(np.full(int(ok.sum()), i, np.int64))
        cand["y"].append(ys[ok].astype(np.int64))
        cand["x"].append(xs[ok].astype(np.int64))
        cand["disp"].append(d[ok].astype(np.float32))
    return TrainingSet(
        pixels=np.concatenate(chunks).astype(np.float32),
        left_base=np.array(bases_l, np.int64),
        right_base=np.array(bases_r, np.int64),
        widths=np.array(widths, np.int64),
        names=tuple(names),
        **{k: np.concatenate(v) for k, v in cand.items()},
    )


def patch_size(cfg: TrainConfig) -> int:
    """Side of the training patches: the variant's receptive field, grown by the aggregation
    window."""
    return receptive_field(cfg.variant) + cfg.aggregate - 1


def sample_batch(ts: TrainingSet, cfg: TrainConfig, rng: np.random.Generator) -> np.ndarray:
    """One batch as uint8-valued float32 (3, B, P, P), P = :func:`patch_size`: left, positive
    right, negative right, each view with its own photometric change."""
    n = cfg.batch
    pick = rng.integers(0, ts.scene.size, size=n)
    s, y, x, d = ts.scene[pick], ts.y[pick], ts.x[pick], ts.disp[pick].astype(np.float64)
    widths = ts.widths[s]
    pos = rng.uniform(-cfg.pos_offset, cfg.pos_offset, n)
    neg = rng.uniform(cfg.neg_low, cfg.neg_high, n) * rng.choice((-1.0, 1.0), n)
    xr = x - d
    view = _Patches(ts, widths, patch_size(cfg))
    left = view.at(ts.left_base[s], y, x.astype(np.float64))
    right_p = view.at(ts.right_base[s], y, xr + pos)
    right_n = view.at(ts.right_base[s], y, xr + neg)
    size = patch_size(cfg)
    out = np.empty((3, n, size, size), np.float32)
    out[0] = photometric(left, cfg, rng)
    # both right patches come from the same right view: one change for the two
    pair = photometric(np.stack([right_p, right_n]), cfg, rng, shared_axis=True)
    out[1], out[2] = pair[0], pair[1]
    return out


class _Patches:
    """Gathers square patches at fractional columns from the flattened views."""

    def __init__(self, ts: TrainingSet, widths: np.ndarray, size: int):
        self.pixels = ts.pixels
        self.widths = widths
        self.size = size

    def at(self, base, y, xf) -> np.ndarray:
        r = self.size // 2
        x0 = np.floor(xf).astype(np.int64)
        frac = (xf - x0).astype(np.float32)[:, None, None]
        taps = np.arange(-r, r + 1)
        idx = base[:, None, None] + (y[:, None, None] + taps[None, :, None]) * self.widths[
            :, None, None
        ]
        idx = idx + x0[:, None, None] + taps[None, None, :]
        a = self.pixels[idx]
        b = self.pixels[idx + 1]
        return a + frac * (b - a)


# --- strips (objective "curve") -----------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class StripSet:
    """Both views of every scene as reference views, for the cost-curve objective.

    ``views[2 i + v]`` float32 (H, W) is view v (0 left, 1 right) of scene i and
    ``targets[2 i + v]`` float32 (H, W) its ground truth where usable (known, visible in the
    other view by the left/right GT cross-check, below ``disparities - 1``), NaN elsewhere.
    Candidates ``image``, ``y``, ``x`` int64 list every usable reference pixel; ``names`` the
    scenes used.
    """

    views: tuple
    targets: tuple
    image: np.ndarray
    y: np.ndarray
    x: np.ndarray
    names: tuple


def load_strip_set(scene_dirs, cfg: TrainConfig) -> StripSet:
    """Read the scenes with the GT of both views (``disp1.png`` and ``disp5.png``)."""

    views, targets, names = [], [], []
    cand = {"image": [], "y": [], "x": []}
    for folder in scene_dirs:
        scene = find_scene(folder)
        if scene.gt is None or scene.gt_right is None:
            raise InputError(
                f"training scene {folder} needs the GT of both views (disp1.png and disp5.png)"
            )
        data = load_scene(scene)
        gt_l = data["gt"]
        gt_r = read_gt(scene.gt_right, scene.gt_scale)
        visible_l = np.isfinite(gt_l) & ~occluded_by_cross_check(gt_l, gt_r)
        # the right view's check is the left view's on mirrored images
        visible_r = np.isfinite(gt_r) & ~occluded_by_cross_check(gt_r[:, ::-1], gt_l[:, ::-1])[
            :, ::-1
        ]
        names.append(f"{folder.parent.name}/{folder.name}")
        for img, gt, visible in (
            (data["left"], gt_l, visible_l),
            (data["right"], gt_r, visible_r),
        ):
            usable = visible & (gt < cfg.disparities - 1)
            ys, xs = np.nonzero(usable)
            cand["image"].append(np.full(ys.size, len(views), np.int64))
            cand["y"].append(ys.astype(np.int64))
            cand["x"].append(xs.astype(np.int64))
            views.append(to_grey(img).astype(np.float32))
            targets.append(np.where(usable, gt, np.nan).astype(np.float32))
    widest = max((v.shape[1] for v in views), default=0)
    if cfg.strip_width > widest:
        raise ConfigError(f"strip_width {cfg.strip_width} is wider than the widest training view "
                          f"({widest} px): a strip is part of one row")
    return StripSet(
        views=tuple(views),
        targets=tuple(targets),
        names=tuple(names),
        **{k: np.concatenate(v) for k, v in cand.items()},
    )


def strip_reach(cfg: TrainConfig) -> int:
    """Pixels a strip's crop reaches beyond its reference pixels: half the variant's receptive
    field and half the box filter."""
    return receptive_field(cfg.variant) // 2 + cfg.box // 2


def sample_strips(ss: StripSet, cfg: TrainConfig, rng: np.random.Generator) -> dict:
    """One batch of ``cfg.strips`` strips.

    A strip is ``strip_width`` consecutive reference pixels of one row around a drawn usable
    pixel. For a left reference view the other (right) view's crop reaches ``disparities - 1``
    columns further left (the match of x at disparity d is x - d); for a right reference view
    the left view's crop reaches as far right. Crops clamp coordinates into the image (the
    chip's replicate border). Returns uint8-valued float32 ``ref`` (S, 2 R + 1, Ws + 2 R) and
    ``other`` (S, 2 R + 1, Ws + 2 R + D - 1), R = :func:`strip_reach`, each view with its own
    photometric change; ``target`` (S, Ws) GT or NaN, ``max_disp`` (S, Ws) the largest
    disparity whose match lies inside the other view, and ``mirror`` (S,) bool: right
    reference, whose descriptor maps :func:`~nna.training.trainloss.cost_curves` mirrors into the
    left geometry (``target`` and ``max_disp`` are already mirrored); ``image``, ``y``, ``x0`` (S,)
    say where each strip was taken (view index in ``ss.views``, row, first reference column).
    """
    n, ws, dn = cfg.strips, cfg.strip_width, cfg.disparities
    reach = strip_reach(cfg)
    pick = rng.integers(0, ss.image.size, size=n)
    shift = rng.integers(0, ws, size=n)
    rows = np.arange(-reach, reach + 1)
    ref = np.empty((n, rows.size, ws + 2 * reach), np.float32)
    other = np.empty((n, rows.size, ws + 2 * reach + dn - 1), np.float32)
    target = np.empty((n, ws), np.float32)
    max_disp = np.empty((n, ws), np.float32)
    mirror = np.zeros(n, bool)
    starts = np.empty(n, np.int64)
    dys = vertical_offsets(cfg, rng, n)  # the other view's misalignment
    for k in range(n):
        i, y = int(ss.image[pick[k]]), int(ss.y[pick[k]])
        view, partner = ss.views[i], ss.views[i ^ 1]
        height, width = view.shape
        x0 = int(np.clip(ss.x[pick[k]] - shift[k], 0, max(width - ws, 0)))
        starts[k] = x0
        xs = np.arange(x0, x0 + ws)
        rr = np.clip(y + rows, 0, height - 1)[:, None]
        cols = np.arange(x0 - reach, x0 + ws + reach)
        ref[k] = view[rr, np.clip(cols, 0, width - 1)]
        gt = ss.targets[i][y, np.clip(xs, 0, width - 1)]
        gt[xs >= width] = np.nan
        if i % 2 == 0:  # left reference: the right view's crop reaches left
            ocols = np.arange(x0 - reach - (dn - 1), x0 + ws + reach)
            target[k], max_disp[k] = gt, xs
        else:  # right reference: the left view's crop reaches right; mirrored
            ocols = np.arange(x0 - reach, x0 + ws + reach + dn - 1)
            target[k], max_disp[k] = gt[::-1], (width - 1 - xs)[::-1]
            mirror[k] = True
        other[k] = rows_at(partner, y + rows, ocols, dys[k])
    return {
        "ref": photometric(ref, cfg, rng),
        "other": photometric(other, cfg, rng),
        "target": target,
        "max_disp": max_disp,
        "mirror": mirror,
        "image": ss.image[pick],
        "y": ss.y[pick],
        "x0": starts,
    }


# --- calibration scenes for the quantizer -------------------------------------------------------


def calibration_scene_dirs(path) -> list[Path]:
    """Scene folders for quantizer calibration: ``path`` may be the shared data folder (its
    training scenes), a collection of scenes or one scene. MiddEval3 is refused: it is the
    evaluation set and must not tune anything."""

    root = Path(path)
    if not is_folder(root, "calibration folder"):
        raise InputError(f"calibration folder {path_text(root)} not found: give --calib DIR")
    if any(is_folder(root / coll, "training collection") for coll in TRAIN_COLLECTIONS):
        return training_scene_dirs(root)
    if root.name == EVALUATION_COLLECTION or root.parent.name == EVALUATION_COLLECTION:
        raise InputError(f"{root} is MiddEval3, the evaluation set: calibrate on training scenes")
    scenes = [Path(s.left).parent for s in find_scenes(root)]
    if any(path_kind(s / "mask0nocc.png", "mask") for s in scenes):
        raise InputError(f"{root} is MiddEval3, the evaluation set: calibrate on training scenes")
    return scenes


def calibration_images(scene_dirs, limit: int) -> tuple[list[np.ndarray], list[str]]:
    """Left and right grey views of up to ``limit`` scenes spread evenly over ``scene_dirs``."""

    dirs = list(scene_dirs)
    if limit < len(dirs):
        picks = np.linspace(0, len(dirs) - 1, limit).round().astype(int)
        dirs = [dirs[i] for i in sorted(set(picks.tolist()))]
    images, names = [], []
    for folder in dirs:
        scene = find_scene(folder)
        images += [to_grey(read_image(scene.left)), to_grey(read_image(scene.right))]
        names.append(f"{folder.parent.name}/{folder.name}")
    return images, names
