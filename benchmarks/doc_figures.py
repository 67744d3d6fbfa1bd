"""The figures the documentation quotes, generated into the pages by the code that measures them.

A generated block sits between two marker comments, ``<!-- NAME:begin -->`` and
``<!-- NAME:end -->``. Every block of docs/ is listed here with the command that writes it:
the blocks of this script (:data:`FIGURES`, cheap: a few 720p and 1080p frames of the cycle
model, a multiply-shift search, the import layers of pyproject.toml, the traced runs of
reading-traces.md's default scene) and the
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
import difflib
import functools
import sys
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import reading_traces
from markers import write_between

from stereosim.quant.quantizer import search_mul_shift
from stereosim.sim.api import run, run_stream
from stereosim.sim.config import load_config
from stereosim.sim.cycle.estimate import estimate
from stereosim.sim.sweep import synthetic_pair

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
    (layered,) = [c for c in contracts["contracts"] if c["type"] == "layers"]
    return ["```", *(", ".join(m.strip() for m in layer.split(":"))
                     for layer in layered["layers"]), "```"]


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


FIGURES = {
    "calibration": Figure("architecture.md", calibration),
    "row-windows": Figure("architecture.md", row_windows),
    "splits": Figure("architecture.md", splits),
    "layers": Figure("architecture.md", layers),
    "energy-720p": Figure("energy.md", energy_720p),
    "dram-defaults": Figure("dram.md", dram_defaults),
    "requant-example": Figure("quantization.md", requant_example),
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
    "shared-sva": ("streams.md", "python benchmarks/shared_sva.py --frames 60"),
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
            held = current(name)
            if held != lines:
                status = 1
                diff = difflib.unified_diff(held or [], lines, f"docs/{figure.doc} ({name})",
                                            "measured now", lineterm="")
                print("\n".join(diff))
        else:
            print("\n".join(lines))
    return status


if __name__ == "__main__":
    sys.exit(main())
