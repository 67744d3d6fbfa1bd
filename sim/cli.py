"""The ``stereosim`` command line.

Every user mistake ends in one line on stderr (``stereosim: error: ...``) and exit status 2,
never a traceback; outputs are written only after the whole frame has been computed, each file
atomically, so a failed run leaves nothing half-written.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import os
import sys
import time
from pathlib import Path

import numpy as np

from stereosim.core import signals
from stereosim.core.config import (
    DESCRIPTOR_DEFAULTS,
    config_diff,
    config_to_toml,
    keys_set,
    layer_notes,
    load_config,
    parse_set_options,
)
from stereosim.core.config.backend import (
    BACKEND_KEYS,
    backend_note,
    backend_text,
    carried_backend,
    describe,
    write_backend,
)
from stereosim.core.datasets import (
    default_scene,
    find_scene,
    find_scenes,
    legal_disparities,
    load_scene,
    scene_files,
)
from stereosim.core.errors import ConfigError, InputError, UserError
from stereosim.core.io import (
    MAX_PIXELS,
    disparity_to_colour,
    encode_png,
    pfm_bytes,
    pixel_cap,
    read_gt,
    read_image,
    read_mask,
)
from stereosim.core.npz import open_npz
from stereosim.core.outputs import (
    atomic_write_bytes,
    check_outputs,
    describe_os_error,
    json_text,
    path_text,
    publish,
)
from stereosim.core.progress import compile_notice
from stereosim.nna.descriptor import load_cnn
from stereosim.sim import formats, rtl_check, rtl_synth, train_cli, whatif_cli
from stereosim.sim.api import run, version_text
from stereosim.sim.argtypes import (
    check_single_output,
    finite_float,
    nonempty_path,
    nonempty_size,
    nonnegative_int,
    positive_int,
)
from stereosim.sim.cycle.contract import RunStopped
from stereosim.sim.cycle.estimate import estimate, parse_size
from stereosim.sim.cycle.frames import MAX_FRAMES
from stereosim.sim.cycle.plan import build_plan, frame_size
from stereosim.sim.diagram import plan_text, write_plan_png
from stereosim.sim.html_report import html_files
from stereosim.sim.run_files import StopAsked, publish_stop, with_report
from stereosim.sim.stream_cli import cmd_run_stream, config_sources
from stereosim.sim.summary import (
    energy_lines,
    eval_document,
    eval_line,
    eval_tables,
    eval_timing,
    print_summary,
)
from stereosim.sim.tracing import TraceRequest, parse_window, trace_files, trace_paths
from stereosim.traces.cli import add_wave_parser
from stereosim.traces.log import parse_patterns

EVAL_KEYS = ("bad0.5", "bad1", "bad2", "bad4", "invalid", "totbad", "avgerr", "rms")
RUN_FILES = ("disparity.pfm", "disparity.png", "report.json")
# run's options that name a file it reads (no output may replace one) and those it writes
RUN_INPUTS = ("left", "right", "gt", "mask", "energy", "calib", "left_video",
              "right_video")
RUN_OUTPUTS = ("html", "vcd", "timeline")


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage mistake is one line and exit status 2 like every other error."""

    def error(self, message):
        raise UserError(f"{message} (see '{self.prog} --help')")


# The named presets (--config NAME) are the TOML files of the checkout's configs/ folder.
PRESETS = Path(__file__).resolve().parent.parent / "configs"


def config_file(text: str) -> str:
    """--config: a TOML file, or the name of a preset in configs/ (``paper-720p``)."""
    if os.path.exists(text) or text.endswith(".toml") or os.sep in text:
        return text
    preset = PRESETS / f"{text}.toml"
    if preset.is_file():
        return str(preset)
    names = sorted(p.stem for p in PRESETS.glob("*.toml")) if PRESETS.is_dir() else []
    raise argparse.ArgumentTypeError(
        f"no config file or preset named {text!r}: give a TOML file or one of the presets "
        f"({', '.join(names) or 'none in this installation'})")


def _add_config_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", metavar="FILE|PRESET", type=config_file, action="append",
                   help="TOML configuration file, or a preset of configs/: paper-720p, 1080p60, "
                   "census-baseline, robust-720p; repeatable: the files are layered in order, "
                   "a later file's keys win (each key it replaces is noted on stderr)")
    p.add_argument(
        "--set", metavar="KEY=VALUE", action="append", default=[],
        help="override one configuration key, e.g. --set sva.p1=10 (repeatable)",
    )
    p.add_argument("--disparities", type=int, metavar="N",
                   help="disparity range D (sva.disparities)")
    p.add_argument(
        "--descriptor", choices=("census", "cnn", "hybrid"),
        help="per-pixel descriptor (nna.descriptor)"
    )


def _overrides(args) -> dict:
    over = parse_set_options(args.set)
    if args.disparities is not None:
        over["sva.disparities"] = args.disparities
    if args.descriptor is not None:
        over["nna.descriptor"] = args.descriptor
    if getattr(args, "max_cycles", None) is not None:
        over["sim.max_cycles"] = args.max_cycles
    return over


def _user_set_disparities(args, over: dict) -> bool:
    """Did the user choose D (flag, --set or config file)? Then a scene's calib.txt does not."""
    return "sva.disparities" in keys_set(args.config, over)


def config_inputs(args) -> list[tuple[str, str]]:
    """The config files of ``--config`` as (path, label) inputs no output may replace."""
    return [(path, "--config") for path in args.config or ()]


def _notes(args, cfg) -> None:
    """What the user should know of the configuration, once a command (the parsed arguments
    remember it), on stderr: with several --config files, a line per file whose keys replace
    an earlier one's; a CNN weight file without its own back end, which back end stays."""
    if getattr(args, "_noted", False):
        return
    args._noted = True
    if cfg.nna.descriptor in ("cnn", "hybrid"):
        load_cnn(cfg.nna)  # a bad weight file is its one line, before any note about it
    lines = layer_notes(args.config) if len(args.config or ()) > 1 else []
    note = backend_note(cfg.nna.cnn.weights, cfg.nna.descriptor,
                        keys_set(args.config, _overrides(args)))
    for line in lines + ([note] if note else []):
        print(f"stereosim: note: {line}", file=sys.stderr)


def _scene_config(args, ndisp: int | None):
    over = _overrides(args)
    if ndisp is not None and not _user_set_disparities(args, over):
        over["sva.disparities"] = legal_disparities(ndisp)
    cfg = load_config(args.config, over)
    _notes(args, cfg)
    return cfg


# ----------------------------------------------------------------------------------------------
# stereosim run


def _pixel_cap(args) -> int:
    """--max-pixels for the file readers (0: no cap)."""
    return pixel_cap(args.max_pixels)


def _load_run_inputs(args) -> dict:
    """The stereo pair (+ GT and masks) from a scene folder, --left/--right, or the default."""
    cap = _pixel_cap(args)

    if args.scene and (args.left or args.right):
        raise InputError("give either a scene folder or --left/--right, not both")
    if bool(args.left) != bool(args.right):
        raise InputError("give both --left and --right (or neither, for the default scene)")
    if args.scene:
        data = load_scene(find_scene(args.scene, gt_scale=args.gt_scale), max_pixels=cap)
        data["source"] = str(args.scene)
    elif args.left:
        data = {
            "name": Path(args.left).parent.name or Path(args.left).stem,
            "left": read_image(args.left, max_pixels=cap),
            "right": read_image(args.right, max_pixels=cap),
            "gt": None,
            "masks": {},
            "ndisp": None,
            "source": f"{args.left} + {args.right}",
        }
    else:
        data = default_scene()
        data["source"] = "embedded default scene (scikit-image stereo_motorcycle)"
    if args.gt:
        data["gt"] = read_gt(args.gt, args.gt_scale, max_pixels=cap)
        data["masks"] = {}
    if args.mask:
        if data.get("gt") is None:
            raise InputError("--mask needs ground truth: give --gt too")
        mask = read_mask(args.mask, max_pixels=cap)
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


def _output_blobs(out_dir: Path, result, dmax: float, traces: dict[str, bytes]) -> dict:
    """Every file of a run by path: the disparity maps, the report and traces."""
    blobs = {
        out_dir / "disparity.pfm": pfm_bytes(result.disparity),
        out_dir / "disparity.png": encode_png(disparity_to_colour(result.disparity, dmax)),
    }
    blobs.update((Path(p), data) for p, data in traces.items())
    return with_report(out_dir, result.report, blobs)


@compile_notice()  # one notice for all the kernels a run compiles (the run's, the writers')
def cmd_run(args) -> int:
    for name in RUN_INPUTS + RUN_OUTPUTS:  # '' (an unset shell variable, say) is not ignored
        if getattr(args, name) is not None and not getattr(args, name).strip():
            raise InputError(f"--{name.replace('_', '-')} is empty: give a file name")
    request = _trace_request(args)
    if not args.out.strip():
        raise InputError("--out is empty: give the output folder, e.g. --out out")
    out_dir = Path(args.out)
    planned = [(out_dir / name, f"--out {name}") for name in RUN_FILES]
    if request is not None:
        planned += trace_paths(request)
    saving = formats.save_request(args.save_as, args.calib, args.scene)  # reads calib.txt
    planned += saving.planned(out_dir)
    if args.html:
        planned.append((args.html, "--html"))
    inputs = [(getattr(args, name), f"--{name.replace('_', '-')}") for name in RUN_INPUTS]
    inputs += config_inputs(args)
    scenes = [find_scene(args.scene, gt_scale=args.gt_scale)] if args.scene else []
    inputs += scene_files(scenes)
    check_outputs(planned, inputs)  # before any work, none an input
    if args.left_video or args.right_video or (args.frames or 1) > 1 or args.save_every:
        if saving.formats:
            raise InputError("--save-as writes one frame's files: drop --frames and the videos")
        if args.html:
            raise ConfigError("--html reports one frame: drop --frames, --save-every and the "
                              "videos")
        video = bool(args.left_video or args.right_video)
        if video and (args.scene or args.left or args.right):
            raise InputError("give the videos or a pair (scene, --left/--right), not both")
        if video and (args.gt or args.mask):
            raise InputError("videos have no ground truth: drop --gt/--mask (a pair repeated "
                             "with --frames N is scored frame by frame)")
        data = None if video else _load_run_inputs(args)
        if not video and args.frames is None:
            raise InputError("--save-every needs a stream: give --frames N or the videos")
        cfg = _scene_config(args, None if data is None else data.get("ndisp"))
        return cmd_run_stream(args, request, data, cfg, inputs)
    data = _load_run_inputs(args)
    saving.check_size(data["left"].shape)
    cfg = _scene_config(args, data.get("ndisp"))
    t0 = time.perf_counter()
    scene = {"name": data["name"], "source": data["source"]}
    try:
        result = run(data["left"], data["right"], mode=args.mode, config=cfg,
                     gt=data.get("gt"), masks=data.get("masks"), trace=request,
                     max_pixels=args.max_pixels or None, energy=args.energy)
    except RunStopped as stop:
        stop.report["config_sources"] = config_sources(args)
        raise publish_stop(stop, request, out_dir, planned, scene) from None
    seconds = time.perf_counter() - t0
    result.report["scene"] = scene
    result.report["config_sources"] = config_sources(args)
    traces = trace_files(result.trace, request) if request is not None else {}
    saved = saving.files(out_dir, result.disparity, data["left"])
    page = html_files(args.html, result, data)
    blobs = _output_blobs(out_dir, result, float(cfg.sva.disparities), traces | saved | page)
    publish(blobs, manifest=out_dir / "report.json")  # the whole set, or the old one
    if args.json:
        sys.stdout.write(json_text(result.report))
    else:
        print_summary(result.report, seconds)
        print(f"wrote {out_dir}/disparity.pfm, disparity.png, report.json")
        if saved:
            print(f"wrote {', '.join(p.name for p in saved)} in {out_dir}")
        if traces:
            print(f"wrote {', '.join(traces)} ({result.trace.n_changes} value changes)")
        if page:
            print(f"wrote {args.html}")
    return 0


def _trace_request(args):
    """The TraceRequest of run's trace options, or None without --vcd/--timeline."""

    if not (args.vcd or args.timeline):
        if args.trace_window or args.trace or args.force:
            raise ConfigError("--trace-window, --trace (--signals) and --force need --vcd FILE "
                              "or --timeline FILE")
        return None
    if args.mode != "cycle":
        raise ConfigError("traces need the cycle model: drop --mode functional")
    parse_window(args.trace_window)  # bad windows fail before the run
    if not args.trace_limit > 0:
        raise ConfigError(f"--trace-limit must be > 0 MB, got {args.trace_limit:g}")
    patterns = parse_patterns(args.trace, "--trace (--signals)")
    return TraceRequest(window=args.trace_window, patterns=patterns, vcd=args.vcd,
                        timeline=args.timeline, force=args.force, limit_mb=args.trace_limit)


# ----------------------------------------------------------------------------------------------
# stereosim eval


def cmd_eval(args) -> int:
    from tqdm import tqdm

    scenes = find_scenes(args.dataset, gt_scale=args.gt_scale)
    _scene_config(args, None)  # a bad --set or --config fails once, before any scene
    planned = [(Path(args.out), "--out")] if args.out else []
    saved = {} if args.save else None  # scene -> (disparity, report, seconds) for --save
    if args.algo_name is not None and not args.save:
        raise ConfigError("--algo-name names the files of --save: give --save DIR too")
    if args.save:
        args.algo_name = name = formats.check_algo_name(args.algo_name
                                                        or formats.DEFAULT_ALGO_NAME)
        planned += formats.middeval3_paths(args.save, name, [s.name for s in scenes])
    check_outputs(planned, [*config_inputs(args), *scene_files(scenes)])  # before a scene
    rows: list[tuple[str, dict, int, dict | None]] = []  # scene, metrics, D, timing
    failed: dict[str, str] = {}
    bar = tqdm(scenes, desc="eval", unit="scene", disable=args.json or None, file=sys.stderr)
    for scene in bar:
        try:
            metrics, disparities, timing = _eval_scene(args, scene, saved)
        except UserError as exc:
            failed[scene.name] = " ".join(str(exc).split())
            if not args.json:
                bar.write(f"{scene.name}: failed: {failed[scene.name]}", file=sys.stdout)
        else:
            rows.append((scene.name, metrics, disparities, timing))
            if not args.json:
                bar.write(eval_line(scene.name, metrics, timing), file=sys.stdout)
        if args.out:  # what is done so far survives an interrupt
            document = eval_document(str(args.dataset), rows, failed)
            atomic_write_bytes(args.out, json_text(document).encode())
    bar.close()
    if saved:  # every scored scene's MiddEval3 files, published as one set
        publish(formats.middeval3_files(args.save, args.algo_name, saved))
        if not args.json:
            print(formats.middeval3_note(args.save, args.algo_name, saved))
    if args.json:
        sys.stdout.write(json_text(eval_document(str(args.dataset), rows, failed)))
    else:
        print(eval_tables(rows, EVAL_KEYS), end="")
        for name, reason in failed.items():
            print(f"FAILED {name}: {reason}")
    if failed:
        first = next(iter(failed))
        raise UserError(
            f"{len(failed)} of {len(scenes)} scenes failed ({first}: {failed[first]}); the others "
            "were scored"
        )
    return 0


def _eval_scene(args, scene, saved: dict | None = None) -> tuple[dict, int, dict | None]:
    """One scene's metrics, D and cycle figures (None in functional mode); a scene that cannot
    be scored raises a UserError."""
    data = load_scene(scene, max_pixels=_pixel_cap(args))
    if data["gt"] is None:
        raise InputError(f"scene {scene.name} has no ground truth: nothing to score")
    cfg = _scene_config(args, data.get("ndisp"))
    res = run(data["left"], data["right"], mode=args.mode, config=cfg, gt=data["gt"],
              masks=data["masks"], max_pixels=args.max_pixels or None)
    if saved is not None:  # the frame time of time<NAME>.txt when the run measured none
        estimate_ms = (None if "latency" in res.report
                       else estimate(cfg, res.disparity.shape)["latency"]["frame_ms"])
        saved[scene.name] = (res.disparity, res.report, estimate_ms)
    return res.report["metrics"], cfg.sva.disparities, eval_timing(res.report)


# ----------------------------------------------------------------------------------------------
# stereosim config


def cmd_config_show(args) -> int:
    cfg = _scene_config(args, None)
    sys.stdout.write(config_to_toml(cfg, comments=not args.plain,
                                    set_keys=keys_set(args.config, _overrides(args))))
    return 0


def cmd_config_plan(args) -> int:
    if args.png is not None:
        check_single_output(Path(args.png), "--png", config_inputs(args))
    cfg = _scene_config(args, None)
    shape = parse_size(args.size) if args.size else frame_size(cfg)
    plan = build_plan(cfg, shape)
    if args.png:
        write_plan_png(plan, args.png)
    sys.stdout.write(plan_text(plan))
    # the chip's energy a frame and power at the rate it delivers, as the estimate prices them
    print("\n".join(energy_lines(estimate(cfg, shape)["energy"])))
    return 0


def cmd_config_backend(args) -> int:
    """Show the back end a weight file carries; with --set, store one in it first."""
    path = args.weights
    try:
        carried = carried_backend(path)
    except ConfigError:
        if not args.set:
            raise
        carried = None  # a damaged back end is replaced by the one given
        open_npz(path, "weight file", "give a weight file")  # but the file must be one
    if args.set:
        over = parse_set_options(args.set)
        keys = {f"sva.{k}" for k in BACKEND_KEYS}
        for key in over:
            if key not in keys:
                raise ConfigError(f"--set {key}: a back end sets only {', '.join(sorted(keys))}")
        base = {f"sva.{k}": v for k, v in (carried or DESCRIPTOR_DEFAULTS["cnn"]).items()}
        cfg = load_config(None, {"nna.descriptor": "cnn", "nna.cnn.weights": path,
                                 **base, **over})  # every value's range
        load_cnn(cfg.nna)  # and the file's network
        carried = {k: getattr(cfg.sva, k) for k in BACKEND_KEYS}
        write_backend(path, carried)
        print(f"wrote the back end into {path}")
    if carried is None:
        print(f"{path} carries no back end: it runs with the cnn descriptor's "
              f"({describe(DESCRIPTOR_DEFAULTS['cnn'])}); store one with --set sva.KEY=VALUE")
    else:
        print(f"{path}: {describe(carried)}")
        sys.stdout.write(backend_text(carried))
    return 0


def cmd_config_diff(args) -> int:
    diff = config_diff(load_config(args.a), load_config(args.b))
    if not diff:
        print("no differences")
    for key, (va, vb) in sorted(diff.items()):
        print(f"{key}: {va!r} -> {vb!r}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="stereosim", description="Simulator of an edge stereo-vision SoC.")
    p.add_argument("--version", action="version", version=version_text())
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    _add_run_parser(sub)
    _add_eval_parser(sub)
    train_cli.register(sub)
    _add_config_parser(sub)
    whatif_cli.register(sub, _add_config_options, _scene_config)
    add_wave_parser(sub)
    rtl = sub.add_parser("rtl", help="the RTL twin: its synthesis figures (docs/rtl-synth.md) "
                         "and its co-simulation against the cycle model (docs/rtl.md)")
    rtl_sub = rtl.add_subparsers(dest="rtl_command", required=True, parser_class=_Parser)
    rtl_synth.add_parser(rtl_sub)
    rtl_check.add_parser(rtl_sub, _add_config_options, _scene_config)
    return p


def _add_run_parser(sub) -> None:
    """``stereosim run``: one frame or a stream, its traces and the formats other tools read."""
    r = sub.add_parser("run", help="simulate one stereo frame")
    r.add_argument("scene", nargs="?", help="a Middlebury scene folder (im0/im1/disp0GT/...)")
    r.add_argument("--left", help="left image (PNG etc.; RGB is converted to grey)")
    r.add_argument("--right", help="right image")
    r.add_argument("--gt", help="ground-truth disparity (.pfm, or .png with --gt-scale)")
    r.add_argument("--gt-scale", type=finite_float, help="GT PNG value per pixel of disparity")
    r.add_argument("--mask", help="evaluation mask PNG (255 = non-occluded)")
    r.add_argument("--mode", default="cycle", choices=("functional", "cycle"),
                   help="cycle (default: the clocked chip, same disparities plus cycle counts) or "
                   "functional (the bit-exact model alone, faster)")
    r.add_argument("--out", default="out", help="output folder (default: out)")
    r.add_argument("--json", action="store_true", help="print the report as JSON")
    r.add_argument("--max-pixels", type=nonnegative_int, default=MAX_PIXELS, metavar="N",
                   help=f"refuse larger images (default {MAX_PIXELS}, 4096x4096; 0 = no cap)")
    r.add_argument("--max-cycles", type=positive_int, metavar="N",
                   help="stop once any clock domain ran N cycles (sim.max_cycles; exit status 2 "
                   "with every FIFO's state)")
    r.add_argument("--html", metavar="FILE", help="also write a one-page HTML report of the "
                   "run (one frame; see docs/html-report.md)")
    r.add_argument("--energy", metavar="FILE", help="energy table (TOML) for the report's "
                   "energy and power (default: stereosim's 45 nm table; docs/energy.md)")
    s = r.add_argument_group("streams of frames (see docs/streams.md)")
    s.add_argument("--frames", type=positive_int, metavar="N",
                   help="simulate N frames back to back: the pair repeated, or the first N of "
                   f"the videos (default 1, all of the videos; at most {MAX_FRAMES:,})")
    s.add_argument("--left-video", metavar="FILE", help="left camera's video (read with OpenCV)")
    s.add_argument("--right-video", metavar="FILE", help="right camera's video")
    s.add_argument("--save-every", type=nonnegative_int, default=0, metavar="K",
                   help="also write every K-th frame's disparity into OUT/frames/ (default 0: "
                   "only the last frame's)")
    t = r.add_argument_group("traces (cycle model; see docs/traces.md)")
    t.add_argument("--vcd", help="write a waveform of the trace window (and a .gtkw next to "
                   "it): VCD, or FST (GTKWave's compressed format) when the name ends in .fst")
    t.add_argument("--timeline", help="write a Chrome/Perfetto trace-event JSON of the window")
    t.add_argument("--trace-window", metavar="A:B",
                   help="a time window with units (fs/ps/ns/us/ms/s, e.g. 0:100us), SVA cycles "
                   "A:B, nna:A:B / sva:A:B / camera:A:B cycles, or rows:A:B (default: the "
                   "whole frame)")
    t.add_argument("--trace", "--signals", dest="trace", action="append", default=[],
                   metavar="PATTERNS", help="keep signals matching these glob patterns "
                   "(comma-separated, repeatable), e.g. 'top.sva.*,top.fifo.*.occupancy'")
    t.add_argument("--trace-limit", type=finite_float, default=500.0, metavar="MB",
                   help="refuse a VCD larger than this (default 500 MB) unless --force")
    t.add_argument("--force", action="store_true", help="write the VCD whatever its size")
    o = r.add_argument_group("formats other tools read (see docs/outputs.md)")
    o.add_argument("--save-as", metavar="FORMATS", help="also write these into --out, comma-"
                   "separated: kitti (disparity_kitti.png), opencv16 (disparity_opencv16.npy), "
                   "depth (depth_mm.png), ply (points.ply); depth and ply need a calib.txt")
    o.add_argument("--calib", metavar="FILE", help="Middlebury calib.txt for depth and ply "
                   "(default: the scene folder's calib.txt)")
    _add_config_options(r)
    r.set_defaults(func=cmd_run)


def _add_eval_parser(sub) -> None:
    """``stereosim eval``: every scene of a folder, scored."""
    e = sub.add_parser("eval", help="run and score every scene of a Middlebury-layout folder")
    e.add_argument("dataset", type=nonempty_path,
                   help="folder of scenes (e.g. ../shared/data/middlebury2014_trainingQ)")
    e.add_argument("--gt-scale", type=finite_float, help="GT PNG scale for non-standard sizes")
    e.add_argument("--mode", default="cycle", choices=("functional", "cycle"),
                   help="cycle (default, as in run): scores plus fps, latency and bottleneck per "
                   "scene; functional: the bit-exact model alone, faster")
    e.add_argument("--json", action="store_true", help="print per-scene and mean metrics as JSON")
    e.add_argument("--out", metavar="FILE.json", type=nonempty_path,
                   help="also write the per-scene and mean metrics here, rewritten "
                   "(atomically) after every scene")
    e.add_argument("--max-pixels", type=nonnegative_int, default=MAX_PIXELS, metavar="N",
                   help=f"refuse larger images (default {MAX_PIXELS}; 0 = no cap)")
    e.add_argument("--save", metavar="DIR", type=nonempty_path,
                   help="also write the disparity maps in MiddEval3's layout: "
                   "DIR/<Scene>/disp0NAME.pfm and timeNAME.txt (docs/outputs.md)")
    e.add_argument("--algo-name", metavar="NAME",
                   help=f"NAME in --save's file names (default {formats.DEFAULT_ALGO_NAME})")
    _add_config_options(e)
    e.set_defaults(func=cmd_eval)


def _add_config_parser(sub) -> None:
    """``stereosim config show | plan | diff``."""
    c = sub.add_parser("config", help="show or compare configurations")
    csub = c.add_subparsers(dest="config_command", required=True, parser_class=_Parser)
    cs = csub.add_parser("show", help="print the effective configuration as TOML")
    cs.add_argument("--plain", action="store_true", help="without the help comments")
    _add_config_options(cs)
    cs.set_defaults(func=cmd_config_show)
    cp = csub.add_parser("plan", help="the chip plan: clock domains, blocks, FIFOs, SRAM")
    cp.add_argument("--size", metavar="WxH", type=nonempty_size,
                    help="frame size (default: the configured camera's, source.camera_width x "
                    "camera_height, else 1280x720)")
    cp.add_argument("--png", metavar="PATH", type=nonempty_path,
                    help="also draw the plan into this PNG")
    _add_config_options(cp)
    cp.set_defaults(func=cmd_config_plan)
    cb = csub.add_parser("backend", help="the SVA back end a CNN weight file carries (the "
                         "P1/P2, adaptive P2 and box it was tuned with); --set stores one")
    cb.add_argument("weights", metavar="FILE.npz", type=nonempty_path,
                    help="a weight file or quantized artifact")
    cb.add_argument("--set", metavar="sva.KEY=VALUE", action="append", default=[],
                    help="store this back-end key in the file (repeatable; the keys not given "
                    "keep the file's, else the cnn descriptor's defaults)")
    cb.set_defaults(func=cmd_config_backend)
    cd = csub.add_parser("diff", help="keys that differ between two configurations (TOML files "
                         "or presets)")
    cd.add_argument("a", metavar="A", type=config_file,
                    help="TOML file or preset (e.g. paper-720p)")
    cd.add_argument("b", metavar="B", type=config_file, help="TOML file or preset (e.g. 1080p60)")
    cd.set_defaults(func=cmd_config_diff)


def main(argv: list[str] | None = None) -> int:
    """Run one command: 0 on success; 2 with one line on stderr for every user mistake or file
    system problem; 130 on SIGINT, 143 on SIGTERM and 129 on SIGHUP, after clean-up: nothing
    half-written (core.signals; the line says when the outputs were written first)."""
    with signals.handling() as handler:
        try:
            try:
                status = _command(argv)
            finally:
                if handler is not None:
                    handler.settle()  # the outcome is decided: a signal no longer changes it
            lost = signals.swallowed()
            if lost is not None:  # a signal came while a finalizer ran: it ends the command now
                raise lost
            return status
        except Exception as exc:
            lost = signals.swallowed()
            if lost is not None:
                # a signal raised inside a finalizer or a C callback (llvmlite's, while numba
                # compiles) cut that code short, and what failed after it is the signal's
                # doing: numba's "no compiled object yet" gave a traceback and exit 1
                status, line = signals.exit_line(lost, handler is not None and handler.published)
                print(line, file=sys.stderr)
                return status
            status = _failure(exc)
            if status is None:  # no command anticipated it: a bug, with its traceback
                raise
            return status
        except KeyboardInterrupt as exc:  # SIGINT, or Terminated (SIGTERM, SIGHUP)
            status, line = signals.exit_line(exc, handler is not None and handler.published)
            print(line, file=sys.stderr)
            return status


def _failure(exc: Exception) -> int | None:
    """Exit 2 with the one line of a command stopped by ``exc`` (a user mistake, a file-system
    problem, memory); None for an exception no command anticipated."""
    if isinstance(exc, StopAsked):  # a stop the user asked for is not an error
        return _fail(str(exc), prefix="stereosim: ")
    if isinstance(exc, UserError):
        return _fail(str(exc))
    if isinstance(exc, OSError):  # a file-system problem no command anticipated
        if not _stdout_works() or (exc.filename is None and exc.errno in _STREAM_ERRNOS):
            _silence_stdout()
            return _fail(f"cannot write to standard output ({describe_os_error(exc)}): "
                         "check the device or pipe it writes to")
        where = f" ({path_text(exc.filename)})" if exc.filename else ""
        return _fail(f"{describe_os_error(exc)}{where}: check the path, its permissions and "
                     "the free space")
    if isinstance(exc, MemoryError):
        return _fail("out of memory: use smaller images (--max-pixels) or a smaller "
                     "disparity range")
    return None


def _command(argv: list[str] | None) -> int:
    if sys.stdout is None:  # started with file descriptor 1 closed
        raise UserError("standard output is closed: give stereosim one (e.g. > /dev/null)")
    args = build_parser().parse_args(argv)
    status = args.func(args)
    if not _stdout_works():
        return _fail("cannot write to standard output: check the device or pipe it writes to")
    return status


# errnos of a write to a stream that cannot take more (an OSError without a file name)
_STREAM_ERRNOS = {errno.ENOSPC, errno.EPIPE, errno.EDQUOT, errno.EIO}


def _stdout_works() -> bool:
    """Flush stdout; if it is broken (a full device, a closed pipe), silence it and say so."""
    if sys.stdout is None:  # closed from the start: the command was refused before any work
        return True
    try:
        sys.stdout.flush()
        return True
    except (OSError, ValueError):
        _silence_stdout()
        return False


def _silence_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's last flush cannot print a traceback."""
    with contextlib.suppress(OSError, ValueError, AttributeError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)


def _fail(message: str, prefix: str = "stereosim: error: ") -> int:
    """The one line on stderr (``prefix``: an error's, or a stop's that the user asked for);
    exit status 2."""
    if not _stdout_works():
        message = f"{message} (and standard output cannot be written)"
    print(f"{prefix}{' '.join(message.split())}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    # the handler is kept until the process exits: a late signal cannot cut the exit short
    sys.exit(signals.entry(main))
