"""The figures the documentation quotes, generated into the pages by the code that measures them.

A generated block sits between two marker comments, ``<!-- NAME:begin -->`` and
``<!-- NAME:end -->``. Every block of docs/ is listed here with the command that writes it:
the blocks of this script (:data:`FIGURES`, cheap: a few 720p frames of the cycle model, the
traced runs of reading-traces.md's default scene) and the
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
import sys
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import reading_traces
from markers import write_between

from stereosim.sim.api import run
from stereosim.sim.config import load_config
from stereosim.sim.sweep import synthetic_pair

DOCS = Path(__file__).resolve().parents[1] / "docs"
COMMAND = "python benchmarks/doc_figures.py --write"


@dataclass(frozen=True)
class Figure:
    """A generated block: its page (in docs/) and the function that measures its lines."""

    doc: str
    lines: Callable[[], list[str]]


def _run_720p(overrides: dict) -> dict:
    """The cycle report of one 1280x720 frame (a synthetic textured pair: cycle counts do not
    depend on the pixels) at D = 128."""
    left, right = synthetic_pair(720, 1280)
    cfg = load_config(overrides={"sva.disparities": 128, **overrides})
    return run(left, right, mode="cycle", config=cfg).report


def calibration() -> list[str]:
    """docs/architecture.md, "Calibration": the default chip (CNN descriptor) and the census
    one at 720p -- cycles, first output, the frame's span, the work bound and the measured
    rate, the bottleneck."""
    lines = ["| run | cycles (nna / sva) | first output | frame (first input pixel to last "
             "word) | fps (work bound) | fps (measured) | bottleneck |",
             "|---|---|---|---|---|---|---|"]
    for name, over in (("defaults (CNN descriptor)", {}),
                       ("`--descriptor census`", {"nna.descriptor": "census"})):
        rep = _run_720p(over)
        cycles, thr, lat = rep["cycles"]["total"], rep["throughput"], rep["latency"]
        lines.append(
            f"| {name} | {cycles['nna']:,} / {cycles['sva']:,} | "
            f"{lat['first_output_us']:.1f} us | {lat['frame_ms']:.3f} ms | "
            f"{thr['fps_bound']:.3f} | {thr['fps_measured']:.3f} | {thr['bottleneck']} |")
    return lines


FIGURES = {
    "calibration": Figure("architecture.md", calibration),
    # reading-traces.md: the instants its pictures show, found in traced runs of the default
    # scene (a few seconds; docs/make_trace_pictures.py draws the pictures from the same runs)
    **{name: Figure(reading_traces.DOC, partial(reading_traces.block, name))
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
