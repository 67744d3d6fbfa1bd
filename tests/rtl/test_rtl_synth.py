"""The synthesis figures of the RTL twin (sim/rtl_synth.py) without Yosys: the NAND2-equivalent
conversion, the fmax arithmetic, the cached table (sva/synth_table.json: every SVA stage at
the defaults and D = 64/128/256, its rows re-derived here from its recorded Yosys builds by the
stated rules, the rules' checks) and the plan's `silicon` section and `stereosim rtl synth`
that read it."""

import json
import math

import pytest

from stereosim.core.config import ChipConfig
from stereosim.core.config.loader import load_config
from stereosim.nna.descriptor import descriptor_parts
from stereosim.sim import rtl_synth as rs

# the library's cells in placement sites (each 0.19 um x 1.4 um; the LEF's SIZE / 0.19)
SITES = {"NAND2_X1": 3, "XOR2_X1": 6, "INV_X1": 2, "MUX2_X1": 7, "DFF_X1": 17}
# a scaling rule's check against a build synthesised whole: cells within this, in percent
CELLS_TOLERANCE_PCT = rs.CHECK_CELLS_PCT
# ... and its depth within this many gates
DEPTH_TOLERANCE = rs.CHECK_DEPTH_GATES


def test_nand2_equivalents_of_a_hand_counted_netlist():
    """10 NAND2 + 2 XOR2 + 3 INV + 1 MUX2 and 4 flip-flops, in sites over NAND2's 3:
    logic 10 + 2 x 6/3 + 3 x 2/3 + 7/3, flip-flops 4 x 17/3."""
    cells = {"NAND": 10, "XOR": 2, "NOT": 3, "MUX": 1, "DFF_P": 4}
    eq = rs.nand2_equivalents(cells)
    n = SITES["NAND2_X1"]
    logic = (10 * n + 2 * SITES["XOR2_X1"] + 3 * SITES["INV_X1"] + SITES["MUX2_X1"]) / n
    assert eq["logic"] == pytest.approx(logic)
    assert eq["flip_flops"] == pytest.approx(4 * SITES["DFF_X1"] / n)
    assert eq["total"] == pytest.approx(eq["logic"] + eq["flip_flops"])
    with pytest.raises(ValueError, match="no library cell"):
        rs.nand2_equivalents({"SDFFE_PP0P": 1})


def test_fmax_is_depth_times_the_gate_delay_plus_the_flip_flop():
    """fmax = 1 / (depth x t_gate + clock-to-Q + setup); the levels that fit a period are
    the largest depth whose cycle is within it."""
    t_ff = rs.FLOP_PS["clk_to_q"] + rs.FLOP_PS["setup"]
    assert rs.fmax_mhz(10, 50.0) == pytest.approx(1e6 / (500.0 + t_ff))
    gates = {"NAND": 3, "XOR": 1, "DFF_P": 9}
    mean = (3 * rs.GATE_DELAY_PS["NAND2_X1"] + rs.GATE_DELAY_PS["XOR2_X1"]) / 4
    assert rs.level_delay_ps(gates) == pytest.approx(mean)
    for mhz in (250.0, 465.0, 900.0):
        n = rs.levels_per_cycle(mhz, mean)
        assert rs.cycle_ps(n, mean) <= 1e6 / mhz < rs.cycle_ps(n + 1, mean)


def _default_key():
    cfg = ChipConfig()
    s = cfg.sva
    parts = [b for _, b in descriptor_parts(cfg.nna)]
    return s.disparities, s.lanes, s.compare_levels, parts


def _wanted_configs():
    """The defaults and D = 64 / 128 / 256 at the defaults' lanes, V and descriptor."""
    d0, lanes, v, parts = _default_key()
    return {(d, min(lanes, d), v, tuple(parts)) for d in (d0, 64, 128, 256)}


def _line(points):
    """Least squares a, b of y = a + b x (the test's own)."""
    n = len(points)
    mx = sum(x for x, _ in points) / n
    my = sum(y for _, y in points) / n
    sxx = sum((x - mx) ** 2 for x, _ in points)
    b = sum((x - mx) * (y - my) for x, y in points) / sxx
    return my - b * mx, b


def _build(table, stage, params):
    found = [b for b in table["builds"] if b["stage"] == stage and b["params"] == params]
    assert found, f"{stage}: no recorded Yosys build at {params}"
    return found[0]


def _logic(table, st, params):
    """A stage's cells at ``params`` from its recorded builds, the memory extrapolated out by
    the stated rule: per cell type c1 - n1 (c2 - c1) / (n2 - n1), n the memory's words."""
    if st.memory is None:
        b = _build(table, st.name, params)
        return dict(b["cells"]), b["depth"]
    m = st.memory
    b1, b2 = (_build(table, st.name, {**params, m.param: x}) for x in m.values)
    n1, n2 = (x + m.offset for x in m.values)
    cells = {}
    for k in set(b1["cells"]) | set(b2["cells"]):
        c1, c2 = b1["cells"].get(k, 0), b2["cells"].get(k, 0)
        c = round(c1 - n1 * (c2 - c1) / (n2 - n1))
        if c > 0:
            cells[k] = c
    return cells, b1["depth"]


def _lg(n):
    return math.ceil(math.log2(n))


def test_the_table_has_every_stage_at_the_defaults_and_d_64_128_256():
    """Every stage of STAGES has a row at each configuration, built with the parameters the
    defaults give, and each row's cells follow from its recorded builds by the stated rule:
    'synthesised' rows are their builds (memory extrapolated out), 'scaled' rows the
    per-cell-type line a + b x lanes and the depth's p + q x ceil(lg lanes) over the recorded
    8- and 16-lane slices of the same G."""
    table = rs.load_table()
    sva = ChipConfig().sva
    names = {r["stage"] for r in table["rows"]}
    assert {st.name for st in rs.STAGES} <= names
    assert {"hamming", "box_filter", "sgm", "wta", "lr_check", "median"} <= names
    for st in rs.STAGES:
        rows = [r for r in table["rows"] if r["stage"] == st.name]
        have = {(r["config"][0], r["config"][1], r["config"][2], tuple(r["config"][3]))
                for r in rows}
        assert _wanted_configs() <= have, f"{st.name}: the table lacks {_wanted_configs() - have}"
        for r in rows:
            d, ln, v, parts = r["config"]
            assert r["params"] == st.params(d, ln, v, tuple(parts), sva), r["config"]
            assert r["source"] == st.source and r["top"] == st.top
            flops = sum(n for k, n in r["cells"].items() if k in rs.FLIP_FLOPS)
            assert r["flip_flops"] == flops and r["gates"] == sum(r["cells"].values()) - flops
            assert r["depth"] > 0 and r["gates"] > 0
            rs.nand2_equivalents(r["cells"])  # every cell has a library cell
            if r["how"].startswith("synthesised"):
                cells, depth = _logic(table, st, r["params"])
            else:
                assert r["how"].startswith("scaled") and st.lanes, r["how"]
                g = -(-d // ln)
                pts = [(sl, _logic(table, st, st.params(g * sl, sl, v, tuple(parts), sva)))
                       for sl in (8, 16)]
                cells = {}
                for k in {k for _, (c, _) in pts for k in c}:
                    a, b = _line([(sl, c.get(k, 0)) for sl, (c, _) in pts])
                    if round(a + b * ln) > 0:
                        cells[k] = round(a + b * ln)
                p, q = _line([(_lg(sl), dp) for sl, (_, dp) in pts])
                depth = round(p + q * _lg(ln))
            assert r["cells"] == cells, (st.name, r["config"])
            assert r["depth"] == depth, (st.name, r["config"])
            if st.memory:
                assert "memory out" in r["how"], r["how"]


def test_the_scaling_rules_hold_against_builds_synthesised_whole(capsys):
    """Every stage scaled from slices has its lanes rule checked against at least one build
    synthesised whole that the fit did not use; the recorded measured figures are the
    recorded build's; every check is within CELLS_TOLERANCE_PCT of the cells and
    DEPTH_TOLERANCE gates of the depth -- or, a lanes rule that misses, its stage's scaled rows
    are not figures: the silicon section has no row for it (saying why) and `stereosim rtl
    synth` marks them NOT VALID and leaves them out of the SVA's total."""
    table = rs.load_table()
    checks = table["scaling_checks"]
    slices = {(b["stage"], json.dumps(b["params"], sort_keys=True))
              for b in table["builds"] if b["role"] == "slice"}
    for st in rs.STAGES:
        if any(r["stage"] == st.name and r["how"].startswith("scaled") for r in table["rows"]):
            mine = [c for c in checks if c["stage"] == st.name and "lanes" in c["what"]]
            assert mine, f"{st.name}: scaled rows without a check of the lanes rule"
    assert checks
    for c in checks:
        if "against a row" not in c["what"]:
            assert (c["stage"], json.dumps(c["params"], sort_keys=True)) not in slices, c
            b = _build(table, c["stage"], c["params"])
            assert c["cells_measured"] == sum(b["cells"].values())
            assert c["depth_measured"] == b["depth"]
        err = 100 * (c["cells_scaled"] - c["cells_measured"]) / c["cells_measured"]
        assert err == pytest.approx(c["error_pct"], abs=0.01)
        if abs(err) <= CELLS_TOLERANCE_PCT and abs(c["depth_scaled"] - c["depth_measured"]) \
                <= DEPTH_TOLERANCE:
            continue
        assert "lanes" in c["what"], f"a memory rule missed its check: {c}"
        name = c["stage"]
        assert name in rs.scaling_failures(table)
        sec = rs.silicon_section(ChipConfig())["stages"][name]
        assert not sec.get("how", "").startswith("scaled"), sec  # a whole build, or no row
        assert rs.main_rtl_synth([]) == 0
        printed = [line for line in capsys.readouterr().out.splitlines()
                   if line.split()[:1] == [name]]
        assert printed and all("NOT VALID" in line for line in printed
                               if "scaled" in line), printed


def _memory_bits_per_step(st, params):
    """The bits one more unit of the memory parameter adds, from the RTL's declarations:
    sva_box's column sums (G words of LANES sums of clog2(K_MAX (2^COST_W - 1) + 1) bits),
    sva_sgm's four previous rows (G words of LANES + 1 path costs) and minima, sva_median's
    K - 1 row banks of WB-bit words."""
    if st.top == "sva_box":
        g = -(-params["D_MAX"] // params["LANES"])
        cs = math.ceil(math.log2(params["K_MAX"] * (2 ** params["COST_W"] - 1) + 1))
        return g * params["LANES"] * cs
    if st.top == "sva_sgm":
        g = -(-params["D_MAX"] // params["LANES"])
        return 4 * (g * (params["LANES"] + 1) + 1) * params["PATH_W"]
    if st.top == "sva_median":
        return (params["K"] - 1) * params["WB"]
    raise AssertionError(st.top)


def test_the_memory_extrapolated_out_is_the_declared_memory():
    """Between a memory stage's two recorded sizes the flip-flops grow by the memory's
    declared bits (sva_box: and its column address's few registers, which widen with
    W_MAX): the extrapolation to no words removes the memory, not logic."""
    table = rs.load_table()
    seen = 0
    for st in rs.STAGES:
        if st.memory is None:
            continue
        m = st.memory
        for b1 in (b for b in table["builds"] if b["stage"] == st.name and b["role"] != "check"
                   and b["params"][m.param] == m.values[0]):  # a check is one size
            b2 = _build(table, st.name, {**b1["params"], m.param: m.values[1]})
            step = m.values[1] - m.values[0]
            extra = b2["flip_flops"] - b1["flip_flops"] - step * _memory_bits_per_step(
                st, b1["params"])
            # sva_box's column address is clog2(W_MAX) bits: its registers (the slot's and
            # the column update's stages) widen with the memory
            widen = math.ceil(math.log2(m.values[1])) - math.ceil(math.log2(m.values[0]))
            allowed = range(0, 4 * widen + 1) if st.top == "sva_box" else range(1)
            assert extra in allowed, (st.name, b1["params"], extra)
            seen += 1
    assert seen >= 3


def test_the_silicon_section_reads_the_table(tmp_path):
    """A table of one hamming row for the defaults: the section carries its figures, the
    other stages say they have no row, and another configuration finds no row."""
    d, lanes, v, parts = _default_key()
    cells = {"NAND": 300, "XOR": 30, "DFF_P": 60}
    sva = ChipConfig().sva
    row = {"stage": "hamming", "source": "sva/hamming/sva_hamming.sv", "top": "sva_hamming",
           "config": [d, min(lanes, d), v, parts],
           "params": rs.STAGE["hamming"].params(d, min(lanes, d), v, tuple(parts), sva),
           "cells": cells, "flip_flops": 60, "gates": 330, "depth": 20, "how": "synthesised"}
    table = {"schema": rs.SCHEMA, "rows": [row], "probes": []}
    path = tmp_path / "t.json"
    path.write_text(json.dumps(table))
    sec = rs.silicon_section(ChipConfig(), rs.load_table(path))
    ham = sec["stages"]["hamming"]
    assert ham["config_row"] and ham["depth_gates"] == 20 and ham["flip_flops"] == 60
    assert ham["nand2_logic"] == round(rs.nand2_equivalents(cells)["logic"])
    assert ham["nand2_flip_flops"] == round(60 * SITES["DFF_X1"] / SITES["NAND2_X1"])
    gate = rs.level_delay_ps(cells)
    assert ham["fmax_mhz"] == pytest.approx(rs.fmax_mhz(20, gate), abs=0.1)
    assert ham["meets_clock"] == (rs.fmax_mhz(20, gate) >= ChipConfig().clocks.sva_mhz)
    assert not sec["stages"]["sgm"]["config_row"] and sec["nand2_logic"] == ham["nand2_logic"]
    assert not sec["stages"]["output"]["rtl"]
    other = rs.silicon_section(load_config(overrides={"sva.disparities": 96}),
                               rs.load_table(path))
    assert not any(st["config_row"] for st in other["stages"].values())


def test_the_silicon_section_of_the_defaults_has_every_stage():
    """From the cached table: every stage with RTL has its row at the defaults, the path sum
    points at the SGM's, the totals are the rows' sums; a configuration whose widths differ
    (box 5) finds no box row, one without a median says it is off."""
    cfg = ChipConfig()
    sec = rs.silicon_section(cfg)
    rows = [st for st in sec["stages"].values() if "gates" in st]
    failed = rs.scaling_failures(rs.load_table())
    for st in rs.STAGES:
        got = sec["stages"][st.name]
        if "scaling_failed" in got:  # its scaled row missed its check (the test above)
            assert not got["config_row"] and got["scaling_failed"] == failed[st.name]
            continue
        assert got["config_row"] and got["gates"] > 0 and got["depth_gates"] > 0, st.name
        assert got["meets_clock"] == (got["fmax_mhz"] >= cfg.clocks.sva_mhz)
    assert sec["stages"]["path_sum"] == {"rtl": True, "in_row": "sgm",
                                         "config_row": sec["stages"]["sgm"]["config_row"]}
    assert sec["nand2_logic"] == sum(st["nand2_logic"] for st in rows)
    assert sec["nand2_flip_flops"] == sum(st["nand2_flip_flops"] for st in rows)
    assert sec["meets_clock"] == all(st["meets_clock"] for st in rows)
    assert sec["compare_levels"] == rs.verdict(rs.load_table(), cfg.clocks.sva_mhz,
                                               cfg.sva.compare_levels)
    for d in (64, 256):
        other = rs.silicon_section(load_config(overrides={"sva.disparities": d}))
        assert all(other["stages"][st.name]["config_row"] for st in rs.STAGES
                   if "scaling_failed" not in other["stages"][st.name]), d
    box5 = rs.silicon_section(load_config(overrides={"sva.box_size": 5}))["stages"]
    assert not box5["box_filter"]["config_row"] and box5["wta"]["config_row"]
    off = rs.silicon_section(load_config(overrides={"sva.median": 0}))["stages"]["median"]
    assert off.get("off") and not off["config_row"]


def test_the_verdict_takes_the_probes_slope():
    """Probes of depth 10 L + 5: 10 gates a level, and the levels that fit follow."""
    probes = [{"kind": "min", "levels": lv, "depth": 10 * lv + 5, "cells": {"NAND": 4}}
              for lv in (1, 2, 4)]
    out = rs.verdict({"probes": probes}, 465.0, v=8)["min"]
    assert out["gates_per_level"] == pytest.approx(10.0)
    gate = rs.GATE_DELAY_PS["NAND2_X1"]
    assert out["levels_that_fit"] == pytest.approx(rs.levels_per_cycle(465.0, gate) / 10,
                                                   abs=0.05)
    assert out["holds"] == (rs.levels_per_cycle(465.0, gate) >= 80)


def test_stereosim_rtl_synth_prints_the_per_stage_table(capsys):
    assert rs.main_rtl_synth([]) == 0
    text = capsys.readouterr().out
    lines = text.splitlines()
    _, lanes, v, _ = _default_key()
    for d in (64, 128, 256):
        for st in rs.STAGES:
            assert any(line.split()[:2] == [st.name, str(d)] for line in lines), (st.name, d)
        assert any(line.split()[:3] == ["SVA", "total", str(d)] for line in lines), d
    assert "compare_levels = 8 at 465 MHz" in text
    assert rs.main_rtl_synth(["--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert {"rows", "verdict", "probes", "builds"} <= set(data)
