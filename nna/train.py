"""Training the learned descriptor in torch on the CPU.

Three variants, all with a 9x9 receptive field and 32 output channels (one descriptor bit each):

* ``mccnn4``: four 3x3 convolutions, channels 1, 32, 32, 32, 32 (MC-CNN-fast);
* ``mccnn4-slim``: four 3x3 convolutions, channels 1, 4, 4, 8, 32;
* ``single9x9``: one 9x9 convolution, 1 -> 32 (the network the chip ships).

ReLU between layers, none after the last. Training uses 'valid' convolutions on crops; at
inference the same weights run on whole images with the chip's replicate border
(:mod:`quant.quantizer` ``float_forward``), identical away from the border. The descriptor the
chip uses is the **sign** of each output.

Two objectives:

* ``curve`` (default): what the SVA's winner-take-all sees after the box filter, with every
  negative. A batch is ``strips`` strips of ``strip_width`` consecutive reference pixels of one
  row, the reference view being the left or the right view of a scene (each with its own GT,
  ``disp1.png`` / ``disp5.png``). One convolution over the (9 + box - 1)-row crop of the reference
  view and over the matching crop of the other view, ``disparities - 1`` columns longer, gives
  the descriptors; their relaxed bits ``tanh(a f)`` give the Hamming distance ``(C - b . b') / 2``
  of every reference pixel to each of its ``disparities`` candidates, which is box-filtered as
  the SVA does (:func:`cost_curves`). The loss is the softmax cross-entropy of ``-cost / T``
  (T learnt) against the ground truth split between its two neighbouring integer disparities
  (:func:`curve_loss`). The tanh scale ``a`` grows geometrically from ``scale_start`` to
  ``scale_end`` so the relaxation tends to the signs, and the last ``sign_fraction`` of the run
  uses the signs themselves (straight-through gradient, :func:`relaxed_bits`), so the network
  is trained for the Hamming costs the chip computes. Two small regularisers keep every bit
  informative (:func:`bit_regularisers`): its mean over the batch (balanced bits) and the
  correlations between bits.
* ``triplet``: MC-CNN's recipe. For a left pixel (x, y) with known, non-occluded ground truth
  d, the positive right patch is centred at x - d + U(-pos, pos), the negative one at
  x - d +- U(neg_low, neg_high), both interpolated linearly along the row; hinge loss
  ``max(0, margin + s(L, N) - s(L, P))`` on a similarity s: ``cosine`` (MC-CNN's), ``tanh``
  (``s = mean_c tanh(f_L[c]) tanh(f_R[c])``, which for outputs of large magnitude tends to
  ``1 - 2 * Hamming(sign f_L, sign f_R) / 32``) or ``both``. With ``aggregate = A > 1`` the
  patches grow to (8 + A) x (8 + A) and the similarity is averaged over the A x A map.

Each view gets its own photometric change -- defocus, gain, offset, gamma and sensor noise, then
rounding and clipping to 0..255 -- and the other view a small vertical misalignment, so the
descriptor learns to ignore what differs between two real cameras (:mod:`nna.augment`).

Input normalisation is the NNA's: ``x = (pixel - input_offset) * input_scale`` with two
constants fixed before training (recorded in the output file), nothing per patch.

The training scenes are Middlebury 2005 (without Art, which is MiddEval3's ArtL) and 2006
ThirdSize; MiddEval3 is the evaluation set and is never read here.

Thread count, checkpoints and resuming a long run: :mod:`nna.trainrun`. torch is imported only
inside the functions that need it: the rest of stereosim does not depend on it.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from stereosim.nna.augment import photometric, rows_at, vertical_offsets
from stereosim.nna.trainrun import (
    load_checkpoint,
    pick_threads,
    restore,
    save_checkpoint,
    snapshot,
    threads_line,
    use_threads,
)
from stereosim.quant.quantizer import FloatModel
from stereosim.sim.datasets import find_scene, find_scenes, load_scene, occluded_by_cross_check
from stereosim.sim.errors import ConfigError, InputError
from stereosim.sim.io import (
    is_folder,
    path_kind,
    path_text,
    read_gt,
    read_image,
    sub_folders,
    to_grey,
)
from stereosim.sim.npz import open_npz
from stereosim.sim.outputs import atomic_write_bytes
from stereosim.sim.progress import progress_bar

# (C_in, C_out, K) per layer
VARIANTS = {
    "mccnn4": ((1, 32, 3), (32, 32, 3), (32, 32, 3), (32, 32, 3)),
    "mccnn4-slim": ((1, 4, 3), (4, 4, 3), (4, 8, 3), (8, 32, 3)),
    "single9x9": ((1, 32, 9),),
}
PATCH = 9  # receptive field of every variant
SIMILARITIES = ("cosine", "tanh", "both")
OBJECTIVES = ("curve", "triplet")
FORMAT = "stereosim-float-v1"
# Training collections under the shared data folder and the scenes left out of them.
TRAIN_COLLECTIONS = ("middlebury2005_third", "middlebury2006_third")
EXCLUDED_SCENES = {"middlebury2005_third": ("Art",)}  # = MiddEval3 ArtL, an evaluation scene
EVALUATION_COLLECTION = "middlebury2014_trainingQ"


@dataclass(frozen=True, slots=True, kw_only=True)
class TrainConfig:
    """Settings of one training run (all recorded in the output file)."""

    variant: str = "single9x9"
    objective: str = "curve"
    epochs: int = 20
    steps_per_epoch: int = 1000
    lr: float = 0.004
    seed: int = 0
    # objective "curve": strips of the reference view against every candidate disparity
    strips: int = 32
    strip_width: int = 64
    disparities: int = 96
    box: int = 5
    temperature: float = 1.0
    scale_start: float = 1.0
    scale_end: float = 12.0
    sign_fraction: float = 0.3
    balance: float = 1.0
    decorrelate: float = 0.5
    # objective "triplet": one positive and one negative right patch per left pixel
    batch: int = 256
    pos_offset: float = 0.5
    neg_low: float = 1.5
    neg_high: float = 6.0
    margin: float = 0.2
    similarity: str = "tanh"
    aggregate: int = 1
    gain: float = 0.2
    offset: float = 20.0
    noise_max: float = 2.0
    # more of what differs between two cameras (nna.augment; 0 = off)
    gamma: float = 0.0
    shot_noise: float = 0.0
    blur_max: float = 0.0
    vshift_max: float = 0.0
    input_offset: int = 128
    input_scale: float = 1.0 / 64.0
    threads: int = 0  # torch CPU threads; 0 = auto (nna.trainrun.pick_threads)

    def __post_init__(self):
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.type in ("int", "float") and (
                isinstance(value, bool) or not isinstance(value, (int, float))
            ):
                raise ConfigError(f"{f.name} must be a number, got {value!r}")
            if f.type == "float" and not math.isfinite(value):
                raise ConfigError(f"{f.name} must be a finite number, got {value!r}")
        if self.variant not in VARIANTS:
            raise ConfigError(
                f"unknown variant {self.variant!r}; choose one of {', '.join(VARIANTS)}"
            )
        if self.objective not in OBJECTIVES:
            raise ConfigError(
                f"unknown objective {self.objective!r}; choose one of {', '.join(OBJECTIVES)}"
            )
        if self.similarity not in SIMILARITIES:
            raise ConfigError(
                f"unknown similarity {self.similarity!r}; choose one of {', '.join(SIMILARITIES)}"
            )
        for name in ("aggregate", "box"):
            if getattr(self, name) < 1 or getattr(self, name) % 2 == 0:
                raise ConfigError(f"{name} must be odd and >= 1, got {getattr(self, name)}")
        for name in ("epochs", "steps_per_epoch", "batch", "strips", "strip_width"):
            if getattr(self, name) < 1:
                raise ConfigError(f"{name} must be at least 1, got {getattr(self, name)}")
        if self.threads < 0:
            raise ConfigError(f"threads must be 0 (auto) or more, got {self.threads}")
        if not 0 <= self.pos_offset < self.neg_low <= self.neg_high:
            raise ConfigError(
                "offsets must satisfy 0 <= pos_offset < neg_low <= neg_high, got "
                f"{self.pos_offset}, {self.neg_low}, {self.neg_high}"
            )
        if not 0 <= self.input_offset <= 255 or not self.input_scale > 0:
            raise ConfigError("input_offset must be in 0..255 and input_scale positive")
        if self.lr <= 0 or min(self.margin, self.gain, self.offset, self.noise_max, self.gamma,
                               self.shot_noise, self.blur_max, self.vshift_max) < 0:
            raise ConfigError("lr must be positive; margin, gain, offset, noise_max, gamma, "
                              "shot_noise, blur_max and vshift_max non-negative")
        if self.disparities < 2:
            raise ConfigError(f"disparities must be at least 2, got {self.disparities}")
        if not (self.temperature > 0 and 0 < self.scale_start <= self.scale_end):
            raise ConfigError(
                "temperature must be positive and 0 < scale_start <= scale_end, got "
                f"{self.temperature}, {self.scale_start}, {self.scale_end}"
            )
        if not 0 <= self.sign_fraction <= 1 or min(self.balance, self.decorrelate) < 0:
            raise ConfigError("sign_fraction must be in [0, 1]; balance, decorrelate >= 0")


# --- data ---------------------------------------------------------------------------------------


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
    """Read the scenes and list the pixels that can be sampled (module docstring)."""

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
    """Side of the training patches: the 9x9 receptive field, grown by the aggregation window."""
    return PATCH + cfg.aggregate - 1


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
    return StripSet(
        views=tuple(views),
        targets=tuple(targets),
        names=tuple(names),
        **{k: np.concatenate(v) for k, v in cand.items()},
    )


def strip_reach(cfg: TrainConfig) -> int:
    """Pixels a strip's crop reaches beyond its reference pixels: the 9x9 receptive field and
    the box filter."""
    return PATCH // 2 + cfg.box // 2


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
    reference, whose descriptor maps :func:`cost_curves` mirrors into the left geometry
    (``target`` and ``max_disp`` are already mirrored); ``image``, ``y``, ``x0`` (S,) say where
    each strip was taken (view index in ``ss.views``, row, first reference column).
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


# --- model and loss -----------------------------------------------------------------------------


def build_network(variant: str):
    """The torch network of a variant: 'valid' convolutions, ReLU between layers."""
    import torch

    layers = []
    spec = VARIANTS[variant]
    for i, (c_in, c_out, k) in enumerate(spec):
        layers.append(torch.nn.Conv2d(c_in, c_out, k))
        if i < len(spec) - 1:
            layers.append(torch.nn.ReLU())
    return torch.nn.Sequential(*layers)


def similarity(f_a, f_b, kind: str):
    """Similarity of two batches of descriptors (B, C), or of descriptor maps (B, C, A, A):
    cosine or the tanh relaxation, at each of the A x A positions averaged over them."""
    import torch

    if kind == "cosine":
        per_pos = torch.nn.functional.cosine_similarity(f_a, f_b, dim=1, eps=1e-6)
    else:
        per_pos = (torch.tanh(f_a) * torch.tanh(f_b)).mean(dim=1)
    return per_pos if per_pos.ndim == 1 else per_pos.flatten(1).mean(dim=1)


def hinge_loss(f_l, f_p, f_n, cfg: TrainConfig):
    kinds = ("cosine", "tanh") if cfg.similarity == "both" else (cfg.similarity,)
    loss = 0.0
    for kind in kinds:
        s_pos = similarity(f_l, f_p, kind)
        s_neg = similarity(f_l, f_n, kind)
        loss = loss + (cfg.margin + s_neg - s_pos).clamp(min=0.0).mean()
    return loss


def relaxed_bits(f, scale: float, sign: bool):
    """The descriptor bits as +-1: ``tanh(scale * f)``, or with ``sign`` the signs themselves
    with the gradient of the tanh (straight-through)."""
    import torch

    soft = torch.tanh(scale * f)
    if not sign:
        return soft
    return soft + (torch.sign(f) - soft).detach()


def cost_curves(b_ref, b_other, disparities: int, box: int):
    """Box-filtered relaxed Hamming costs (S, Ws, D) on the scale of one descriptor, 0..C.

    ``b_ref`` (S, C, box, Ws + box - 1) and ``b_other`` (S, C, box, Ws + box - 1 + D - 1) are
    +-1 bit maps (:func:`relaxed_bits`) in the left-reference geometry: column j of the
    reference matches column j + D - 1 - d of the other map at disparity d. The Hamming
    distance of two +-1 vectors is ``(C - a . b) / 2``; the box filter of the SVA is the mean
    over the box x box window (the chip's sum divided by box^2).
    """
    import torch

    n_ref, n_other = b_ref.shape[3], b_other.shape[3]
    # every reference column against every other column of the same row, then the band of
    # the D candidates of each reference column
    dots = b_ref.permute(0, 2, 3, 1) @ b_other.permute(0, 2, 1, 3)  # (S, box, n_ref, n_other)
    band = dots.as_strided(
        (dots.shape[0], dots.shape[1], n_ref, disparities),
        (dots.stride(0), dots.stride(1), n_other + 1, 1),
    ).flip(-1)
    cost = 0.5 * (b_ref.shape[1] - band)  # (S, box, n_ref, D)
    cost = cost.mean(dim=1).permute(0, 2, 1)  # (S, D, n_ref): the box's rows
    cost = torch.nn.functional.avg_pool1d(cost, box, stride=1)  # and its columns
    return cost.permute(0, 2, 1)


def curve_loss(cost, target, max_disp, log_temp):
    """Softmax cross-entropy over the candidate disparities of every usable reference pixel.

    ``-cost / T`` are the logits (T = exp(log_temp), learnt); candidates whose match lies
    outside the other view are left out; the target splits between the two integer
    disparities around the (sub-pixel) ground truth, in proportion to their closeness.
    """
    import torch

    grid = torch.arange(cost.shape[2], dtype=cost.dtype)
    logits = (-cost / log_temp.exp()).masked_fill(grid > max_disp[..., None], -1e4)
    usable = torch.isfinite(target)
    gt = torch.nan_to_num(target, nan=0.0)
    weight = (1.0 - (grid - gt[..., None]).abs()).clamp(min=0.0)
    ce = -(weight * torch.nn.functional.log_softmax(logits, dim=-1)).sum(dim=-1)
    return ce[usable].mean() if bool(usable.any()) else cost.sum() * 0.0


def bit_regularisers(bits):
    """(balance, decorrelation) of the +-1 bit maps (S, C, ...): the squared mean of each bit
    (0 when a bit is 1 as often as -1) and the squared off-diagonal correlations between bits
    (0 when the bits are uncorrelated), each averaged, so every bit carries information."""
    import torch

    c = bits.shape[1]
    z = bits.transpose(0, 1).reshape(c, -1)
    mean = z.mean(dim=1)
    z = z - mean[:, None]
    cov = (z @ z.T) / z.shape[1]
    std = cov.diagonal().clamp(min=1e-6).sqrt()
    corr = cov / std[:, None] / std[None, :]
    off = corr - torch.eye(c, dtype=corr.dtype)
    return (mean * mean).mean(), (off * off).sum() / (c * (c - 1))


def _scale_at(cfg: TrainConfig, frac: float) -> float:
    """The tanh scale after ``frac`` of the run: geometric from scale_start to scale_end."""
    return cfg.scale_start * (cfg.scale_end / cfg.scale_start) ** frac


def _curve_step(net, batch, cfg: TrainConfig, frac: float, log_temp):
    import torch

    def features(crops):
        x = (torch.from_numpy(crops) - float(cfg.input_offset)) * cfg.input_scale
        return net(x[:, None])

    f_ref, f_other = features(batch["ref"]), features(batch["other"])
    mirror = torch.from_numpy(batch["mirror"])[:, None, None, None]
    f_ref = torch.where(mirror, f_ref.flip(3), f_ref)
    f_other = torch.where(mirror, f_other.flip(3), f_other)
    scale, sign = _scale_at(cfg, frac), frac >= 1.0 - cfg.sign_fraction
    b_ref, b_other = relaxed_bits(f_ref, scale, sign), relaxed_bits(f_other, scale, sign)
    cost = cost_curves(b_ref, b_other, cfg.disparities, cfg.box)
    loss = curve_loss(
        cost, torch.from_numpy(batch["target"]), torch.from_numpy(batch["max_disp"]), log_temp
    )
    if cfg.balance or cfg.decorrelate:
        bal, dec = bit_regularisers(b_ref)
        loss = loss + cfg.balance * bal + cfg.decorrelate * dec
    return loss


# --- the run ------------------------------------------------------------------------------------


def train(cfg: TrainConfig, scene_dirs, *, progress: bool = True, checkpoint=None,
          checkpoint_every: int = 0, resume: bool = False, log=None) -> dict:
    """Train one network; returns the arrays and metadata :func:`save_float_model` writes.

    ``cfg.threads`` 0 picks the thread count (:func:`nna.trainrun.pick_threads`; the result
    records the count used). With ``checkpoint`` (a path) and ``checkpoint_every`` N > 0 the
    state is written there every N steps; ``resume`` continues from it, to the same weights as
    an uninterrupted run (:mod:`nna.trainrun`). ``log(line)`` receives the line that says how
    many threads the run uses, before the first step."""
    import torch

    requested = cfg.threads
    cfg = dataclasses.replace(cfg, threads=pick_threads(requested))
    use_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    torch.use_deterministic_algorithms(True)
    rng = np.random.default_rng(cfg.seed)
    if cfg.objective == "curve":
        data = load_strip_set(scene_dirs, cfg)
        n_samples = data.image.size
    else:
        data = load_training_set(scene_dirs, cfg)
        n_samples = data.scene.size
    if n_samples == 0:
        raise InputError("the training scenes have no pixel with usable ground truth")
    net = build_network(cfg.variant)
    params = list(net.parameters())
    log_temp = torch.nn.Parameter(torch.tensor(float(np.log(cfg.temperature))))
    if cfg.objective == "curve":
        params.append(log_temp)
    opt = torch.optim.Adam(params, lr=cfg.lr)
    total = cfg.epochs * cfg.steps_per_epoch
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda step: 1.0 - step / total)
    run = {"step": 0, "history": [], "running": 0.0}
    if resume:
        saved = load_checkpoint(checkpoint, asdict(cfg), data.names)
        restore(saved, net, log_temp, opt, sched, rng, checkpoint)
        run = {k: saved[k] for k in run}
    if log is not None:
        log(threads_line(cfg.threads, requested))
    bar = progress_bar(total, f"train {cfg.variant}", "step", quiet=not progress,
                       initial=run["step"])
    with bar:
        for step in range(run["step"], total):
            epoch, k = divmod(step, cfg.steps_per_epoch)
            if cfg.objective == "curve":
                loss = _curve_step(net, sample_strips(data, cfg, rng), cfg, step / total, log_temp)
            else:
                loss = _triplet_step(net, sample_batch(data, cfg, rng), cfg)
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            run["running"] += loss.item()
            if k == cfg.steps_per_epoch - 1:
                run["history"].append(run["running"] / cfg.steps_per_epoch)
                run["running"] = 0.0
            run["step"] = step + 1
            bar.update(1)
            bar.set_postfix(epoch=epoch + 1, loss=f"{loss.item():.4f}", refresh=False)
            if checkpoint is not None and checkpoint_every > 0 and run["step"] < total \
                    and run["step"] % checkpoint_every == 0:
                state = {**snapshot(net, log_temp, opt, sched, rng), **run}
                save_checkpoint(checkpoint, state, asdict(cfg), data.names)
    convs = [m for m in net if isinstance(m, torch.nn.Conv2d)]
    return {
        "weights": [c.weight.detach().numpy().astype(np.float32) for c in convs],
        "biases": [c.bias.detach().numpy().astype(np.float32) for c in convs],
        "config": asdict(cfg),
        "scenes": list(data.names),
        "loss_per_epoch": run["history"],
        "samples": int(n_samples),
    }


def _triplet_step(net, batch, cfg: TrainConfig):
    import torch

    x = (torch.from_numpy(batch) - float(cfg.input_offset)) * cfg.input_scale
    f = net(x.reshape(3 * cfg.batch, 1, *batch.shape[2:]))
    if cfg.aggregate == 1:
        f = f.reshape(3, cfg.batch, -1)
    else:
        f = f.reshape(3, cfg.batch, *f.shape[1:])
    return hinge_loss(f[0], f[1], f[2], cfg)


def save_float_model(path, result: dict) -> None:
    """Write a trained float model as .npz, atomically (format ``stereosim-float-v1``)."""
    import io


    cfg = result["config"]
    arrays = {
        "format": np.array(FORMAT),
        "variant": np.array(cfg["variant"]),
        "n_layers": np.int32(len(result["weights"])),
        "input_offset": np.int32(cfg["input_offset"]),
        "input_scale": np.float64(cfg["input_scale"]),
        "training": np.array(
            json.dumps(
                {k: result[k] for k in ("config", "scenes", "loss_per_epoch", "samples")},
                sort_keys=True,
            )
        ),
    }
    for i, (w, b) in enumerate(zip(result["weights"], result["biases"])):
        arrays[f"weights_{i}"] = w
        arrays[f"bias_{i}"] = b
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    atomic_write_bytes(path, buf.getvalue())


def load_float_model(path):
    """Read a file written by :func:`save_float_model`: ``(FloatModel, variant, training dict)``.

    Problems (missing, unreadable or unbounded file -- :func:`sim.npz.open_npz` --, a missing
    field, a field of the wrong kind, wrong shapes for the variant) raise :class:`ConfigError`.
    """

    name = os.fspath(path)
    with open_npz(name, "float model", "write it with 'stereosim train'") as archive:
        fmt = archive.scalar("format", "U")
        if fmt != FORMAT:
            raise ConfigError(f"float model {name!r} has format {fmt!r}, expected {FORMAT!r}")
        variant = archive.scalar("variant", "U")
        if variant not in VARIANTS:
            raise ConfigError(f"float model {name!r}: unknown variant {variant!r}")
        weights, biases = [], []
        for i, (c_in, c_out, k) in enumerate(VARIANTS[variant]):
            w, b = archive.field(f"weights_{i}"), archive.field(f"bias_{i}")
            floats = w.dtype.kind == "f" and b.dtype.kind == "f"
            if not floats or w.shape != (c_out, c_in, k, k) or b.shape != (c_out,):
                raise ConfigError(
                    f"float model {name!r}: layer {i} of {variant} must be float "
                    f"({c_out}, {c_in}, {k}, {k}) + ({c_out},), got {w.dtype} {w.shape} + "
                    f"{b.dtype} {b.shape}"
                )
            weights.append(w.astype(np.float64))
            biases.append(b.astype(np.float64))
        text = archive.scalar("training", "U")
        offset, scale = archive.scalar("input_offset", "iu"), archive.scalar("input_scale", "f")
    try:
        training = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as err:
        raise ConfigError(f"float model {name!r}: its training record is not JSON ({err})") from None
    try:
        model = FloatModel(
            weights=tuple(weights), biases=tuple(biases), input_offset=offset, input_scale=scale
        )
    except ConfigError as err:
        raise ConfigError(f"float model {name!r}: {err}") from None
    return model, variant, training


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
