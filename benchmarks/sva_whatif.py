"""What the SVA's structure costs at 720p: D x lanes x paths x LR check, measured by the cycle
model (compiled engine) on one CNN frame of the embedded scene's size class (a 1280x720
synthetic pair; cycle counts do not depend on the pixels).

Prints a Markdown table -- the SVA's own frame rate (1 / its work per frame: the bound), the
rate one frame achieves when the SVA is the bottleneck (measured: the same point with the census
descriptor, whose NNA takes one cycle per descriptor, first input pixel to last word), the
chip's (its bottleneck's), the first output's latency, the SVA's SRAM and its pipeline
registers -- and with ``--write`` puts it in docs/architecture.md between the ``sva-whatif``
markers.

    python benchmarks/sva_whatif.py [--write]
"""

from __future__ import annotations

import argparse
import itertools
import sys
from pathlib import Path

from markers import write_between

from stereosim.core.config import load_config
from stereosim.sim.api import run
from stereosim.sim.sweep import synthetic_pair

DOC = Path(__file__).resolve().parents[1] / "docs" / "architecture.md"
BEGIN, END = "<!-- sva-whatif:begin -->", "<!-- sva-whatif:end -->"
GRID = {"sva.disparities": (64, 128, 256), "sva.lanes": (32, 64, 128), "sva.paths": (2, 4),
        "sva.lr_check": (True, False)}


def measure() -> list[str]:
    left, right = synthetic_pair(720, 1280)
    lines = ["| D | lanes | paths | LR | II | SVA latency (cycles) | SVA fps (bound) | "
             "SVA-bound frame (fps, measured) | chip fps (bottleneck) | first output (us) | "
             "SVA SRAM (kbit) | SVA registers (kbit) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for combo in itertools.product(*GRID.values()):
        over = dict(zip(GRID, combo))
        rep = run(left, right, mode="cycle", config=load_config(overrides=over)).report
        census = run(left, right, mode="cycle", config=load_config(
            overrides={**over, "nna.descriptor": "census"})).report
        assert census["throughput"]["bottleneck"] == "sva"
        pipe = rep["architecture"]["sva_pipeline"]
        thr = rep["throughput"]
        d, lanes, paths, lr = combo
        lines.append(
            f"| {d} | {lanes} | {paths} | {'on' if lr else 'off'} | "
            f"{pipe['initiation_interval']} | {pipe['latency']} | "
            f"{thr['fps_bound_per_block']['sva']:.1f} | "
            f"{census['throughput']['fps_measured']:.1f} | "
            f"{thr['fps_bound']:.1f} ({thr['bottleneck']}) | "
            f"{rep['latency']['first_output_us']:.1f} | "
            f"{rep['architecture']['sram_bits_total']['sva'] / 1e3:.0f} | "
            f"{pipe['register_bits'] / 1e3:.1f} |")
        print(lines[-1], flush=True)
    return lines


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="update docs/architecture.md")
    args = ap.parse_args()
    lines = measure()
    if args.write:
        return write_between(DOC, BEGIN, END, lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
