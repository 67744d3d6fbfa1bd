"""The figures the documentation quotes, generated into the pages by the code that measures them.

A generated block sits between two marker comments, ``<!-- NAME:begin -->`` and
``<!-- NAME:end -->``. Every block of docs/ is listed here with the command that writes it:
the blocks of this script (:data:`FIGURES`, cheap: a few 720p and 1080p frames of the cycle
model, short 720p streams, the points of two 720p sweeps, a multiply-shift search, the import
layers of pyproject.toml, the traced runs of reading-traces.md's default scene, what
``stereosim run`` prints for a 64 x 24 pair) and the
blocks other scripts write (:data:`ELSEWHERE`: accuracy tables, sweeps, minutes to hours).
``tests/benchmarks/test_doc_figures.py`` re-runs this script's blocks and requires the pages
to hold exactly what they print, and requires every block of docs/ to be listed here with a
command its page names.

    python benchmarks/doc_figures.py            # print every block of this script
    python benchmarks/doc_figures.py --write    # put them into their pages
    python benchmarks/doc_figures.py --check    # exit 1 (with a diff) if a page is stale
    python benchmarks/doc_figures.py calibration --write   # one block
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import difflib
import functools
import io
import re
import sys
import tempfile
import textwrap
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import reading_traces
import rule_table
from markers import write_between

from stereosim.core.config import load_config
from stereosim.core.io import encode_png
from stereosim.quant.quantizer import search_mul_shift
from stereosim.sim.api import run, run_stream
from stereosim.sim.cli import main as stereosim_main
from stereosim.sim.cycle.contract import CameraOverflow
from stereosim.sim.cycle.estimate import estimate
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.readable.beats import BEATS
from stereosim.sim.cycle.rules import ClockDomain
from stereosim.sim.plot import rate_gaps
from stereosim.sim.sweep import load_sweep, run_task, synthetic_pair
from stereosim.sim.sweep_results import read_rows, write_rows
from stereosim.sim.synthetic_trace import synthetic_log
from stereosim.sim.whatif_cli import sweep_summary
from stereosim.traces.fst import fst_bytes
from stereosim.traces.log import Clock, Signal, TraceLog
from stereosim.traces.vcd import vcd_bytes

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
COMMAND = "python benchmarks/doc_figures.py --write"


@dataclass(frozen=True)
class Figure:
    """A generated block: its page (in docs/) and the function that measures its lines."""

    doc: str
    lines: Callable[[], list[str]]


def _run_720p(overrides: dict) -> dict:
    """The cycle report of one 1280x720 frame (a synthetic textured pair: cycle counts do not
    depend on the pixels) at D = 128."""
    return _run_frame((720, 1280), tuple(sorted(overrides.items())))


@functools.cache
def _run_frame(shape: tuple[int, int], overrides: tuple) -> dict:
    """The cycle report of one frame of ``shape`` at D = 128, run once per process: several
    blocks quote the same runs (the report is shared: read it, never change it)."""
    left, right = synthetic_pair(*shape)
    cfg = load_config(overrides={"sva.disparities": 128, **dict(overrides)})
    return run(left, right, mode="cycle", config=cfg).report


RUNS_720P = (("defaults (CNN descriptor)", {}),
             ("`--descriptor census`", {"nna.descriptor": "census"}))


def calibration() -> list[str]:
    """docs/architecture.md, "Calibration": the default chip (CNN descriptor) and the census
    one at 720p -- cycles, first output, the frame's span, the work bound and the measured
    rate, the bottleneck -- and the analytic estimate's first output and frame beside them."""
    lines = ["| run | cycles (nna / sva) | first output | frame (first input pixel to last "
             "word) | estimate: first output, frame | fps (work bound) | fps (measured) | "
             "bottleneck |",
             "|---|---|---|---|---|---|---|---|"]
    for name, over in RUNS_720P:
        rep = _run_720p(over)
        est = estimate(load_config(overrides={"sva.disparities": 128, **over}),
                       (720, 1280))["latency"]
        cycles, thr, lat = rep["cycles"]["total"], rep["throughput"], rep["latency"]
        lines.append(
            f"| {name} | {cycles['nna']:,} / {cycles['sva']:,} | "
            f"{lat['first_output_us']:.3f} us | {lat['frame_ms']:.6f} ms | "
            f"{est['first_output_us']:.3f} us, {est['frame_ms']:.6f} ms | "
            f"{thr['fps_bound']:.3f} | {thr['fps_measured']:.3f} | {thr['bottleneck']} |")
    return lines


def row_windows() -> list[str]:
    """docs/architecture.md, "Row windows": the most each row window (and the FIFO in front of
    the NNA) held in the calibration runs, beside its capacity."""
    lines = ["| run | NNA line buffer (rows) | source-to-NNA FIFO (pixels) | NNA-to-SVA FIFO "
             "(descriptors) | SVA descriptor rows | bottleneck |",
             "|---|---|---|---|---|---|"]
    for name, over in RUNS_720P:
        rep = _run_720p(over)
        nna = rep["buffers"]["nna_left"]["nna.line_buffer"]
        sva = rep["buffers"]["sva"]["sva.descriptor_rows"]
        src, n2s = rep["fifos"]["src_left_to_nna"], rep["fifos"]["nna_left_to_sva"]
        lines.append(
            f"| {name} | {nna['peak_rows']} of {nna['capacity_rows']} | "
            f"{src['max_occupancy']} of {src['depth']} | {n2s['max_occupancy']} of "
            f"{n2s['depth']} | {sva['peak_rows']} of {sva['capacity_rows']} | "
            f"{rep['throughput']['bottleneck']} |")
    return lines


def splits() -> list[str]:
    """docs/architecture.md, "Splits": a 1920x1080 frame on 6 NNA submodules (3 column tiles a
    camera) with the default merge FIFOs and with the depth ``stereosim estimate`` says the
    tiles need (``throughput.merge_depth_needed``)."""
    six = (("nna.stereo_submodules", 6),)
    need = estimate(load_config(overrides={"sva.disparities": 128, **dict(six)}),
                    (1080, 1920))["throughput"]["merge_depth_needed"]
    lines = ["| `fifo.nna_to_merge_depth` | frame (first input pixel to last word) | "
             "fps (measured) | fps (work bound) | bottleneck |",
             "|---|---|---|---|---|"]
    for depth in (64, need):
        rep = _run_frame((1080, 1920), (("fifo.nna_to_merge_depth", depth), *six))
        thr = rep["throughput"]
        label = f"{depth} (the estimate's need)" if depth == need else f"{depth} (default)"
        lines.append(f"| {label} | {rep['latency']['frame_ms']:.3f} ms | "
                     f"{thr['fps_measured']:.3f} | {thr['fps_bound']:.3f} | "
                     f"{thr['bottleneck']} |")
    return lines


def layers() -> list[str]:
    """docs/architecture.md, "Layers": the layers contract of pyproject.toml, top to bottom
    (a module may import only from the lines below its own)."""
    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
    (layered,) = [c for c in contracts["contracts"] if c["id"] == "layers"]
    return ["```", *(", ".join(m.strip() for m in layer.split(":"))
                     for layer in layered["layers"]), "```"]


def _modules(package: Path) -> list[str]:
    """The modules of a sub-package of sim/cycle, a sub-folder's as ``folder/name``."""
    names = [p.stem for p in sorted(package.glob("*.py")) if p.stem != "__init__"]
    for sub in sorted(d for d in package.iterdir() if (d / "__init__.py").exists()):
        names += [f"{sub.name}/{p.stem}" for p in sorted(sub.glob("*.py"))
                  if p.stem != "__init__"]
    return names


def engines() -> list[str]:
    """docs/architecture.md, "Two engines": the layers of the import contract ``engines`` of
    pyproject.toml (sim/cycle, top to bottom: a line imports only from the lines below it;
    ``|`` joins siblings that import neither each other), the engines with their modules read
    off their folders."""
    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
    (layered,) = [c for c in contracts["contracts"] if c["id"] == "engines"]
    cycle = ROOT / "sim" / "cycle"
    col = 38
    rows = []
    for layer in layered["layers"]:
        if "|" in layer:
            parts = [m.strip() for m in layer.split("|")]
            columns = [[f"{m}/"] + [f"  {name}" for name in _modules(cycle / m)] for m in parts]
            rows += ["      /" + " " * (col - 4) + "\\"]
            for i in range(max(map(len, columns))):
                cells = [c[i] if i < len(c) else "" for c in columns]
                rows.append("  " + "".join(cell.ljust(col) for cell in cells).rstrip())
            rows += ["      \\" + " " * (col - 4) + "/   (neither imports the other)"]
        else:
            rows += ["  " + "   ".join(m.strip() for m in layer.split(":")), "        |"]
    if rows[-1].strip() == "|":
        rows.pop()
    return ["```", *rows, "```", "", *twins()]


TWIN = re.compile(r"twin (?:of|is) the readable kernel's\s+:(?:mod|class):`~?([\w.]+)`")


def twins() -> list[str]:
    """Each compiled module beside the readable module its docstring names as its twin."""
    lines = ["| compiled engine | its readable twin | what the compiled module holds |",
             "|---|---|---|"]
    for path in sorted((ROOT / "sim" / "cycle" / "compiled").glob("*.py")):
        doc = ast.get_docstring(ast.parse(path.read_text())) or ""
        found = TWIN.search(" ".join(doc.split()))
        if found is None:
            continue
        parts = found.group(1).removeprefix("sim.cycle.readable.").split(".")
        cls = f": {parts.pop()}" if parts[-1][0].isupper() else ""
        first = " ".join(doc.split("\n\n")[0].split())
        lines.append(f"| `compiled/{path.name}` | `readable/{'/'.join(parts)}.py{cls}` | "
                     f"{first.split(' (')[0].rstrip('.')} |")
    return lines


def beats() -> list[str]:
    """docs/architecture.md, "Beats": the kinds of beat the readable chip's FIFOs carry, from
    their types (sim/cycle/readable/beats.py)."""
    lines = ["| beat | what, from where to where | pushed by (block kind) | fields | on the wire "
             "(the FIFO's width) |", "|---|---|---|---|---|"]
    for beat in BEATS:
        lines.append(f"| `{beat.__name__}` | {' '.join(beat.__doc__.split())} | "
                     f"{', '.join(beat.pushed_by)} | `{', '.join(beat._fields)}` | {beat.wire} |")
    return lines


SVA_STAGE_POINTS = (
    ("the defaults (D = 128, 128 lanes, 4 paths, LR check, 1r1w SRAM)", {}),
    ("`--set sva.lanes=64 --set sva.sram_ports=1rw`", {"sva.lanes": 64, "sva.sram_ports": "1rw"}),
)


def sva_stages_table() -> list[str]:
    """docs/architecture.md, "The SVA's stages": each stage's II, latency, the arithmetic behind
    both and its SRAM, as the plan builds them (:func:`sim.cycle.stages.sva_stages`) for a
    1280x720 CNN frame, at the defaults and with half the lanes on single-port SRAM."""
    lines = []
    for title, over in SVA_STAGE_POINTS:
        plan = build_plan(load_config(overrides=over), (720, 1280))
        sva = next(b for b in plan.blocks if b.kind == "sva")
        lines += [f"**{title}**: II {max(st.ii for st in sva.stages)}, latency "
                  f"{sum(st.latency for st in sva.stages)} cycles", "",
                  "| stage | II | latency | how (the plan's formula) | SRAM and registers |",
                  "|---|---|---|---|---|"]
        for st in sva.stages:
            store = "; ".join(f"`{b.name}` {b.bits:,} bits"
                              + (f" ({b.ports}: {b.reads} r + {b.writes} w per pixel)"
                                 if b.ports else "") for b in st.buffers)
            lines.append(f"| {st.name} | {st.ii} | {st.latency} | {st.formula} | {store} |")
        lines.append("")
    return lines[:-1]


def energy_720p() -> list[str]:
    """docs/energy.md, "What is counted": the energy of a 720p frame at the defaults and with
    the paper's 2-path option, by block, the SGM's previous-row SRAM apart."""
    lines = ["| run (1280x720, D = 128) | energy per frame | NNA | SVA | of which the SGM's "
             "previous-row SRAM | FIFOs | DRAM | power at the work bound |",
             "|---|---|---|---|---|---|---|---|"]
    for name, over in (("defaults (CNN descriptor, 4 paths, LR check)", {}),
                       ("`--set sva.paths=2`", {"sva.paths": 2})):
        energy = _run_720p(over)["energy"]
        block = energy["per_frame_uj"]["by_block"]
        total = energy["per_frame_uj"]["total"]
        sgm_uj = sum(i["count"] * i["pj_each"] for i in energy["items"]
                     if i["what"].startswith("sva.sgm_previous_row")) * 1e-6
        lines.append(
            f"| {name} | {total / 1e3:.2f} mJ | {block['nna'] / 1e3:.2f} mJ | "
            f"{block['sva'] / 1e3:.2f} mJ | {sgm_uj / 1e3:.2f} mJ ({100 * sgm_uj / total:.0f} %) "
            f"| {block['fifos'] / 1e3:.2f} mJ | {block['dram'] / 1e3:.2f} mJ | "
            f"{energy['power_mw']:.1f} mW at {energy['power_at_fps']:.3f} fps |")
    return lines


def dram_defaults() -> list[str]:
    """docs/dram.md, "The report": a stream of three 720p frames (the defaults) without and
    with the DRAM channel."""
    left, right = synthetic_pair(720, 1280)
    lines = ["| `dram.model` | slot | slots a round (read + write-back) | bandwidth of the "
             "read slots | stall cycles of a memory source (NNA) | stall cycles of the sink "
             "(SVA) | utilisation | sustained fps |",
             "|---|---|---|---|---|---|---|---|"]
    for model in ("none", "tdm"):
        rep = run_stream([(left, right)] * 3, config=load_config(
            overrides={"sva.disparities": 128, "dram.model": model})).report
        fps = f"{rep['stream']['sustained_fps']:.3f}"
        if model == "none":
            lines.append(f"| none | | | | | | | {fps} |")
            continue
        dram, clients = rep["dram"], rep["dram"]["clients"]
        lines.append(
            f"| tdm | {dram['slot_ns']:.3f} ns | {dram['round_slots']} "
            f"({clients['read']['slots_per_round']} + "
            f"{clients['write_back']['slots_per_round']}) | "
            f"{clients['read']['slot_gbps']:.1f} GB/s | {dram['stall_cycles']['memory_left']} | "
            f"{dram['stall_cycles']['sink']} | {100 * dram['utilisation']:.2f} % | {fps} |")
    return lines


def requant_example() -> list[str]:
    """docs/quantization.md, "Worked example": the multiply-shift searched for the wanted ratio
    1/256 over the accumulators -5000..40000, at z = 8 and z = 4."""
    acc = np.arange(-5000, 40001)
    lines = ["| z | (m, h) | m / 2^h | mean error |", "|---|---|---|---|"]
    for z_bits in (8, 4):
        m, h, err = search_mul_shift(acc, acc / 256, z_bits=z_bits)
        lines.append(f"| {z_bits} | ({m}, {h}) | {m / 2**h:.6f} | {err:.3f} |")
    return lines


# ---- what a command prints (report.md, reliability.md, streams.md) ---------------------------


class OutcomeChanged(RuntimeError):
    """A command no longer ends as the page that quotes it says (a run that should stop
    completes, say): the page's prose needs rewriting, not only its block."""


@contextlib.contextmanager
def _scratch():
    """A fresh temporary folder as the working directory: the quoted commands name their
    files relatively (``--out out``), as a reader types them."""
    with tempfile.TemporaryDirectory() as tmp, contextlib.chdir(tmp):
        yield


def _stereosim(argv: list[str]) -> tuple[int, str, str]:
    """``stereosim ARGV`` run in this process: its exit status, stdout and stderr."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = stereosim_main(argv)
    return status, out.getvalue(), err.getvalue()


def _prose(text: str) -> list[str]:
    """A sentence of a block, wrapped as the pages wrap their prose."""
    return textwrap.wrap(text, 96, break_long_words=False, break_on_hyphens=False)


def _error_line(argv: list[str]) -> str:
    """The one line ``stereosim ARGV`` refuses or stops with (exit status 2)."""
    status, _, err = _stereosim(argv)
    lines = [line for line in err.splitlines()
             if line.startswith(("stereosim: error:", "stereosim: stopped"))]
    if status != 2 or len(lines) != 1:
        raise OutcomeChanged(f"stereosim {' '.join(argv)} exited {status}, not 2 with one line")
    return lines[0]


# The small pair of the pages' examples: l.png and r.png, 64 x 24 (synthetic_pair(24, 64)).
SMALL_RUN = ["run", "--left", "l.png", "--right", "r.png", "--disparities", "16"]


def _small_pair() -> None:
    for name, image in zip(("l.png", "r.png"), synthetic_pair(24, 64)):
        Path(name).write_bytes(encode_png(image))


def run_summary() -> list[str]:
    """docs/report.md, "The summary": what ``stereosim run`` prints, piped, for the 64 x 24
    pair at D = 16 -- its throughput and blocks tables, the right camera's rows left out."""
    with _scratch():
        _small_pair()
        status, out, _ = _stereosim([*SMALL_RUN, "--out", "out"])
    if status != 0:
        raise OutcomeChanged(f"stereosim {' '.join(SMALL_RUN)} exited {status}")
    tables = [t for t in out.split("\n\n")
              if t.startswith(("throughput and latency", "blocks ("))]
    lines = [line for line in "\n\n".join(tables).splitlines() if "_right " not in line]
    return ["```", *lines, "```", "",
            *_prose(f"(`stereosim {' '.join(SMALL_RUN)} --out out | cat` on a 64 x 24 pair, "
                    "`stereosim.sim.sweep.synthetic_pair(24, 64)` written as PNGs; the run "
                    "table above these, the energy below them and the right camera's rows "
                    "left out.)")]


STOP_RUN = [*SMALL_RUN, "--set", "nna.descriptor=census", "--max-cycles", "2000",
            "--vcd", "out/t.vcd", "--out", "out"]


def stop_line() -> list[str]:
    """docs/reliability.md, "Stops you can inspect": the line of a run stopped by
    ``--max-cycles`` (the 64 x 24 pair, census), wrapped for the page."""
    with _scratch():
        _small_pair()
        line = _error_line(STOP_RUN)
    return ["```", *_prose(line), "```", "",
            *_prose(f"(one line in reality; `stereosim {' '.join(STOP_RUN)}` on a 64 x 24 "
                    "pair, `stereosim.sim.sweep.synthetic_pair(24, 64)` written as PNGs.)")]


def frame_cap() -> list[str]:
    """docs/streams.md, "How long a stream may be": the line refusing 10^9 frames."""
    with _scratch():
        return ["```", _error_line(["run", "--frames", "1000000000", "--out", "out"]), "```"]


# The 720p streams of docs/streams.md: the defaults (a memory source), a CEA-861 720p60 camera
# straight into the NNA, the same camera into two frame buffers (the paper-720p preset), and
# two NNA submodules per camera behind the camera with deep and default merge FIFOs.
CAMERA = {"source.kind": "camera"}
STREAMS_720P = (
    ("defaults (a memory source)", {}, 3),
    ("`source.kind=camera`", CAMERA, 3),
    ("`source.kind=camera`, `source.frame_buffers=2`, `source.on_overflow=drop_frame` "
     "(`--config paper-720p`)",
     {**CAMERA, "source.frame_buffers": 2, "source.on_overflow": "drop_frame"}, 30),
    ("`source.kind=camera`, `nna.stereo_submodules=4`, `fifo.nna_to_merge_depth=1024`",
     {**CAMERA, "nna.stereo_submodules": 4, "fifo.nna_to_merge_depth": 1024}, 5),
    ("`source.kind=camera`, `nna.stereo_submodules=4` (merge FIFOs at the default 64)",
     {**CAMERA, "nna.stereo_submodules": 4}, 5),
)


def stream_720p() -> list[str]:
    """docs/streams.md, "Cost" and the camera paragraph: short 720p streams of the pair
    repeated (cycle counts do not depend on the pixels), D = 128 -- what each sustains, its
    drops and latencies, or where it stops."""
    left, right = synthetic_pair(720, 1280)
    lines = ["| `--set` (1280x720, D = 128) | frames | taken | dropped (camera frame) | "
             "sustained fps | work bound (bottleneck) | latency min / median / max |",
             "|---|---|---|---|---|---|---|"]
    for name, over, frames in STREAMS_720P:
        cfg = load_config(overrides={"sva.disparities": 128, **over})
        try:
            rep = run_stream([(left, right)] * frames, config=cfg).report
        except CameraOverflow as stop:
            first = str(stop).split(";")[0].split(": ")[0]
            lines.append(f"| {name} | {frames} | stops: {first} | | | | |")
            continue
        st, thr = rep["stream"], rep["throughput"]
        lat = st["latency_ms"]
        dropped = f"{st['frames_dropped']}"
        if st["dropped_frames"]:
            dropped += f" ({', '.join(map(str, st['dropped_frames']))})"
        lines.append(
            f"| {name} | {frames} | {st['frames_completed']} | {dropped} | "
            f"{st['sustained_fps']:.3f} | {thr['fps_bound']:.3f} ({thr['bottleneck']}) | "
            f"{lat['min']:.2f} / {lat['median']:.2f} / {lat['max']:.2f} ms |")
    return lines


# ---- traces.md -------------------------------------------------------------------------------


def vcd_example() -> list[str]:
    """docs/traces.md, "VCD": the whole dump of a small log -- the chip's NNA and SVA clocks,
    a 1-bit valid, a line-buffer fill that is 9 at the window's start and a FIFO occupancy,
    over 4.4 ns."""
    cfg = load_config()
    clocks = [Clock(name, dom.period_fs, dom.phase_fs)
              for name, dom in (("nna", ClockDomain("nna", cfg.clocks.nna_mhz * 1e6)),
                                ("sva", ClockDomain("sva", cfg.clocks.sva_mhz * 1e6)))]
    nna, sva = clocks[0].period_fs, clocks[1].period_fs
    log = TraceLog(
        signals=[Signal("top.nna.left.valid", 1, "nna"), Signal("top.nna.left.fill", 16, "nna"),
                 Signal("top.fifo.a_to_b.occupancy", 5, "sva")],
        clocks=clocks, start_fs=0, end_fs=4_400_000,
        initial=np.zeros(3, np.uint64),
        times_fs=np.array([0, nna, nna, 2 * sva], np.int64),
        ids=np.array([1, 0, 1, 2], np.int32),
        values=np.array([9, 1, 10, 3], np.uint64))
    return ["```", *vcd_bytes(log).decode("ascii").splitlines(), "```"]


def trace_signals() -> list[str]:
    """docs/traces.md, "Signal names": how many signals the chip plan traces."""
    counts = [len(build_plan(load_config(overrides=over), (720, 1280)).signals)
              for over in ({}, {"nna.stereo_submodules": 4})]
    return _prose(f"`ChipPlan.signals` lists {counts[0]} signals for the default chip, "
                  f"{counts[1]} with two submodules per camera (`nna.stereo_submodules = 4`).")


def fst_size() -> list[str]:
    """docs/traces.md, "FST": the VCD and the FST of one synthetic log."""
    log = synthetic_log(2000, seed=0)
    vcd, fst = len(vcd_bytes(log)), len(fst_bytes(log))
    return _prose(f"For the synthetic 2,000-SVA-cycle log of "
                  f"`sim.synthetic_trace.synthetic_log(2000)`: {vcd / 1e3:,.0f} kB of VCD, "
                  f"{fst / 1e3:,.0f} kB of FST ({vcd / fst:.1f} times smaller).")


# ---- whatif.md -------------------------------------------------------------------------------


@functools.cache
def _study(name: str) -> tuple[list[dict], list[str]]:
    """The rows ``stereosim sweep docs/studies/NAME.toml`` computes (each point run in this
    process by the sweep's own ``run_task``, read back through its CSV) and its swept keys."""
    sweep = load_sweep(DOCS / "studies" / f"{name}.toml")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "results.csv"
        write_rows(path, [run_task(task) for task in sweep.tasks], sweep.axes)
        return read_rows(path), sweep.axes


def study_fifo() -> list[str]:
    """docs/whatif.md, study 2: the NNA->SVA FIFO at each depth behind a 720p60 camera
    (census); depths that give the same figures share a row, the least that never fills is
    bold."""
    rows, _ = _study("fifo_720p")
    fifo = "fifos.nna_left_to_sva"
    cols = (f"{fifo}.max_producer_occupancy", f"{fifo}.cycles_full", "latency.frame_ms",
            "estimate.latency.frame_ms", "throughput.fps_measured")
    groups: list[tuple[list[str], tuple]] = []
    for r in rows:
        key = tuple(r[c] for c in cols)
        if groups and groups[-1][1] == key:
            groups[-1][0].append(r["fifo.nna_to_sva_depth"])
        else:
            groups.append(([r["fifo.nna_to_sva_depth"]], key))
    lines = ["| depth | high-water (producer view) | cycles the NNA saw it full | frame latency | "
             "frame latency, estimate | fps, measured (one frame) |", "|---|---|---|---|---|---|"]
    answer = next(i for i, (_, key) in enumerate(groups) if int(key[1]) == 0)
    for i, (depths, (high, full, frame, est, fps)) in enumerate(groups):
        depth, full = ", ".join(depths), f"{int(full):,}"
        if i == answer:
            depth, full = f"**{depth}**", f"**{full}**"
        lines.append(f"| {depth} | {high} | {full} | {float(frame):.4f} ms | "
                     f"{float(est):.4f} ms | {float(fps):.1f} |")
    return lines


def study_merge() -> list[str]:
    """docs/whatif.md, study 4: column tiles and their merge FIFOs at 720p; a measured rate
    more than the sweep's RATE_GAP off its work bound is bold."""
    rows, _ = _study("merge_720p")
    gaps = {r["point_id"] for r in rate_gaps(rows)}
    lines = ["| stereo submodules | merge FIFOs | fps, work bound | fps, measured (one frame) | "
             "frame | merge FIFOs needed (estimate) | chip SRAM (bits) |",
             "|---|---|---|---|---|---|---|"]
    unsplit = set()
    for r in rows:
        need = r["estimate.throughput.merge_depth_needed"]
        subs = r["nna.stereo_submodules"]
        if not need:  # no column tiles, no merge: one row whatever the merge depth
            if subs in unsplit:
                continue
            unsplit.add(subs)
            subs, depth, need = f"{subs} (no merge)", "--", "--"
        else:
            depth = r["fifo.nna_to_merge_depth"]
        fps = f"{float(r['throughput.fps_measured']):.1f}"
        if r["point_id"] in gaps:
            fps = f"**{fps}**"
        lines.append(f"| {subs} | {depth} | {float(r['throughput.fps_bound']):.1f} | {fps} | "
                     f"{float(r['latency.frame_ms']):.3f} ms | {need} | "
                     f"{int(r['sram_bits']):,} |")
    return lines


def study_merge_summary() -> list[str]:
    """docs/whatif.md, "What a sweep plots and prints": what ``stereosim sweep`` prints of
    study 4's rows after its count line (``sweep_summary``, the function it calls)."""
    rows, axes = _study("merge_720p")
    return ["```", *sweep_summary(rows, axes), "```"]


def row_bands() -> list[str]:
    """docs/whatif.md, row bands: a 16x48 CNN frame (D = 16) on one submodule per camera, on
    two row bands and on two column tiles -- work bound and last word."""
    left, right = synthetic_pair(16, 48)
    lines = ["| 16x48 CNN frame, D = 16 | fps (work bound) | last word (SVA cycle) |",
             "|---|---|---|"]
    for name, over in (("one submodule per camera", {}),
                       ("two row bands (`nna.stereo_submodules=4`, `nna.split=rows`)",
                        {"nna.stereo_submodules": 4, "nna.split": "rows"}),
                       ("two column tiles (`nna.stereo_submodules=4`)",
                        {"nna.stereo_submodules": 4})):
        cfg = load_config(overrides={"nna.descriptor": "cnn", "sva.disparities": 16, **over})
        rep = run(left, right, mode="cycle", config=cfg).report
        lines.append(f"| {name} | {rep['throughput']['fps_bound']:,.1f} | "
                     f"{rep['cycles']['last_output']['sva']:,} |")
    return lines


FIGURES = {
    "calibration": Figure("architecture.md", calibration),
    "row-windows": Figure("architecture.md", row_windows),
    "splits": Figure("architecture.md", splits),
    "layers": Figure("architecture.md", layers),
    "engines": Figure("architecture.md", engines),
    "rules": Figure("architecture.md", rule_table.table),
    "beats": Figure("architecture.md", beats),
    "sva-stages": Figure("architecture.md", sva_stages_table),
    "energy-720p": Figure("energy.md", energy_720p),
    "dram-defaults": Figure("dram.md", dram_defaults),
    "requant-example": Figure("quantization.md", requant_example),
    "run-summary": Figure("report.md", run_summary),
    "stop-line": Figure("reliability.md", stop_line),
    "frame-cap": Figure("streams.md", frame_cap),
    "stream-720p": Figure("streams.md", stream_720p),
    "vcd-example": Figure("traces.md", vcd_example),
    "trace-signals": Figure("traces.md", trace_signals),
    "fst-size": Figure("traces.md", fst_size),
    "study-fifo": Figure("whatif.md", study_fifo),
    "study-merge": Figure("whatif.md", study_merge),
    "study-merge-summary": Figure("whatif.md", study_merge_summary),
    "row-bands": Figure("whatif.md", row_bands),
    # reading-traces.md: the instants its pictures show, found in traced runs of the default
    # scene (a few seconds; docs/make_trace_pictures.py draws the pictures from the same runs)
    **{name: Figure(reading_traces.DOC, functools.partial(reading_traces.block, name))
       for name in reading_traces.SECTIONS},
}

# The blocks other scripts write (slow: accuracy over the Middlebury scenes, sweeps), by name:
# the page and the command that writes the block (the page names it).
ELSEWHERE = {
    "plan": ("architecture.md", "python docs/make_plan_pictures.py"),
    "sva-whatif": ("architecture.md", "python benchmarks/sva_whatif.py --write"),
    "ablation-clean": ("ablation.md", "python benchmarks/ablation.py --write docs/ablation.md"),
    "ablation-noise": ("ablation.md",
                       "python benchmarks/ablation.py --noise 8 --seed 0 --write docs/ablation.md"),
    "ablation-architecture": ("ablation.md",
                              "python benchmarks/ablation.py --write docs/ablation.md"),
    "robustness": ("ablation.md",
                   "python benchmarks/robustness.py --seed 0 --write docs/ablation.md"),
    "spill-study": ("energy.md", "python benchmarks/descriptor_dram_study.py --write"),
    "tech-model": ("energy.md", "python -m stereosim.core.tech"),  # held by tests/core/tech
    "hardware-study": ("hardware-study.md", "python benchmarks/hardware_study.py --write"),
    "hybrid-tuning": ("hybrid.md", "python benchmarks/hybrid_tuning.py --jobs 2 --write "
                      "docs/hybrid.md"),
    "hybrid-curve": ("hybrid.md", "python benchmarks/hybrid_plot.py --write docs/hybrid.md"),
    "hybrid-whatif": ("hybrid.md", "python benchmarks/hybrid_whatif.py --write"),
    "hybrid-hardware": ("hardware-study.md", "python benchmarks/hybrid_whatif.py --write"),
    "hybrid-accuracy": ("learned-descriptor.md", "python benchmarks/hybrid_whatif.py --write"),
    "shared-sva": ("streams.md", "python benchmarks/shared_sva.py --frames 60 --write"),
    "protocol-results": ("tuning.md", "python benchmarks/tuning_report.py --write docs/tuning.md"),
}


def markers(name: str) -> tuple[str, str]:
    return f"<!-- {name}:begin -->", f"<!-- {name}:end -->"


def current(name: str) -> list[str]:
    """The lines a page holds now between the markers of ``name`` (None if it lacks them)."""
    begin, end = markers(name)
    text = (DOCS / FIGURES[name].doc).read_text()
    if begin not in text or end not in text:
        return None
    return text.split(begin, 1)[1].split(end, 1)[0].strip("\n").split("\n")


def stale(name: str, lines: list[str]) -> list[str]:
    """The diff of block ``name``'s page against ``lines`` (measured now); [] if it holds them."""
    held = current(name)
    if held == lines:
        return []
    return list(difflib.unified_diff(held or [], lines, f"docs/{FIGURES[name].doc} ({name})",
                                     "measured now", lineterm=""))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", metavar="NAME", help=f"blocks ({', '.join(FIGURES)}; "
                    "default all)")
    mode = ap.add_mutually_exclusive_group()
    mode.add_argument("--write", action="store_true", help="put the blocks into their pages")
    mode.add_argument("--check", action="store_true", help="exit 1 if a page differs")
    args = ap.parse_args(argv)
    unknown = [n for n in args.names if n not in FIGURES]
    if unknown:
        print(f"doc_figures: no block named {unknown[0]!r} (blocks: {', '.join(FIGURES)})",
              file=sys.stderr)
        return 2
    status = 0
    for name in args.names or FIGURES:
        figure = FIGURES[name]
        lines = figure.lines()
        if args.write:
            status |= write_between(DOCS / figure.doc, *markers(name), lines)
        elif args.check:
            diff = stale(name, lines)
            if diff:
                status = 1
                print("\n".join(diff))
        else:
            print("\n".join(lines))
    return status


if __name__ == "__main__":
    sys.exit(main())
