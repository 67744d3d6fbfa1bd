"""Training the learned descriptor: MC-CNN-fast-style siamese networks in torch on the CPU.

Three variants, all with a 9x9 receptive field and 32 output channels (one descriptor bit each):

* ``mccnn4``: four 3x3 convolutions, channels 1, 32, 32, 32, 32 (MC-CNN-fast);
* ``mccnn4-slim``: four 3x3 convolutions, channels 1, 4, 4, 8, 32;
* ``single9x9``: one 9x9 convolution, 1 -> 32 (the network the chip ships).

ReLU between layers, none after the last. Training sees 9x9 patches ('valid' convolutions, one
output per patch); at inference the same weights run on whole images with the chip's replicate
border (:mod:`quant.quantizer` ``float_forward``), identical away from the border.

Samples (MC-CNN's Middlebury recipe): a left pixel p = (x, y) with known, non-occluded ground
truth d; the positive right patch is centred at x - d + U(-pos, pos), the negative one at
x - d +- U(neg_low, neg_high), both interpolated linearly along the row. Each view gets its own
photometric change -- gain, offset and Gaussian noise, then rounding and clipping to 0..255 -- so
the descriptor learns to ignore what differs between two real cameras.

Input normalisation is the NNA's: ``x = (pixel - input_offset) * input_scale`` with two
constants fixed before training (recorded in the output file), nothing per patch.

Loss: hinge ``max(0, margin + s(L, N) - s(L, P))`` on a similarity s. ``cosine`` is MC-CNN's;
``tanh`` is the relaxation of the binary Hamming comparison the chip makes:
``s = mean_c tanh(f_L[c]) tanh(f_R[c])``, which for outputs of large magnitude tends to
``1 - 2 * Hamming(sign f_L, sign f_R) / 32``. ``both`` adds the two losses. With
``aggregate = A > 1`` the patches grow to (8 + A) x (8 + A), each gives an A x A map of
descriptors and the similarity is averaged over the map -- the A x A box filter the SVA applies
to the matching costs, seen by the loss.

The training scenes are Middlebury 2005 (without Art, which is MiddEval3's ArtL) and 2006
ThirdSize; MiddEval3 is the evaluation set and is never read here.

torch is imported only inside the functions that need it: the rest of stereosim does not
depend on it.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from sim.errors import ConfigError, InputError

# (C_in, C_out, K) per layer
VARIANTS = {
    "mccnn4": ((1, 32, 3), (32, 32, 3), (32, 32, 3), (32, 32, 3)),
    "mccnn4-slim": ((1, 4, 3), (4, 4, 3), (4, 8, 3), (8, 32, 3)),
    "single9x9": ((1, 32, 9),),
}
PATCH = 9  # receptive field of every variant
SIMILARITIES = ("cosine", "tanh", "both")
FORMAT = "stereosim-float-v1"
# Training collections under the shared data folder and the scenes left out of them.
TRAIN_COLLECTIONS = ("middlebury2005_third", "middlebury2006_third")
EXCLUDED_SCENES = {"middlebury2005_third": ("Art",)}  # = MiddEval3 ArtL, an evaluation scene
EVALUATION_COLLECTION = "middlebury2014_trainingQ"


@dataclass(frozen=True, slots=True, kw_only=True)
class TrainConfig:
    """Settings of one training run (all recorded in the output file)."""

    variant: str = "single9x9"
    epochs: int = 20
    steps_per_epoch: int = 4000
    batch: int = 256
    lr: float = 0.002
    seed: int = 0
    pos_offset: float = 0.5
    neg_low: float = 1.5
    neg_high: float = 6.0
    margin: float = 0.2
    similarity: str = "tanh"
    aggregate: int = 1
    gain: float = 0.2
    offset: float = 20.0
    noise_max: float = 12.0
    input_offset: int = 128
    input_scale: float = 1.0 / 64.0
    threads: int = 2

    def __post_init__(self):
        if self.variant not in VARIANTS:
            raise ConfigError(
                f"unknown variant {self.variant!r}; choose one of {', '.join(VARIANTS)}"
            )
        if self.similarity not in SIMILARITIES:
            raise ConfigError(
                f"unknown similarity {self.similarity!r}; choose one of {', '.join(SIMILARITIES)}"
            )
        if self.aggregate < 1 or self.aggregate % 2 == 0:
            raise ConfigError(f"aggregate must be odd and >= 1, got {self.aggregate}")
        for name in ("epochs", "steps_per_epoch", "batch", "threads"):
            if getattr(self, name) < 1:
                raise ConfigError(f"{name} must be at least 1, got {getattr(self, name)}")
        if not 0 <= self.pos_offset < self.neg_low <= self.neg_high:
            raise ConfigError(
                "offsets must satisfy 0 <= pos_offset < neg_low <= neg_high, got "
                f"{self.pos_offset}, {self.neg_low}, {self.neg_high}"
            )
        if not 0 <= self.input_offset <= 255 or not self.input_scale > 0:
            raise ConfigError("input_offset must be in 0..255 and input_scale positive")
        if self.lr <= 0 or min(self.margin, self.gain, self.offset, self.noise_max) < 0:
            raise ConfigError("lr must be positive; margin, gain, offset, noise_max non-negative")


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
    if not root.is_dir():
        raise InputError(f"training data folder {root} not found: give --data DIR")
    if root.name == EVALUATION_COLLECTION or (root / "mask0nocc.png").exists():
        raise InputError(f"{root} is MiddEval3, the evaluation set: never train on it")
    dirs = []
    for coll in TRAIN_COLLECTIONS:
        folder = root / coll
        if not folder.is_dir():
            continue
        skip = EXCLUDED_SCENES.get(coll, ())
        dirs.extend(p for p in sorted(folder.iterdir()) if p.is_dir() and p.name not in skip)
    if not dirs:
        raise InputError(
            f"{root} holds no training scenes: expected {' and '.join(TRAIN_COLLECTIONS)} "
            "folders of Middlebury 2005/2006 ThirdSize scenes"
        )
    return dirs


def load_training_set(scene_dirs, cfg: TrainConfig) -> TrainingSet:
    """Read the scenes and list the pixels that can be sampled (module docstring)."""
    from sim.datasets import find_scene, load_scene
    from sim.io import to_grey

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
    out[0] = _photometric(left, cfg, rng)
    # both right patches come from the same right view: one change for the two
    pair = _photometric(np.stack([right_p, right_n]), cfg, rng, shared_axis=True)
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


def _photometric(patches, cfg: TrainConfig, rng, shared_axis: bool = False) -> np.ndarray:
    """gain * (v - 128) + 128 + offset + N(0, sigma), rounded and clipped to 0..255, with gain,
    offset and sigma drawn per sample (shared along axis 0 when ``shared_axis``)."""
    n = patches.shape[1] if shared_axis else patches.shape[0]
    gain = rng.uniform(1.0 - cfg.gain, 1.0 + cfg.gain, n).astype(np.float32)[:, None, None]
    offset = rng.uniform(-cfg.offset, cfg.offset, n).astype(np.float32)[:, None, None]
    sigma = rng.uniform(0.0, cfg.noise_max, n).astype(np.float32)[:, None, None]
    noise = rng.standard_normal(patches.shape).astype(np.float32) * sigma
    v = gain * (patches - 128.0) + 128.0 + offset + noise
    return np.clip(np.rint(v), 0.0, 255.0)


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


# --- the run ------------------------------------------------------------------------------------


def train(cfg: TrainConfig, scene_dirs, *, progress: bool = True) -> dict:
    """Train one network; returns the arrays and metadata :func:`save_float_model` writes."""
    import torch
    from tqdm import tqdm

    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    torch.use_deterministic_algorithms(True)
    rng = np.random.default_rng(cfg.seed)
    ts = load_training_set(scene_dirs, cfg)
    if ts.scene.size == 0:
        raise InputError("the training scenes have no pixel with usable ground truth")
    net = build_network(cfg.variant)
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr)
    total = cfg.epochs * cfg.steps_per_epoch
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda step: 1.0 - step / total)
    history = []
    bar = tqdm(total=total, desc=f"train {cfg.variant}", unit="step", disable=not progress)
    try:
        for epoch in range(cfg.epochs):
            running = 0.0
            for _ in range(cfg.steps_per_epoch):
                batch = sample_batch(ts, cfg, rng)
                x = (torch.from_numpy(batch) - float(cfg.input_offset)) * cfg.input_scale
                f = net(x.reshape(3 * cfg.batch, 1, *batch.shape[2:]))
                if cfg.aggregate == 1:
                    f = f.reshape(3, cfg.batch, -1)
                else:
                    f = f.reshape(3, cfg.batch, *f.shape[1:])
                loss = hinge_loss(f[0], f[1], f[2], cfg)
                opt.zero_grad()
                loss.backward()
                opt.step()
                sched.step()
                running += loss.item()
                bar.update(1)
                bar.set_postfix(epoch=epoch + 1, loss=f"{loss.item():.4f}")
            history.append(running / cfg.steps_per_epoch)
    finally:
        bar.close()
    convs = [m for m in net if isinstance(m, torch.nn.Conv2d)]
    return {
        "weights": [c.weight.detach().numpy().astype(np.float32) for c in convs],
        "biases": [c.bias.detach().numpy().astype(np.float32) for c in convs],
        "config": asdict(cfg),
        "scenes": list(ts.names),
        "loss_per_epoch": history,
        "samples": int(ts.scene.size),
    }


def save_float_model(path, result: dict) -> None:
    """Write a trained float model as .npz, atomically (format ``stereosim-float-v1``)."""
    import io

    from sim.io import atomic_write_bytes

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

    Problems (missing file or field, wrong shapes for the variant) raise :class:`ConfigError`.
    """
    from nna.weights import open_npz
    from quant.quantizer import FloatModel

    name = os.fspath(path)
    archive = open_npz(name, "float model", "write it with 'stereosim train'")
    with archive:

        def get(key):
            if key not in archive.files:
                raise ConfigError(f"float model {name!r} lacks the field {key!r}")
            return archive[key]

        fmt = str(get("format")[()])
        if fmt != FORMAT:
            raise ConfigError(f"float model {name!r} has format {fmt!r}, expected {FORMAT!r}")
        variant = str(get("variant")[()])
        if variant not in VARIANTS:
            raise ConfigError(f"float model {name!r}: unknown variant {variant!r}")
        spec = VARIANTS[variant]
        weights, biases = [], []
        for i, (c_in, c_out, k) in enumerate(spec):
            w, b = get(f"weights_{i}"), get(f"bias_{i}")
            if w.shape != (c_out, c_in, k, k) or b.shape != (c_out,):
                raise ConfigError(
                    f"float model {name!r}: layer {i} of {variant} must be "
                    f"({c_out}, {c_in}, {k}, {k}) + ({c_out},), got {w.shape} + {b.shape}"
                )
            weights.append(w.astype(np.float64))
            biases.append(b.astype(np.float64))
        training = json.loads(str(get("training")[()]))
        model = FloatModel(
            weights=tuple(weights),
            biases=tuple(biases),
            input_offset=int(get("input_offset")[()]),
            input_scale=float(get("input_scale")[()]),
        )
    return model, variant, training


def calibration_scene_dirs(path) -> list[Path]:
    """Scene folders for quantizer calibration: ``path`` may be the shared data folder (its
    training scenes), a collection of scenes or one scene. MiddEval3 is refused: it is the
    evaluation set and must not tune anything."""
    from sim.datasets import find_scenes

    root = Path(path)
    if not root.is_dir():
        raise InputError(f"calibration folder {root} not found: give --calib DIR")
    if any((root / coll).is_dir() for coll in TRAIN_COLLECTIONS):
        return training_scene_dirs(root)
    if root.name == EVALUATION_COLLECTION or root.parent.name == EVALUATION_COLLECTION:
        raise InputError(f"{root} is MiddEval3, the evaluation set: calibrate on training scenes")
    scenes = [Path(s.left).parent for s in find_scenes(root)]
    if any((s / "mask0nocc.png").exists() for s in scenes):
        raise InputError(f"{root} is MiddEval3, the evaluation set: calibrate on training scenes")
    return scenes


def calibration_images(scene_dirs, limit: int) -> tuple[list[np.ndarray], list[str]]:
    """Left and right grey views of up to ``limit`` scenes spread evenly over ``scene_dirs``."""
    from sim.datasets import find_scene
    from sim.io import read_image, to_grey

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
