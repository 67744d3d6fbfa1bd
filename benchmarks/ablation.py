"""The paper's descriptor ablation on MiddEval3 trainingQ (docs/ablation.md).

Every row goes through the same SVA back end (box filter, SGM, WTA, sub-pixel, LR check, median)
with the same settings; only the descriptor and its matching cost change:

* ``census``: the 32-bit census at its own tuned P1/P2 (``nna.descriptor = census``);
* for each variant of ``nna.training.trainconfig.VARIANTS`` whose float and int8 files are in the
models
  folder (or those ``--variants`` names), at the CNN's tuned P1/P2:
  ``float cosine`` (the float network's outputs compared by cosine, cost on the Hamming scale,
  :func:`sva.hamming.cost.cosine_cost`), ``float sign`` (signs of the float outputs, Hamming) and
  ``int8 sign`` (signs of the integer network's accumulators, Hamming -- what the chip runs).

Metrics: mean over the 15 scenes of bad2 / invalid / totbad / avgerr on the nonocc mask, in
quarter-resolution pixels (sim.metrics), D from each calib.txt. With ``--noise SIGMA`` each view
gets independent Gaussian noise N(0, SIGMA^2), rounded and clipped to 0..255, from
``np.random.default_rng([seed, scene index, view])``. Also reported: the fraction of int8
descriptor bits equal to the float signs, and the architecture figures per 720p frame.

    python benchmarks/ablation.py [--data DIR] [--models DIR] [--noise SIGMA] [--seed S]
                                  [--scenes N] [--write docs/ablation.md] [--json FILE] [--quiet]

On a terminal a progress bar on stderr counts every (configuration, scene) pair, with its ETA.

``--write`` replaces the generated table between the markers of docs/ablation.md (the clean or
the noisy one) and leaves the discussion around it alone.
"""

from __future__ import annotations

import argparse
import fcntl
import json
import re
import sys
import time
from pathlib import Path

import numpy as np

from stereosim.core.config import load_config
from stereosim.core.datasets import find_scenes, legal_disparities, load_scene, shared_data_dir
from stereosim.core.errors import UserError
from stereosim.core.io import to_grey
from stereosim.core.outputs import atomic_write_bytes
from stereosim.core.progress import progress_bar
from stereosim.nna.census_unit.census import census
from stereosim.nna.training.floatmodel import load_float_model
from stereosim.nna.training.trainconfig import VARIANTS
from stereosim.quant.artifact import load_quantized
from stereosim.quant.intconv import int_forward
from stereosim.quant.quantizer import float_forward
from stereosim.sim.metrics import evaluate
from stereosim.sva.hamming.cost import cosine_cost
from stereosim.sva.pipeline.pipeline import sva_cost_volume, sva_stream
from stereosim.sva.wta.wta import to_float

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "benchmarks" / "models"
KINDS = ("float cosine", "float sign", "int8 sign")
KEYS = ("bad2", "invalid", "totbad", "avgerr")
FRAME_720P = 1280 * 720
PAPER = {
    "mccnn4": {"bad2": 16.226, "invalid": 10.95, "totbad": 27.178, "avgerr": 3.819},
    "single9x9": {"bad2": 17.39, "invalid": 11.50, "totbad": 28.89, "avgerr": 4.202},
}


def model_paths(models_dir: Path, variant: str) -> tuple[Path, Path]:
    """(float model, quantized artifact) of a variant; single9x9's artifact is the shipped one."""
    quant = models_dir / f"{variant}.int8.npz"
    if variant == "single9x9" and not quant.exists():
        quant = ROOT / "nna" / "conv" / "single9x9.npz"
    return models_dir / f"{variant}.float.npz", quant


def variants_with_files(models_dir: Path) -> list[str]:
    """The variants, in ``VARIANTS`` order, whose float model and int8 artifact are both in
    ``models_dir`` (the study's networks; the other variants were not trained or not kept)."""
    return [v for v in VARIANTS if all(p.is_file() for p in model_paths(models_dir, v))]


def pack_signs(values) -> np.ndarray:
    """Descriptor words (H, W) uint32 from (H, W, C <= 32) outputs: bit c = value[c] > 0."""
    bits = values.shape[2]
    weights = np.uint64(1) << np.arange(bits, dtype=np.uint64)
    words = ((values > 0).astype(np.uint64) * weights).sum(axis=2, dtype=np.uint64)
    return words.astype(np.uint32)


def add_noise(img, sigma: float, seed: int, scene: int, view: int) -> np.ndarray:
    if sigma <= 0:
        return img
    rng = np.random.default_rng([seed, scene, view])
    noisy = img.astype(np.float64) + rng.normal(0.0, sigma, img.shape)
    return np.clip(np.rint(noisy), 0, 255).astype(np.uint8)


def architecture(variant: str) -> dict:
    """MACs per pixel, weight count and bytes, feature-map and descriptor bytes per 720p frame
    (one camera), computed from the layer shapes."""
    if variant == "census":
        return {"macs": 0, "weights": 0, "biases": 0, "weight_bytes": 0, "fmap_bytes": 0,
                "desc_binary": FRAME_720P * 32 // 8, "desc_float": None}
    spec = VARIANTS[variant]
    macs = sum(k * k * c_in * c_out for c_in, c_out, k in spec)
    n_bias = sum(c_out for _, c_out, _ in spec)
    hidden = sum(c_out for _, c_out, _ in spec[:-1])
    c_last = spec[-1][1]
    return {
        "macs": macs,
        "weights": macs,
        "biases": n_bias,
        "weight_bytes": macs + 4 * n_bias,  # int8 weights + int32 biases
        "fmap_bytes": hidden * FRAME_720P,  # int8 hidden activations (none for one layer)
        "desc_binary": FRAME_720P * c_last // 8,
        "desc_float": FRAME_720P * c_last * 4,
    }


def rows_per_scene(models) -> int:
    """Table rows computed per scene: census, then three per network variant."""
    return 1 + len(KINDS) * len(models)


def evaluate_scene(data, index, args, models, done=lambda name: None):
    """Metrics (nonocc) of every row on one scene, plus the int8/float bit agreement;
    ``done(row name)`` is called as each row is scored (for the progress bar)."""
    left = add_noise(to_grey(data["left"]), args.noise, args.seed, index, 0)
    right = add_noise(to_grey(data["right"]), args.noise, args.seed, index, 1)
    dn = legal_disparities(data["ndisp"])
    out, agree = {}, {}

    def score(q, cfg):
        disp = to_float(q, cfg.subpixel_bits)
        return evaluate(disp, data["gt"], data["masks"])["nonocc"]

    ccfg = load_config(None, {"nna.descriptor": "census", "sva.disparities": dn})
    c = ccfg.nna.census
    dl, dr = census(left, c.window, c.kind, c.stride), census(right, c.window, c.kind, c.stride)
    out["census"] = score(sva_stream(dl, dr, left, ccfg.sva, 32), ccfg.sva)
    done("census")
    cfg = load_config(None, {"nna.descriptor": "cnn", "sva.disparities": dn}).sva
    for variant, (fmodel, qm) in models.items():
        fl, fr = float_forward(fmodel, left), float_forward(fmodel, right)
        bits = fl.shape[2]
        out[(variant, "float cosine")] = score(
            sva_cost_volume(cosine_cost(fl, fr, dn, bits), left, cfg), cfg
        )
        done(f"{variant} float cosine")
        out[(variant, "float sign")] = score(
            sva_stream(pack_signs(fl), pack_signs(fr), left, cfg, bits), cfg
        )
        done(f"{variant} float sign")
        args_int = (qm.weights, qm.biases, qm.mult, qm.shift, qm.input_offset, qm.z_bits)
        al, ar = int_forward(left, *args_int), int_forward(right, *args_int)
        out[(variant, "int8 sign")] = score(
            sva_stream(pack_signs(al), pack_signs(ar), left, cfg, bits), cfg
        )
        done(f"{variant} int8 sign")
        same = np.count_nonzero((al > 0) == (fl > 0)) + np.count_nonzero((ar > 0) == (fr > 0))
        agree[variant] = (same, al.size + ar.size)
    return out, agree


def mean_rows(per_scene):
    rows = {}
    for key in per_scene[0]:
        rows[key] = {k: float(np.mean([s[key][k] for s in per_scene])) for k in KEYS}
    return rows


def sgm_text(sva) -> str:
    """A descriptor's SGM settings as the table headers state them."""
    adaptive = f", adaptive P2 slope {sva.p2_slope}" if sva.p2_adaptive else ""
    return f"P1/P2 = {sva.p1}/{sva.p2}{adaptive}, box {sva.box_size}"


def format_tables(rows, agree, models, args, n_scenes) -> str:
    cnn = load_config(None, {"nna.descriptor": "cnn"}).sva
    cen = load_config(None, {"nna.descriptor": "census"}).sva
    noise = "clean images"
    if args.noise:
        noise = f"Gaussian noise sigma = {args.noise:g} per view (seed {args.seed})"
    lines = [
        f"MiddEval3 trainingQ, {n_scenes} scenes, nonocc, quarter-resolution pixels, {noise}; "
        f"census at {sgm_text(cen)}, every network row at the CNN's {sgm_text(cnn)} (each "
        f"descriptor's defaults, docs/tuning.md); LR threshold {cnn.lr_max_diff}, median "
        f"{cnn.median}; generated by `python benchmarks/ablation.py"
        f"{f' --noise {args.noise:g} --seed {args.seed}' if args.noise else ''}"
        f"{f' --scenes {args.scenes}' if args.scenes else ''} --write docs/ablation.md`.",
        "",
        "| descriptor | cost | bad2 % | invalid % | totbad % | avgerr px "
        "| int8 bits = float signs |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    m = rows["census"]
    lines.append(
        f"| census 11x3 (32 bit) | Hamming | {m['bad2']:.2f} | {m['invalid']:.2f} | "
        f"{m['totbad']:.2f} | {m['avgerr']:.3f} | |"
    )
    for variant in models:
        same, total = agree[variant]
        for kind in KINDS:
            m = rows[(variant, kind)]
            cost = "cosine" if kind == "float cosine" else "Hamming"
            extra = f"{100 * same / total:.3f} %" if kind == "int8 sign" else ""
            lines.append(
                f"| {variant} {kind} | {cost} | {m['bad2']:.2f} | {m['invalid']:.2f} | "
                f"{m['totbad']:.2f} | {m['avgerr']:.3f} | {extra} |"
            )
    for variant, ref in PAPER.items():
        lines.append(
            f"| paper: {variant} (their SGM) | float | {ref['bad2']:.2f} | {ref['invalid']:.2f} | "
            f"{ref['totbad']:.2f} | {ref['avgerr']:.3f} | |"
        )
    return "\n".join(lines) + "\n"


def format_architecture() -> str:
    lines = [
        "| descriptor | MACs / pixel | G MAC / 720p frame | weights + biases "
        "| weight bytes (int8 + int32 bias) "
        "| hidden feature maps / 720p frame | descriptor / 720p frame: binary | float32 |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for name in ("census", *VARIANTS):
        a = architecture(name)
        flt = f"{a['desc_float'] / 1e6:.1f} MB" if a["desc_float"] else "-"
        lines.append(
            f"| {name} | {a['macs']:,} | {a['macs'] * FRAME_720P / 1e9:.2f} | "
            f"{a['weights']:,} + {a['biases']} | "
            f"{a['weight_bytes']:,} | {a['fmap_bytes'] / 1e6:.1f} MB | "
            f"{a['desc_binary'] / 1e6:.2f} MB | {flt} |"
        )
    return "\n".join(lines) + "\n"


def write_section(doc: Path, marker: str, text: str) -> None:
    """Replace the text between ``<!-- marker:begin -->`` and ``<!-- marker:end -->`` (under a
    lock, so a clean and a noisy run finishing together do not lose each other's table)."""
    pattern = re.compile(
        rf"(<!-- {re.escape(marker)}:begin -->\n).*?(<!-- {re.escape(marker)}:end -->)", re.S
    )
    with open(doc.with_name(f".{doc.name}.lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        src = doc.read_text()
        if not pattern.search(src):
            sys.exit(f"ablation: {doc} has no '<!-- {marker}:begin/end -->' markers")
        new = pattern.sub(lambda mm: mm.group(1) + text + mm.group(2), src)
        atomic_write_bytes(doc, new.encode())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", help="MiddEval3 trainingQ folder (default: shared data)")
    ap.add_argument("--models", default=str(MODELS), help="folder of VARIANT.float.npz and "
                    "VARIANT.int8.npz (default: benchmarks/models)")
    ap.add_argument("--variants", help="comma-separated subset (default: every variant whose "
                    "float and int8 files are both in --models)")
    ap.add_argument("--noise", type=float, default=0.0, metavar="SIGMA")
    ap.add_argument("--seed", type=int, default=0, metavar="S")
    ap.add_argument("--scenes", type=int, default=0, metavar="N", help="only the first N scenes")
    ap.add_argument("--write", metavar="DOC", help="put the tables into this markdown file")
    ap.add_argument("--json", metavar="FILE", help="also write per-scene figures as JSON")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    args = ap.parse_args(argv)
    data_dir = args.data or (
        shared_data_dir() / "middlebury2014_trainingQ" if shared_data_dir() else None
    )
    if data_dir is None:
        sys.exit("ablation: no data; pass --data pointing at MiddEval3 trainingQ")
    models = {}
    if args.variants is None:
        present = variants_with_files(Path(args.models))
        if not present:
            sys.exit(f"ablation: no VARIANT.float.npz with VARIANT.int8.npz in {args.models}")
        args.variants = ",".join(present)
    for variant in args.variants.split(","):
        if variant not in VARIANTS:
            sys.exit(f"ablation: unknown variant {variant!r}; choose from {', '.join(VARIANTS)}")
        fpath, qpath = model_paths(Path(args.models), variant)
        try:
            fmodel, v, _ = load_float_model(fpath)
            qm = load_quantized(qpath)
        except UserError as err:
            sys.exit(f"ablation: {err}")
        if v != variant or qm.variant != variant:
            sys.exit(f"ablation: {fpath} / {qpath} hold {v} / {qm.variant}, not {variant}")
        models[variant] = (fmodel, qm)
    scenes = find_scenes(data_dir)
    if args.scenes:
        scenes = scenes[: args.scenes]
    t0 = time.perf_counter()
    per_scene, agree = [], {v: (0, 0) for v in models}
    # one step per (configuration, scene): the ETA counts every row of every scene
    bar = progress_bar(len(scenes) * rows_per_scene(models), "ablation", "row",
                       quiet=args.quiet)
    with bar:
        for i, sc in enumerate(scenes):

            def done(name, scene=sc.name):
                bar.set_postfix_str(f"{scene}: {name}", refresh=False)
                bar.update(1)

            res, ag = evaluate_scene(load_scene(sc), i, args, models, done)
            per_scene.append(res)
            for v, (same, total) in ag.items():
                agree[v] = (agree[v][0] + same, agree[v][1] + total)
            bar.write(f"{sc.name}: census totbad {res['census']['totbad']:.2f}, " + ", ".join(
                f"{v} int8 {res[(v, 'int8 sign')]['totbad']:.2f}" for v in models
            ), file=sys.stderr)
    seconds = time.perf_counter() - t0
    rows = mean_rows(per_scene)
    table = format_tables(rows, agree, models, args, len(scenes))
    print(f"{len(scenes)} scenes in {seconds:.0f} s", file=sys.stderr)
    print(table)
    print(format_architecture())
    if args.json:
        dump = {
            "noise": args.noise, "seed": args.seed,
            "scenes": [sc.name for sc in scenes],
            "mean": {k if isinstance(k, str) else " / ".join(k): v for k, v in rows.items()},
            "bit_agreement": {v: s / t for v, (s, t) in agree.items()},
            "per_scene": [
                {k if isinstance(k, str) else " / ".join(k): v for k, v in r.items()}
                for r in per_scene
            ],
        }
        atomic_write_bytes(args.json, (json.dumps(dump, indent=1, sort_keys=True) + "\n").encode())
    if args.write:
        write_section(Path(args.write), "ablation-noise" if args.noise else "ablation-clean", table)
        write_section(Path(args.write), "ablation-architecture", format_architecture())


if __name__ == "__main__":
    main()
