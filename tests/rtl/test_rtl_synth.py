"""The synthesis figures of the RTL twin (sim/rtl_synth.py) without Yosys: the NAND2-equivalent
conversion, the fmax arithmetic, the cached table (sva/rtl/synth_table.json) and the plan's
`silicon` section and `stereosim rtl synth` that read it."""

import json

import pytest

from stereosim.nna.descriptor import descriptor_parts
from stereosim.sim import rtl_synth as rs
from stereosim.sim.config import ChipConfig
from stereosim.sim.config.loader import load_config

# the library's cells in placement sites (each 0.19 um x 1.4 um; the LEF's SIZE / 0.19)
SITES = {"NAND2_X1": 3, "XOR2_X1": 6, "INV_X1": 2, "MUX2_X1": 7, "DFF_X1": 17}


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


def test_the_cached_table_covers_the_defaults_and_d_64_128_256():
    table = rs.load_table()
    _, lanes, v, parts = _default_key()
    wanted = {(d, min(lanes, d), v, tuple(parts)) for d in (64, 128, 256)}
    for stage in rs.STAGES:
        rows = [r for r in table["rows"] if r["stage"] == stage.name]
        have = {(r["config"][0], r["config"][1], r["config"][2], tuple(r["config"][3]))
                for r in rows}
        assert wanted <= have, f"{stage.name}: the table lacks {wanted - have}"
        for r in rows:
            d, ln, rv, rp = r["config"]
            assert r["params"] == stage.params(d, ln, rv, tuple(rp)), r["config"]
            assert r["source"] == stage.source and r["top"] == stage.top
            flops = sum(n for k, n in r["cells"].items() if k in rs.FLIP_FLOPS)
            assert r["flip_flops"] == flops
            assert r["gates"] == sum(r["cells"].values()) - flops
            assert r["depth"] > 0 and r["gates"] > 0
            assert r["how"] == "measured" or r["how"].startswith("scaled")
            rs.nand2_equivalents(r["cells"])  # every cell has a library cell
    # a scaled row's rule is checked against at least two sizes synthesised whole
    if any(r["how"].startswith("scaled") for r in table["rows"]):
        checks = table["scaling_checks"]
        assert len({c["config"][1] for c in checks}) >= 2
        fitted = {s["config"][1] for s in table["slices"]}
        for check in checks:
            assert check["config"][1] not in fitted, check  # not one of the fitted slices
            assert abs(check["error_pct"]) < 10, check
            assert check["depth_measured"] == check["depth_scaled"], check
    kinds = {p["kind"] for p in table["probes"]}
    assert kinds == {"min", "add"}
    for b in table.get("small_builds", []):  # the other stages: figures, or why not
        assert ("cells" in b and b["depth"] > 0) or b["failed"], b["stage"]
        if "cells" in b:
            rs.nand2_equivalents(b["cells"])


def test_the_silicon_section_reads_the_table(tmp_path):
    """A table of one hamming row for the defaults: the section carries its figures, the
    other stages say they have no RTL, and another configuration finds no row."""
    d, lanes, v, parts = _default_key()
    cells = {"NAND": 300, "XOR": 30, "DFF_P": 60}
    row = {"stage": "hamming", "source": "sva/rtl/sva_hamming.sv", "top": "sva_hamming",
           "config": [d, min(lanes, d), v, parts], "params": {}, "cells": cells,
           "flip_flops": 60, "gates": 330, "depth": 20, "how": "measured", "seconds": 1.0}
    table = {"schema": rs.SCHEMA, "rows": [row], "probes": []}
    path = tmp_path / "t.json"
    path.write_text(json.dumps(table))
    sec = rs.silicon_section(ChipConfig(), rs.load_table(path))
    ham = sec["stages"]["hamming"]
    assert ham["rtl"] and ham["depth_gates"] == 20 and ham["flip_flops"] == 60
    assert ham["nand2_logic"] == round(rs.nand2_equivalents(cells)["logic"])
    assert ham["nand2_flip_flops"] == round(60 * SITES["DFF_X1"] / SITES["NAND2_X1"])
    gate = rs.level_delay_ps(cells)
    assert ham["fmax_mhz"] == pytest.approx(rs.fmax_mhz(20, gate), abs=0.1)
    assert ham["meets_clock"] == (rs.fmax_mhz(20, gate) >= ChipConfig().clocks.sva_mhz)
    assert not sec["stages"]["sgm"]["rtl"] and sec["nand2_logic"] == ham["nand2_logic"]
    other = rs.silicon_section(load_config(overrides={"sva.disparities": 96}),
                               rs.load_table(path))
    assert not any(st["config_row"] for st in other["stages"].values())
    table["small_builds"] = [{"stage": "sgm", "top": "sva_sgm", "params": {"D_MAX": 8},
                              "cells": cells, "depth": 50}]
    path.write_text(json.dumps(table))
    sgm = rs.silicon_section(ChipConfig(), rs.load_table(path))["stages"]
    assert sgm["sgm"]["rtl"] and not sgm["sgm"]["config_row"]
    assert sgm["path_sum"]["small_build"]["depth_gates"] == 50  # sva_sgm holds the path sum
    assert sgm["sgm"]["small_build"]["fmax_mhz"] == pytest.approx(rs.fmax_mhz(50, gate), abs=0.1)
    real = rs.silicon_section(ChipConfig())  # the cached table has the defaults' rows
    assert real["stages"]["hamming"]["rtl"]
    cfg = ChipConfig()
    assert real["compare_levels"] == rs.verdict(rs.load_table(), cfg.clocks.sva_mhz,
                                                cfg.sva.compare_levels)


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


def test_stereosim_rtl_synth_prints_the_table(capsys):
    assert rs.main_rtl_synth([]) == 0
    text = capsys.readouterr().out
    for d in (64, 128, 256):
        assert any(line.startswith("hamming") and f" {d} " in line
                   for line in text.splitlines()), d
    assert "compare_levels = 8 at 465 MHz" in text
    assert rs.main_rtl_synth(["--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert {"rows", "verdict", "probes"} <= set(data)
