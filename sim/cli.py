"""The ``stereosim`` command line.

Every user mistake ends in one line on stderr (``stereosim: error: ...``) and exit status 2,
never a traceback; outputs are written only after the whole frame has been computed, each file
atomically, so a failed run leaves nothing half-written.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from nna.train import (
    TrainConfig,
    calibration_images,
    calibration_scene_dirs,
    load_float_model,
    save_float_model,
    train,
    training_scene_dirs,
)
from quant.artifact import save_quantized
from quant.quantizer import QuantizerConfig, quantize
from sim import whatif_cli
from sim.api import run
from sim.config import config_diff, config_to_toml, load_config, parse_set_options
from sim.cycle.estimate import parse_size
from sim.cycle.plan import build_plan
from sim.datasets import (
    default_scene,
    find_scene,
    find_scenes,
    legal_disparities,
    load_scene,
    shared_data_dir,
)
from sim.diagram import plan_text, write_plan_png
from sim.errors import ConfigError, InputError, UserError
from sim.outputs import atomic_write_bytes
from sim.io import (
    disparity_to_colour,
    encode_png,
    pfm_bytes,
    read_gt,
    read_image,
    read_mask,
)
from sim.metrics import format_table, mean_metrics
from sim.tracing import TraceRequest, check_size, parse_window, write_traces
from traces.cli import add_wave_parser

EVAL_KEYS = ("bad0.5", "bad1", "bad2", "bad4", "invalid", "totbad", "avgerr", "rms")


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage mistake is one line and exit status 2 like every other error."""

    def error(self, message):
        raise UserError(f"{message} (see '{self.prog} --help')")


def _add_config_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", metavar="FILE", help="TOML configuration file")
    p.add_argument(
        "--set", metavar="KEY=VALUE", action="append", default=[],
        help="override one configuration key, e.g. --set sva.p1=10 (repeatable)",
    )
    p.add_argument("--disparities", type=int, metavar="N", help="disparity range D (sva.disparities)")
    p.add_argument(
        "--descriptor", choices=("census", "cnn"), help="per-pixel descriptor (nna.descriptor)"
    )


def _overrides(args) -> dict:
    over = parse_set_options(args.set)
    if args.disparities is not None:
        over["sva.disparities"] = args.disparities
    if args.descriptor is not None:
        over["nna.descriptor"] = args.descriptor
    return over


def _user_set_disparities(args, over: dict) -> bool:
    """Did the user choose D (flag, --set or config file)? Then a scene's calib.txt does not."""
    if "sva.disparities" in over:
        return True
    if args.config:
        import tomllib

        try:
            tree = tomllib.loads(Path(args.config).read_text())
        except (OSError, ValueError):
            return False  # load_config reports the problem
        return "disparities" in tree.get("sva", {})
    return False


def _scene_config(args, ndisp: int | None):
    over = _overrides(args)
    if ndisp is not None and not _user_set_disparities(args, over):
        over["sva.disparities"] = legal_disparities(ndisp)
    return load_config(args.config, over)


# ----------------------------------------------------------------------------------------------
# stereosim run


def _load_run_inputs(args) -> dict:
    """The stereo pair (+ GT and masks) from a scene folder, --left/--right, or the default."""

    if args.scene and (args.left or args.right):
        raise InputError("give either a scene folder or --left/--right, not both")
    if bool(args.left) != bool(args.right):
        raise InputError("give both --left and --right (or neither, for the default scene)")
    if args.scene:
        data = load_scene(find_scene(args.scene, gt_scale=args.gt_scale))
        data["source"] = str(args.scene)
    elif args.left:
        data = {
            "name": Path(args.left).parent.name or Path(args.left).stem,
            "left": read_image(args.left),
            "right": read_image(args.right),
            "gt": None,
            "masks": {},
            "ndisp": None,
            "source": f"{args.left} + {args.right}",
        }
    else:
        data = default_scene()
        data["source"] = "embedded default scene (scikit-image stereo_motorcycle)"
    if args.gt:
        data["gt"] = read_gt(args.gt, args.gt_scale)
        data["masks"] = {}
    if args.mask:
        if data.get("gt") is None:
            raise InputError("--mask needs ground truth: give --gt too")
        mask = read_mask(args.mask)
        if mask.shape != data["gt"].shape:
            raise InputError(
                f"mask {args.mask} is {mask.shape[1]}x{mask.shape[0]} but the GT is "
                f"{data['gt'].shape[1]}x{data['gt'].shape[0]}"
            )
        data["masks"] = {"nonocc": mask == 255, "all": np.isfinite(data["gt"])}
    gt = data.get("gt")
    if gt is not None:
        h, w = data["left"].shape[:2]
        if gt.shape != (h, w):
            raise InputError(
                f"the GT is {gt.shape[1]}x{gt.shape[0]} but the images are {w}x{h}: "
                f"give the GT of this pair"
            )
        if not data.get("masks"):
            data["masks"] = {"all": np.isfinite(gt)}
    return data


def _write_outputs(out_dir: Path, result, dmax: float) -> None:
    # Encode everything first, then write: a failure leaves no partial set of outputs.
    blobs = {
        "disparity.pfm": pfm_bytes(result.disparity),
        "disparity.png": encode_png(disparity_to_colour(result.disparity, dmax)),
        "report.json": (json.dumps(result.report, indent=2, sort_keys=True) + "\n").encode(),
    }
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the output folder {out_dir}: {exc.strerror}") from None
    for name, data in blobs.items():
        atomic_write_bytes(out_dir / name, data)


def _summary(report: dict, seconds: float) -> str:
    img = report["image"]
    lines = [
        f"stereosim {report['mode']}: {img['width']}x{img['height']}, "
        f"D={report['config']['sva']['disparities']}, descriptor {report['descriptor']['kind']} "
        f"({report['descriptor']['bits']} bits), {report['config']['sva']['paths']} SGM paths, "
        f"{seconds:.2f} s wall",
        f"valid pixels: {100 - report['output']['invalid_percent']:.2f}%",
    ]
    if "throughput" in report:
        thr, lat = report["throughput"], report["latency"]
        lines.append(
            f"cycles: {report['cycles']['total']}; first output {lat['first_output_ns'] / 1e3:.1f} us, "
            f"frame {lat['frame_ns'] / 1e6:.3f} ms; {thr['fps']} fps, bottleneck {thr['bottleneck']}"
        )
        if thr.get("fps_frame") and thr["fps"] and thr["fps_frame"] < 0.9 * thr["fps"]:
            lines.append(
                f"note: one frame at a time runs at {thr['fps_frame']} fps, far below the "
                f"{thr['fps']} fps the busiest block's work allows: blocks wait on each other "
                "(see blocks.*.blocked in report.json)"
            )
    for mask, m in report.get("metrics", {}).items():
        lines.append(
            f"{mask:>7}: bad2 {m['bad2']:.2f}%  invalid {m['invalid']:.2f}%  "
            f"totbad {m['totbad']:.2f}%  avgerr {m['avgerr']:.3f}  rms {m['rms']:.3f}"
        )
    return "\n".join(lines)


def cmd_run(args) -> int:
    request = _trace_request(args)
    data = _load_run_inputs(args)
    cfg = _scene_config(args, data.get("ndisp"))
    t0 = time.perf_counter()
    result = run(data["left"], data["right"], mode=args.mode, config=cfg,
                 gt=data.get("gt"), masks=data.get("masks"), trace=request)
    seconds = time.perf_counter() - t0
    result.report["scene"] = {"name": data["name"], "source": data["source"]}
    traced = []
    if request is not None:
        check_size(result.trace, request)  # refuse before anything is written
    out_dir = Path(args.out)
    _write_outputs(out_dir, result, float(cfg.sva.disparities))
    if request is not None:
        traced = write_traces(result.trace, request, size_checked=True)
    if args.json:
        print(json.dumps(result.report, indent=2, sort_keys=True))
    else:
        print(_summary(result.report, seconds))
        print(f"wrote {out_dir}/disparity.pfm, disparity.png, report.json")
        if traced:
            print(f"wrote {', '.join(traced)} ({result.trace.n_changes} value changes)")
    return 0


def _trace_request(args):
    """The TraceRequest of run's trace options, or None without --vcd/--timeline."""

    if not (args.vcd or args.timeline):
        if args.trace_window or args.trace or args.force:
            raise ConfigError("--trace-window, --trace and --force need --vcd FILE or --timeline "
                              "FILE")
        return None
    if args.mode != "cycle":
        raise ConfigError("traces need the cycle model: drop --mode functional")
    parse_window(args.trace_window)  # bad windows fail before the run
    if args.trace_limit <= 0:
        raise ConfigError(f"--trace-limit must be > 0 MB, got {args.trace_limit:g}")
    patterns = tuple(p for item in args.trace for p in item.split(",") if p)
    return TraceRequest(window=args.trace_window, patterns=patterns, vcd=args.vcd,
                        timeline=args.timeline, force=args.force, limit_mb=args.trace_limit)


# ----------------------------------------------------------------------------------------------
# stereosim eval


def cmd_eval(args) -> int:
    from tqdm import tqdm


    scenes = find_scenes(args.dataset, gt_scale=args.gt_scale)
    rows = []
    results = []
    for scene in tqdm(scenes, desc="eval", unit="scene", disable=args.json or None, file=sys.stderr):
        data = load_scene(scene)
        cfg = _scene_config(args, data.get("ndisp"))
        res = run(data["left"], data["right"], mode=args.mode, config=cfg,
                  gt=data["gt"], masks=data["masks"])
        results.append(res.report["metrics"])
        rows.append((scene.name, res.report["metrics"], cfg.sva.disparities))
    mean = mean_metrics(results)
    if args.json:
        out = {
            "dataset": str(args.dataset),
            "scenes": {name: {"disparities": d, "metrics": m} for name, m, d in rows},
            "mean": mean,
        }
        print(json.dumps(out, indent=2, sort_keys=True))
        return 0
    for mask in ("nonocc", "all"):
        table_rows = [(name, m[mask]) for name, m, _ in rows if mask in m]
        if table_rows:
            print(f"\n[{mask}]  (thresholds in pixels of the GT's resolution)")
            print(format_table(table_rows, EVAL_KEYS))
    return 0


# ----------------------------------------------------------------------------------------------
# stereosim config


def cmd_config_show(args) -> int:
    cfg = load_config(args.config, _overrides(args))
    sys.stdout.write(config_to_toml(cfg, comments=not args.plain))
    return 0


def cmd_config_plan(args) -> int:
    plan = build_plan(load_config(args.config, _overrides(args)), parse_size(args.size))
    if args.png:
        write_plan_png(plan, args.png)
    sys.stdout.write(plan_text(plan))
    return 0


def cmd_config_diff(args) -> int:
    diff = config_diff(load_config(args.a), load_config(args.b))
    if not diff:
        print("no differences")
    for key, (va, vb) in sorted(diff.items()):
        print(f"{key}: {va!r} -> {vb!r}")
    return 0


# ----------------------------------------------------------------------------------------------
# stereosim train / quantize


def _import_torch():
    try:
        import torch  # noqa: F401
    except ImportError:
        raise UserError(
            "training needs torch, which is not installed: pip install 'stereosim[train]'"
        ) from None


def cmd_train(args) -> int:
    # options left unset keep TrainConfig's defaults (the shipped recipe)
    given = {
        "variant": args.variant, "objective": args.objective, "epochs": args.epochs,
        "steps_per_epoch": args.steps, "batch": args.batch, "strips": args.strips,
        "lr": args.lr, "seed": args.seed, "similarity": args.similarity,
        "noise_max": args.noise_max, "aggregate": args.aggregate, "threads": args.threads,
    }
    cfg = TrainConfig(**{k: v for k, v in given.items() if v is not None})
    data = args.data or shared_data_dir()
    if data is None:
        raise InputError("no training data found: give --data DIR (the shared Middlebury folder)")
    dirs = training_scene_dirs(data)
    out = Path(args.out or f"{args.variant}.npz")
    if not out.parent.is_dir():
        raise InputError(f"output folder {out.parent} does not exist: create it first")
    _import_torch()
    t0 = time.perf_counter()
    result = train(cfg, dirs, progress=not args.quiet)
    save_float_model(out, result)
    print(
        f"trained {args.variant} on {len(result['scenes'])} scenes ({result['samples']} pixels) in "
        f"{time.perf_counter() - t0:.0f} s; final loss {result['loss_per_epoch'][-1]:.4f}; "
        f"wrote {out}"
    )
    return 0


def cmd_quantize(args) -> int:
    model, variant, _ = load_float_model(args.model)
    qcfg = QuantizerConfig(
        n_steps=args.steps, z_bits=args.z_bits, n_samples=args.samples, seed=args.seed,
        distance=args.distance, hidden_distance=args.hidden_distance,
        act_quantile=args.act_quantile,
    )
    out = Path(args.out)
    if not out.parent.is_dir():
        raise InputError(f"output folder {out.parent} does not exist: create it first")
    images, names = calibration_images(calibration_scene_dirs(args.calib), args.calib_scenes)
    calibration = (
        f"{len(images)} views (left+right) of {', '.join(names)}; {qcfg.n_samples} sampled "
        f"pixels, seed {qcfg.seed}, {qcfg.n_steps} scale steps, z={qcfg.z_bits}, "
        f"distance {qcfg.distance}"
        + (
            f", hidden layers: distance {qcfg.hidden_distance}, activation quantile "
            f"{qcfg.act_quantile}"
            if len(model.weights) > 1
            else ""
        )
    )
    t0 = time.perf_counter()
    qm = quantize(model, images, qcfg, variant=variant, calibration=calibration)
    save_quantized(out, qm)
    print(
        f"quantized {variant} ({qm.n_layers} layer(s)) on {len(images)} calibration views in "
        f"{time.perf_counter() - t0:.0f} s: {100 * qm.sign_agreement:.3f}% of descriptor bits "
        f"agree with the float signs, accumulator RMS error {qm.acc_rms:.2f}; wrote {out}"
    )
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="stereosim", description="Simulator of an edge stereo-vision SoC.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    r = sub.add_parser("run", help="simulate one stereo frame")
    r.add_argument("scene", nargs="?", help="a Middlebury scene folder (im0/im1/disp0GT/...)")
    r.add_argument("--left", help="left image (PNG etc.; RGB is converted to grey)")
    r.add_argument("--right", help="right image")
    r.add_argument("--gt", help="ground-truth disparity (.pfm, or .png with --gt-scale)")
    r.add_argument("--gt-scale", type=float, help="GT PNG value per pixel of disparity")
    r.add_argument("--mask", help="evaluation mask PNG (255 = non-occluded)")
    r.add_argument("--mode", default="cycle", choices=("functional", "cycle"),
                   help="cycle (default: the clocked chip, same disparities plus cycle counts) or "
                   "functional (the bit-exact model alone, faster)")
    r.add_argument("--out", default="out", help="output folder (default: out)")
    r.add_argument("--json", action="store_true", help="print the report as JSON")
    t = r.add_argument_group("traces (cycle model; see docs/traces.md)")
    t.add_argument("--vcd", help="write a VCD waveform of the trace window (and a .gtkw next to it)")
    t.add_argument("--timeline", help="write a Chrome/Perfetto trace-event JSON of the window")
    t.add_argument("--trace-window", metavar="A:B",
                   help="SVA cycles A:B, or nna:A:B / sva:A:B / camera:A:B, or rows:A:B "
                   "(default: the whole frame)")
    t.add_argument("--trace", action="append", default=[], metavar="PATTERNS",
                   help="keep signals matching these glob patterns (comma-separated, "
                   "repeatable), e.g. 'top.sva.*,top.fifo.*.occupancy'")
    t.add_argument("--trace-limit", type=float, default=500.0, metavar="MB",
                   help="refuse a VCD larger than this (default 500 MB) unless --force")
    t.add_argument("--force", action="store_true", help="write the VCD whatever its size")
    _add_config_options(r)
    r.set_defaults(func=cmd_run)

    e = sub.add_parser("eval", help="run and score every scene of a Middlebury-layout folder")
    e.add_argument("dataset", help="folder of scenes (e.g. ../shared/data/middlebury2014_trainingQ)")
    e.add_argument("--gt-scale", type=float, help="GT PNG scale for non-standard sizes")
    e.add_argument("--mode", default="functional", choices=("functional", "cycle"))
    e.add_argument("--json", action="store_true", help="print per-scene and mean metrics as JSON")
    _add_config_options(e)
    e.set_defaults(func=cmd_eval)

    t = sub.add_parser("train", help="train a siamese descriptor network (needs torch)")
    t.add_argument("--variant", default="single9x9", choices=("mccnn4", "mccnn4-slim", "single9x9"))
    t.add_argument("--data", metavar="DIR", help="shared data folder holding "
                   "middlebury2005_third/ and middlebury2006_third/ (default: ../shared/data)")
    t.add_argument("--objective", choices=("curve", "triplet"), help="curve (default): "
                   "softmax over the box-filtered cost of every candidate disparity of strips of "
                   "pixels; triplet: MC-CNN's hinge on one positive and one negative patch")
    t.add_argument("--epochs", type=int, metavar="N", help="default 20")
    t.add_argument("--steps", type=int, metavar="N", help="batches per epoch (default 1000)")
    t.add_argument("--strips", type=int, metavar="N", help="strips per batch, curve (default 32)")
    t.add_argument("--batch", type=int, metavar="N", help="triplets per batch, triplet "
                   "(default 256)")
    t.add_argument("--lr", type=float, help="Adam learning rate, decaying linearly to 0 "
                   "(default 0.004)")
    t.add_argument("--seed", type=int, default=0, metavar="S")
    t.add_argument("--similarity", choices=("cosine", "tanh", "both"), help="triplet: hinge on "
                   "cosine (MC-CNN), on the tanh relaxation of the Hamming comparison (default), "
                   "or both")
    t.add_argument("--noise-max", type=float, metavar="SIGMA",
                   help="augmentation noise: sigma ~ U(0, SIGMA) grey levels per view (default 2)")
    t.add_argument("--aggregate", type=int, metavar="A", help="triplet: average the "
                   "similarity over A x A neighbouring descriptors, as the box filter does (odd)")
    t.add_argument("--threads", type=int, default=2, metavar="N", help="torch CPU threads")
    t.add_argument("--out", metavar="FILE", help="float model .npz (default: VARIANT.npz)")
    t.add_argument("--quiet", action="store_true", help="no progress bar")
    t.set_defaults(func=cmd_train)

    q = sub.add_parser("quantize", help="int8-quantise a trained model for the NNA")
    q.add_argument("model", help="float model .npz written by 'stereosim train'")
    q.add_argument("--calib", required=True, metavar="DIR", help="calibration scenes: the "
                   "shared data folder (its training scenes), a collection or one scene")
    q.add_argument("--out", required=True, metavar="WEIGHTS", help="quantized artifact .npz")
    q.add_argument("--calib-scenes", type=int, default=8, metavar="N",
                   help="use the views of at most N scenes, spread evenly (default 8)")
    q.add_argument("--distance", default="hamming", choices=("hamming", "rms", "l1", "kl",
                   "hist_rms"), help="distance that picks the last layer's scales")
    q.add_argument("--hidden-distance", default="rms", choices=("hamming", "rms", "l1", "kl",
                   "hist_rms"), help="distance that picks the other layers' scales (default rms)")
    q.add_argument("--act-quantile", type=float, default=0.9999, metavar="Q", help="multi-layer: "
                   "each hidden layer's int8 activations map this quantile of its ReLU outputs "
                   "to 127 (default 0.9999; lower clips more and rounds finer)")
    q.add_argument("--steps", type=int, default=1000, metavar="N",
                   help="scale candidates per channel (>= 1000)")
    q.add_argument("--z-bits", type=int, default=8, metavar="Z", help="m, h in [0, 2^Z - 1]")
    q.add_argument("--samples", type=int, default=20000, metavar="N",
                   help="sampled pixels for the search")
    q.add_argument("--seed", type=int, default=0, metavar="S")
    q.set_defaults(func=cmd_quantize)

    c = sub.add_parser("config", help="show or compare configurations")
    csub = c.add_subparsers(dest="config_command", required=True, parser_class=_Parser)
    cs = csub.add_parser("show", help="print the effective configuration as TOML")
    cs.add_argument("--plain", action="store_true", help="without the help comments")
    _add_config_options(cs)
    cs.set_defaults(func=cmd_config_show)
    cp = csub.add_parser("plan", help="the chip plan: clock domains, blocks, FIFOs, SRAM")
    cp.add_argument("--size", default="1280x720", metavar="WxH",
                    help="frame size (default 1280x720)")
    cp.add_argument("--png", metavar="PATH", help="also draw the plan into this PNG")
    _add_config_options(cp)
    cp.set_defaults(func=cmd_config_plan)
    cd = csub.add_parser("diff", help="keys that differ between two TOML configurations")
    cd.add_argument("a")
    cd.add_argument("b")
    cd.set_defaults(func=cmd_config_diff)


    whatif_cli.register(sub, _add_config_options, _scene_config)
    add_wave_parser(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    try:
        args = build_parser().parse_args(argv)
        return args.func(args)
    except UserError as exc:
        print(f"stereosim: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("stereosim: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
