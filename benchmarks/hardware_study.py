"""The paper's descriptor ablation as a hardware study (docs/hardware-study.md).

The paper (section 5) cut MC-CNN-fast's four 3x3 layers to one 9x9 layer because a multilayer
network must store its intermediate feature maps. stereosim runs 1-4 layer networks on an NNA
submodule as a layer pipeline with a line buffer per layer (nna/geometry.py). This script puts
seven networks of ``benchmarks/models`` (:data:`NETWORKS`: the paper's three, our
``mixed5x5`` and the three of the robust-network budget) side by side at 1280x720 on the
paper's NNA:

* from the chip plan and nna/geometry.py (cheap): MACs per pixel, each layer's MAC share,
  cycles per pixel and line buffer, the NNA's frame rate on one submodule per camera (the hand
  formula and the plan's work bound), the submodules per camera 30 and 60 fps need, the first
  descriptor's cycle by the formula of docs/architecture.md;
* from the ablation's cached JSON (benchmarks/results/, written by ``benchmarks/ablation.py
  --json``): the int8 descriptor's MiddEval3 trainingQ accuracy, clean and with noise;
* from the cycle model (a 720p synthetic pair, the compiled engine, seconds per network): the
  measured fps of one frame and the sustained fps of a 3-frame stream, the bottleneck, the
  first descriptor (the trace's ``out.valid`` and the report's per-layer first outputs), the
  energy per frame and the power at 30 fps.

    python benchmarks/hardware_study.py            # print the block
    python benchmarks/hardware_study.py --write    # put it into docs/hardware-study.md
    python benchmarks/hardware_study.py --check    # exit 1 (with a diff) if the page's plan,
                                                   # formula and accuracy figures are stale
"""

from __future__ import annotations

import argparse
import difflib
import json
import math
import sys
from pathlib import Path

import ablation
from markers import write_between

from stereosim.core.config import load_config
from stereosim.nna.geometry import layer_halves, layer_macs_per_pixel, mac_shares
from stereosim.nna.submodule.timing import cycles_per_descriptor, layer_cycles
from stereosim.nna.training.trainconfig import VARIANTS
from stereosim.sim.api import run, run_stream
from stereosim.sim.cycle.figures import submodule_report
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.sweep import synthetic_pair
from stereosim.sim.tracing import TraceRequest
from stereosim.traces.log import changes_of

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "hardware-study.md"
BEGIN, END = "<!-- hardware-study:begin -->", "<!-- hardware-study:end -->"
NETWORKS = ("single9x9", "mccnn4-slim", "mccnn4", "mixed5x5", "mccnn4-mid", "mccnn4-wide",
            "mixed5x5-wide")
SHAPE = (720, 1280)
#: the paper's NNA, set explicitly (each equals stereosim's default today)
CHIP = {"clocks.nna_mhz": 460.0, "nna.macs": 288, "nna.submodules": 10,
        "nna.stereo_submodules": 2, "sva.disparities": 128}
TARGETS = (30, 60)
STREAM_FRAMES = 3
RESULTS = ROOT / "benchmarks" / "results"
ACCURACY = {
    "clean": (RESULTS / "ablation-clean.json",
              "python benchmarks/ablation.py --write docs/ablation.md "
              "--json benchmarks/results/ablation-clean.json"),
    "noise 8": (RESULTS / "ablation-noise8.json",
                "python benchmarks/ablation.py --noise 8 --seed 0 --write docs/ablation.md "
                "--json benchmarks/results/ablation-noise8.json"),
}
OUT_VALID = "top.nna.left.sub0.out.valid"
MISSING = "..."


def weights_path(variant: str) -> Path:
    """The int8 artifact the NNA runs for ``variant`` (the ablation's choice of file)."""
    return ablation.model_paths(ablation.MODELS, variant)[1]


def overrides(variant: str, **extra) -> dict:
    """The configuration keys of a network's run: the paper's NNA (:data:`CHIP`), the network's
    int8 weights and ``nna.line_buffer_rows`` = K_0 + 1 (the first layer's window and a row)."""
    k0 = VARIANTS[variant][0][2]
    return {**CHIP, "nna.descriptor": "cnn", "nna.cnn.weights": str(weights_path(variant)),
            "nna.line_buffer_rows": k0 + 1, **extra}


def nna_fps(variant: str, per_camera: int, shape=SHAPE) -> float:
    """The plan's NNA work bound with ``per_camera`` column tiles a camera (its busiest tile's
    busiest layer: f / max over layers of output pixels x II_l; ``nna.submodules`` raised
    to 2 x ``per_camera`` when that exceeds the chip's 10)."""
    n = 2 * per_camera
    cfg = load_config(overrides=overrides(variant, **{"nna.stereo_submodules": n,
                                                      "nna.submodules": max(n, 10)}))
    return submodule_report(build_plan(cfg, shape))["nna_fps"]


def first_outputs_formula(halves, cycles, shape) -> list[int]:
    """Each layer's first output cycle on a whole frame from a memory source (one pixel a
    cycle from cycle a = 1), nothing stalling (docs/architecture.md, NNA submodule): input row
    r complete in D_-1(r) = a + r W + W - 1; S_l(y) = max(D_l-1(min(y + h_l, H - 1)),
    D_l(y - 1)) + 1, D_l(y) = S_l(y) + W II_l - 1; first output S_l(0) + II_l - 1."""
    h_img, w = shape
    reach = [sum(halves[i + 1:]) for i in range(len(halves))]
    done = [1 + r * w + w - 1 for r in range(h_img)]  # D_-1
    firsts = []
    for half, ii, rows in zip(halves, cycles, reach, strict=True):
        mine, prev_end = [], -math.inf
        for y in range(min(rows, h_img - 1) + 1):
            start = max(done[min(y + half, h_img - 1)], prev_end) + 1
            prev_end = start + w * ii - 1
            mine.append(prev_end)
            if y == 0:
                firsts.append(start + ii - 1)
        done = mine
    return firsts


def plan_figures(variant: str, shape=SHAPE) -> dict:
    """The cheap figures of a network: per layer (kernel, channels, MACs per pixel, MAC share,
    cycles per pixel, line buffer rows, width and bits), the NNA's fps on one submodule per
    camera by the hand formula and the plan's work bound, the submodules per camera each
    target needs (ceil and plan), the first outputs by the formula."""
    cfg = load_config(overrides=overrides(variant))
    plan = build_plan(cfg, shape)
    nna = cfg.nna
    sub = plan.blocks_of("nna")[0]
    h, w = shape
    f_hz = cfg.clocks.nna_mhz * 1e6
    nna_ii = cycles_per_descriptor(nna)
    layers = [{"kernel": 2 * lay.half + 1, "c_in": lay.channels_in, "c_out": lay.channels_out,
               "rows": lay.rows, "width": lay.buffer.bits // (lay.rows * lay.channels_in * 8),
               "bits": lay.buffer.bits} for lay in sub.layers]
    fps_formula = f_hz / (nna_ii * w * h)
    need = {}
    for target in TARGETS:
        ceil_n = math.ceil(target / fps_formula)
        n = ceil_n
        while nna_fps(variant, n, shape) < target:
            n += 1
        need[target] = {"ceil": ceil_n, "plan": n, "fps_at_ceil": nna_fps(variant, ceil_n, shape),
                        "fps_at_plan": nna_fps(variant, n, shape)}
    return {
        "variant": variant, "f_hz": f_hz, "macs": nna.macs, "shape": shape,
        "line_buffer_rows": nna.line_buffer_rows, "layers": layers,
        "m": layer_macs_per_pixel(nna), "shares": mac_shares(nna), "layer_ii": layer_cycles(nna),
        "halves": layer_halves(nna), "nna_ii": nna_ii,
        "macs_per_pixel": sum(layer_macs_per_pixel(nna)),
        "lb_bits": sum(lay["bits"] for lay in layers),
        "hidden_bytes": ablation.architecture(variant)["fmap_bytes"],
        "fps_formula": fps_formula, "fps_plan": submodule_report(plan)["nna_fps"],
        "need": need,
        "first_formula": first_outputs_formula(layer_halves(nna), layer_cycles(nna), shape),
    }


def cycle_figures(variant: str, first_formula: int, shape=SHAPE) -> dict:
    """The cycle model's figures of a network on a synthetic pair (cycle counts do not depend
    on the pixels): one traced frame (its report and the first rise of the left submodule's
    ``out.valid``) and a stream of :data:`STREAM_FRAMES` frames (its sustained rate)."""
    left, right = synthetic_pair(*shape)
    cfg = load_config(overrides=overrides(variant))
    window = f"nna:0:{2 * first_formula + 1000}"
    res = run(left, right, mode="cycle", config=cfg,
              trace=TraceRequest(window=window, patterns=(OUT_VALID,)))
    rep = res.report
    clock = next(c for c in res.trace.clocks if c.name == "nna")
    times, values = changes_of(res.trace, 0)
    rises = [int(t) for t, v in zip(times, values, strict=True) if v == 1]
    if not rises:
        sys.exit(f"hardware_study: {variant}: no descriptor left in the window {window}")
    first = (rises[0] - clock.phase_fs) // clock.period_fs
    layers = rep.get("nna_layers", {}).get("nna_left")
    per_layer = [lay["first_output_cycle"] for lay in layers] if layers else [first]
    if per_layer[-1] != first:
        sys.exit(f"hardware_study: {variant}: the trace's first descriptor (cycle {first}) is "
                 f"not the report's last layer's first output ({per_layer[-1]})")
    stream = run_stream([(left, right)] * STREAM_FRAMES, mode="cycle", config=cfg).report
    energy = rep["energy"]["per_frame_uj"]
    return {
        "fps_measured": rep["throughput"]["fps_measured"],
        "frame_ms": rep["latency"]["frame_ms"],
        "fps_bound": rep["throughput"]["fps_bound"],
        "bottleneck": rep["throughput"]["bottleneck"],
        "sustained_fps": stream["stream"]["sustained_fps"],
        "first_cycle": first, "first_us": first / (cfg.clocks.nna_mhz),
        "per_layer_first": per_layer,
        "energy_uj": energy["total"], "nna_uj": energy["by_block"]["nna"],
        "engine": rep["engine"],
    }


def accuracy() -> dict:
    """condition -> variant -> (totbad, bad2) of the int8 descriptor, from the cached JSON of
    benchmarks/ablation.py (exit 2 with the command to run when a file or a network is
    missing)."""
    out = {}
    for cond, (path, command) in ACCURACY.items():
        if not path.exists():
            print(f"hardware_study: {path} is missing: run {command}", file=sys.stderr)
            sys.exit(2)
        mean = json.loads(path.read_text())["mean"]
        out[cond] = {}
        for v in NETWORKS:
            row = mean.get(f"{v} / int8 sign")
            if row is None:
                print(f"hardware_study: {path} has no {v}: run {command}", file=sys.stderr)
                sys.exit(2)
            out[cond][v] = (row["totbad"], row["bad2"])
    return out


# ----------------------------------------------------------------------------------------------
# the block

COST_HEAD = ("| network | layers (K: C_in -> C_out) | MACs / pixel | line buffer rows per layer "
             "| line buffer bits per layer (rows x width x C_in x 8) | line buffers / submodule "
             "| int8 hidden maps a frame store would hold | totbad (bad2) %, clean "
             "| totbad (bad2) %, noise sigma 8 |")
COST_KINDS = ("plan",) * 7 + ("accuracy",) * 2
RATE_HEAD = ("| network | MAC shares | cycles / pixel per layer | NNA fps, formula "
             "| NNA fps, plan | chip fps, cycle model: one frame | sustained, 3 frames "
             "| bottleneck | submodules / camera for 30 fps | for 60 fps |")
RATE_KINDS = ("plan",) * 5 + ("cycle",) * 3 + ("plan",) * 2
TIME_HEAD = ("| network | first descriptor: formula (cycles) | cycle model: cycles (us) "
             "| per-layer first outputs (cycles) | energy / frame: total (NNA), uJ "
             "| power at 30 fps, mW |")
TIME_KINDS = ("plan", "plan") + ("cycle",) * 4
FILL_HEAD = ("| network | 1 / NNA fps = max_l II_l W H / f, ms "
             "| one frame: first input pixel to last word, ms | difference, us "
             "| of which before the first descriptor, us | after it, us |")
FILL_KINDS = ("plan", "plan") + ("cycle",) * 4
TABLES = {COST_HEAD: COST_KINDS, RATE_HEAD: RATE_KINDS, TIME_HEAD: TIME_KINDS,
          FILL_HEAD: FILL_KINDS}


def _row(cells) -> str:
    return "| " + " | ".join(str(c) for c in cells) + " |"


def _rule(kinds) -> str:
    return "|---|" + "---:|" * (len(kinds) - 1)


def _need_cell(need: dict, limit_per_camera: int) -> str:
    n = need["plan"]
    over = f" (over the chip's {limit_per_camera})" if n > limit_per_camera else ""
    return f"{n}{over}"


def cost_row(p: dict, acc: dict) -> list[str]:
    lays = p["layers"]
    clean, noisy = acc["clean"][p["variant"]], acc["noise 8"][p["variant"]]
    return [
        p["variant"],
        ", ".join(f"{la['kernel']}: {la['c_in']} -> {la['c_out']}" for la in lays),
        f"{p['macs_per_pixel']:,}",
        ", ".join(str(la["rows"]) for la in lays),
        ", ".join(f"{la['rows']} x {la['width']} x {la['c_in']} x 8 = {la['bits']:,}"
                  for la in lays),
        f"{p['lb_bits']:,} bits = {p['lb_bits'] / 8192:.1f} KiB",
        f"{p['hidden_bytes'] / 1e6:.1f} MB" if p["hidden_bytes"] else "none",
        f"{clean[0]:.2f} ({clean[1]:.2f})",
        f"{noisy[0]:.2f} ({noisy[1]:.2f})",
    ]


def rate_row(p: dict, c: dict | None) -> list[str]:
    limit = CHIP["nna.submodules"] // 2
    return [
        p["variant"],
        ", ".join(str(s) for s in p["shares"]),
        ", ".join(str(s) for s in p["layer_ii"]),
        f"{p['fps_formula']:.3f}",
        f"{p['fps_plan']:.3f}",
        f"{c['fps_measured']:.3f}" if c else MISSING,
        f"{c['sustained_fps']:.3f}" if c else MISSING,
        f"{c['bottleneck']}" if c else MISSING,
        _need_cell(p["need"][30], limit),
        _need_cell(p["need"][60], limit),
    ]


def time_row(p: dict, c: dict | None) -> list[str]:
    return [
        p["variant"],
        f"{p['first_formula'][-1]:,}",
        f"{c['first_cycle']:,} ({c['first_us']:.1f} us)" if c else MISSING,
        ", ".join(f"{x:,}" for x in c["per_layer_first"]) if c else MISSING,
        f"{c['energy_uj']:,.0f} ({c['nna_uj']:,.0f})" if c else MISSING,
        f"{c['energy_uj'] * 30 / 1e3:.0f}" if c else MISSING,
    ]


def fill_row(p: dict, c: dict | None) -> list[str]:
    period_ms = 1e3 / p["fps_formula"]
    if not c:
        return [p["variant"], f"{period_ms:.3f}", *[MISSING] * 4]
    diff_us = (c["frame_ms"] - period_ms) * 1e3
    return [p["variant"], f"{period_ms:.3f}", f"{c['frame_ms']:.3f}", f"{diff_us:.1f}",
            f"{c['first_us']:.1f}", f"{diff_us - c['first_us']:.1f}"]


def formula_lines(p: dict) -> list[str]:
    """The hand arithmetic of a network's fps and first descriptor, numbers filled in."""
    h, w = p["shape"]
    f_mhz = p["f_hz"] / 1e6
    ii = ", ".join(f"ceil({mm:,} / {s}) = {c}" for mm, s, c in
                    zip(p["m"], p["shares"], p["layer_ii"], strict=True))
    lines = [
        f"- **{p['variant']}**: m_l = {', '.join(f'{x:,}' for x in p['m'])} "
        f"(sum {p['macs_per_pixel']:,}); MAC shares (of {p['macs']}) "
        f"{', '.join(str(s) for s in p['shares'])}; II_l = {ii}; "
        f"fps = {f_mhz:g}e6 / ({p['nna_ii']} x {w} x {h}) = {p['fps_formula']:.3f}.",
    ]
    for target in TARGETS:
        nd = p["need"][target]
        text = f"  - {target} fps: ceil({target} / {p['fps_formula']:.3f}) = {nd['ceil']} a camera"
        if nd["plan"] == nd["ceil"]:
            text += f"; the plan gives {nd['fps_at_ceil']:.3f} fps with {nd['ceil']}."
        else:
            text += (f", but the plan gives {nd['fps_at_ceil']:.3f} fps with {nd['ceil']} (a "
                     "column tile's earlier layers also compute a halo of the later layers' "
                     f"half kernels); {nd['plan']} give {nd['fps_at_plan']:.3f}.")
        lines.append(text)
    halves = ", ".join(str(x) for x in p["halves"])
    lines.append(f"  - first outputs (h_l = {halves}): "
                 f"{', '.join(f'{x:,}' for x in p['first_formula'])} cycles.")
    return lines


def sva_drain_line(variant: str, shape=SHAPE) -> str:
    """The SVA's time after the NNA's last descriptor (the SVA keeping up before it): its last
    r + 1 box rows wait for the last input row (box radius r); the first of them starts r slot
    IIs a later (its look-ahead slots), the rows' words follow at II and each later row's first
    max(II, (r + 1) a) after the previous row's last (``sim.cycle.rules.sva_row_issue_tick``);
    the last word leaves with the median's S = m W + m flush ticks and L cycles later."""
    cfg = load_config(overrides=overrides(variant))
    sva = build_plan(cfg, shape).block("sva")
    r, a, ii, s_ = sva.lookahead, sva.slot_ii, sva.ii, sva.skew
    w = shape[1]
    gap = max(ii, (r + 1) * a)
    cycles = r * a + (r + 1) * (w - 1) * ii + r * gap + s_ + sva.latency
    return (f"After the NNA's last descriptor the SVA still owes its last r + 1 box rows (box "
            f"radius r = {r}) at II = {ii} cycles a word: r a + (r + 1)(W - 1) II + r max(II, "
            f"(r + 1) a) + S + L = {r} x {a} + {r + 1} x {w - 1} x {ii} + {r} x {gap} + {s_} + "
            f"{sva.latency} = {cycles:,} SVA cycles (slot II a = {a}, the median's skew S = "
            f"{s_}, latency L = {sva.latency}) = {cycles / cfg.clocks.sva_mhz:.1f} us at "
            f"{cfg.clocks.sva_mhz:g} MHz (the same for every network).")


def block_lines(plans: list[dict], acc: dict, cycles: dict | None) -> list[str]:
    """The generated block of docs/hardware-study.md (cycle cells :data:`MISSING` when
    ``cycles`` is None)."""
    cyc = cycles or {}
    keys = ", ".join(f"`{k} = {v}`" for k, v in CHIP.items())
    lines = [
        f"1280x720, {keys}; per network `nna.cnn.weights` = its int8 artifact and "
        "`nna.line_buffer_rows` = K_0 + 1. Generated by `python benchmarks/hardware_study.py "
        "--write`; accuracy from the ablation's JSON (" + "; ".join(
            f"{cond}: `{cmd}`" for cond, (_, cmd) in ACCURACY.items()) + ").",
        "",
        COST_HEAD, _rule(COST_KINDS),
        *(_row(cost_row(p, acc)) for p in plans),
        "",
        RATE_HEAD, _rule(RATE_KINDS),
        *(_row(rate_row(p, cyc.get(p["variant"]))) for p in plans),
        "",
        TIME_HEAD, _rule(TIME_KINDS),
        *(_row(time_row(p, cyc.get(p["variant"]))) for p in plans),
        "",
        FILL_HEAD, _rule(FILL_KINDS),
        *(_row(fill_row(p, cyc.get(p["variant"]))) for p in plans),
        "",
        "The arithmetic (f = NNA clock, W x H = 1280 x 720, one submodule a camera, memory "
        "source; m_l = K_l^2 C_in,l C_out,l, macs_l its share, II_l = ceil(m_l / macs_l), "
        "fps = f / (max_l II_l x W x H)):",
        "",
    ]
    for p in plans:
        lines += formula_lines(p)
    lines += ["", sva_drain_line(plans[0]["variant"], plans[0]["shape"])]
    engines = sorted({c["engine"] for c in cyc.values()}) or [MISSING]
    lines += ["", f"Cycle model engine: {', '.join(engines)}."]
    return lines


def masked(lines: list[str]) -> list[str]:
    """``lines`` with the cycle model's cells of each table (and the engine line) replaced by
    :data:`MISSING`: what ``--check`` compares."""
    out, kinds = [], None
    for line in lines:
        if line in TABLES:
            kinds = TABLES[line]
        elif kinds and line.startswith("|") and not line.startswith("|---"):
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            line = _row(MISSING if k == "cycle" else c for c, k in zip(cells, kinds,
                                                                        strict=True))
        elif not line.startswith("|"):
            kinds = None
        if not line.startswith("Cycle model engine:"):
            out.append(line)
    return out


def current() -> list[str]:
    text = DOC.read_text()
    if BEGIN not in text or END not in text:
        print(f"hardware_study: {DOC} lacks the {BEGIN} / {END} markers", file=sys.stderr)
        sys.exit(2)
    return text.split(BEGIN, 1)[1].split(END, 1)[0].strip("\n").split("\n")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mode = ap.add_mutually_exclusive_group()
    mode.add_argument("--write", action="store_true", help=f"put the block into {DOC.name}")
    mode.add_argument("--check", action="store_true",
                      help="exit 1 if the page's plan, formula or accuracy figures differ "
                           "(no cycle model run)")
    args = ap.parse_args(argv)
    acc = accuracy()
    plans = [plan_figures(v) for v in NETWORKS]
    if args.check:
        want, have = masked(block_lines(plans, acc, None)), masked(current())
        if want == have:
            print(f"{DOC.name}: up to date")
            return 0
        sys.stdout.writelines(difflib.unified_diff(
            [x + "\n" for x in have], [x + "\n" for x in want], "page", "script"))
        return 1
    cycles = {}
    for p in plans:
        print(f"cycle model: {p['variant']}", file=sys.stderr)
        cycles[p["variant"]] = cycle_figures(p["variant"], p["first_formula"][-1])
    lines = block_lines(plans, acc, cycles)
    if args.write:
        return write_between(DOC, BEGIN, END, lines)
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
