"""The chip's area by block (sim/cycle/area.py) and the area rules it reads from the synthesis
table (sva/synth_table.json's ``area_rules``, written by ``python benchmarks/rtl_synth.py
--section area_rules``): the rules re-fitted and re-checked from their recorded builds, totals
as sums of blocks, monotone in lanes, D and submodules, the idle submodules counted, 7 nm's
SRAM refused with a reason, leakage from the node's figures."""

import dataclasses
import json

import pytest

from stereosim.core.config import ChipConfig
from stereosim.core.tech.nodes import node
from stereosim.core.tech.sram import sram_macro
from stereosim.sim import rtl_synth as rs
from stereosim.sim.cycle.area import chip_area, format_area, main
from stereosim.sim.cycle.plan import build_plan, frame_size

TABLE = rs.load_table()
RULES = TABLE["area_rules"]
MEMORY = {st.name: st.memory for st in rs.STAGES if st.memory}
# rules whose checks miss the stated error (docs/area.md, "The SGM"): a finding, not a tolerance
MISSES = {"sgm"}


def _plan(**sections):
    cfg = ChipConfig()
    for name, values in sections.items():
        cfg = dataclasses.replace(cfg, **{name: dataclasses.replace(getattr(cfg, name),
                                                                    **values)})
    return build_plan(cfg, frame_size(cfg))


@pytest.fixture(scope="module")
def default_area():
    return chip_area(_plan(), "45nm")


def _measured(stage: str, params: dict) -> dict | None:
    """A check's figures re-derived from the builds the table records (the memory, if the
    stage has one, extrapolated to no words from its two sizes); None if not recorded."""
    builds = TABLE["builds"] + RULES["builds"]
    mem = MEMORY.get(stage)

    def find(p):
        return next((rs.area_point(b["cells"]) for b in builds
                     if b["stage"] == stage and b["params"] == p), None)

    if mem is None:
        return find(params)
    (v1, v2) = mem.values
    f1, f2 = find({**params, mem.param: v1}), find({**params, mem.param: v2})
    if f1 is None or f2 is None:
        return None
    n1, n2 = v1 + mem.offset, v2 + mem.offset
    return {q: f1[q] - n1 * (f2[q] - f1[q]) / (n2 - n1) for q in rs.AREA_QUANTITIES}


@pytest.mark.parametrize("stage", [r.stage for r in rs.AREA_RULES])
def test_each_rule_refits_and_reproduces_its_checks_within_the_stated_error(stage):
    entry = RULES["stages"][stage]
    rule = rs.AREA_RULE_OF[stage]
    coef = rs.fit_area_rule(rule, entry["fit"])
    assert sorted(coef) == sorted(entry["coef"])
    for g in coef:
        for q in rs.AREA_QUANTITIES:
            assert coef[g][q] == pytest.approx(entry["coef"][g][q], rel=1e-3, abs=0.5)
    assert len(entry["checks"]) >= 2, "a rule is checked at two sizes or more"
    sizes = {json.dumps({k: v for k, v in c["params"].items() if k not in rule.width},
                        sort_keys=True) for c in entry["checks"]}
    assert len(sizes) >= 2, f"{stage}: checked at one size only"
    fitted = [p["params"] for p in entry["fit"]]
    for check in entry["checks"]:
        assert check["params"] not in fitted
        pred = rs.area_rule_eval(coef, rule, check["params"])
        assert pred is not None
        measured = check["measured"]
        if stage != "nna":  # the NNA's line buffer is taken out at one size (its entry)
            rederived = _measured(stage, check["params"])
            assert rederived is not None, f"{stage}: check {check['params']} has no build"
            for q in rs.AREA_QUANTITIES:
                assert rederived[q] == pytest.approx(measured[q], abs=0.1)
        for q in rs.AREA_QUANTITIES:
            err = 100 * (pred[q] - measured[q]) / measured[q]
            assert err == pytest.approx(check["error_pct"][q], abs=0.02)
            if stage not in MISSES:
                assert abs(err) <= RULES["error_pct"], (stage, check["params"], q, err)
    assert rs.area_rule_holds(entry, RULES["error_pct"]) == (stage not in MISSES)


def test_a_rule_that_missed_its_check_gives_no_figure_and_says_by_how_much():
    """The SGM's rule misses its 24- and 32-lane checks (its memory-free logic, extrapolated
    from 3- and 4-slot memories, grows faster than the 8- and 16-lane slices say): the chip's
    SGM has no logic figure, and the reason names the check."""
    sgm = RULES["stages"]["sgm"]
    assert max(abs(c["error_pct"]["nand2_logic"]) for c in sgm["checks"]) > RULES["error_pct"]
    area = chip_area(_plan(), "45nm")
    block = next(b for b in area["blocks"] if b["name"] == "sva.sgm")
    assert block["logic"] is None and "missed its check" in block["logic_reason"]
    assert block["sram"]["area_mm2"] > 0  # its previous rows are still counted
    assert any(nc["block"] == "sva.sgm" for nc in area["not_costed"])


def test_the_nna_rule_is_per_mac_and_checked_at_larger_arrays():
    entry = RULES["stages"]["nna"]

    def macs(p):
        return p["C1"] * p["P0"]

    fit = max(macs(p["params"]) for p in entry["fit"])
    assert all(macs(c["params"]) > fit for c in entry["checks"])
    assert entry["coef"]["all"]["nand2_logic"][2] > 0  # logic per MAC


def test_a_lane_group_count_the_slices_lack_is_outside_the_rule():
    """The builds at G = 4 are recorded, and a configuration of G = 4 gets no figure."""
    assert any(o["group"] == "G4" for o in RULES["stages"]["hamming"]["outside"])
    area = chip_area(_plan(sva={"disparities": 256, "lanes": 64}), "45nm")
    ham = next(b for b in area["blocks"] if b["name"] == "sva.hamming")
    assert ham["logic"] is None and "G4" in ham["logic_reason"]


def test_totals_are_the_sums_of_the_blocks(default_area):
    blocks, t = default_area["blocks"], default_area["totals"]
    logic = sum(b["logic"]["area_mm2"] for b in blocks if b["logic"])
    sram = sum(b["sram"]["area_mm2"] for b in blocks if b.get("sram"))
    assert t["logic_mm2"] == pytest.approx(logic)
    assert t["sram_mm2"] == pytest.approx(sram)
    assert t["chip_mm2"] == pytest.approx(sum(b["area_mm2"] for b in blocks))
    assert t["leakage_mw"] == pytest.approx(sum(b["leakage_mw"] for b in blocks))
    for b in blocks:
        if b.get("sram"):
            assert b["sram"]["area_mm2"] == pytest.approx(
                sum(m["area_mm2"] for m in b["sram"]["macros"]))


def test_every_block_of_the_chip_is_listed_and_sram_macros_are_per_bank(default_area):
    plan = _plan()
    names = {b["name"] for b in default_area["blocks"]}
    assert {f"sva.{st.name}" for st in plan.block("sva").stages} <= names
    assert {f"fifo.{f.name}" for f in plan.fifos} <= names
    rows = next(b for b in default_area["blocks"] if b["name"] == "sva.descriptor_rows"
                or b["name"] == "sva.hamming")["sram"]["macros"]
    buf = next(b for b in plan.block("sva").buffers if b.name == "sva.descriptor_rows")
    m = next(m for m in rows if m["buffer"] == "sva.descriptor_rows")
    per = sram_macro("45nm", -(-buf.bits // buf.banks), buf.word_bits, buf.ports)
    assert m["banks"] == buf.banks
    assert m["area_mm2"] == pytest.approx(buf.banks * per.area_mm2)


def test_unused_submodules_are_counted_and_marked(default_area):
    cfg = ChipConfig().nna
    subs = [b for b in default_area["blocks"] if b["kind"] == "nna_submodule"]
    assert len(subs) == cfg.submodules
    assert sum(b["used"] for b in subs) == cfg.stereo_submodules
    assert [b["use"] for b in subs].count("idle") == cfg.submodules - cfg.stereo_submodules
    idle = next(b for b in subs if not b["used"])
    used = next(b for b in subs if b["used"])
    assert idle["area_mm2"] == pytest.approx(used["area_mm2"]) and idle["area_mm2"] > 0
    assert idle["logic"] is not None and idle["logic"]["flip_flops"] > 0


def test_more_lanes_d_or_submodules_cost_more_area():
    def chip(**kw):
        return chip_area(_plan(**kw), "45nm")["totals"]

    base = chip()
    assert chip(sva={"lanes": 64})["logic_mm2"] < base["logic_mm2"]
    assert chip(sva={"disparities": 64})["chip_mm2"] < base["chip_mm2"]
    more_d = chip_area(_plan(sva={"disparities": 192, "lanes": 96}), "45nm")
    less_d = chip_area(_plan(sva={"disparities": 96, "lanes": 96}), "45nm")
    assert more_d["not_costed"] == less_d["not_costed"]  # the same blocks costed
    assert more_d["totals"]["logic_mm2"] > less_d["totals"]["logic_mm2"]
    assert chip(nna={"submodules": 12})["chip_mm2"] > base["chip_mm2"]
    assert chip(nna={"macs": 576})["logic_mm2"] > base["logic_mm2"]


def test_7nm_has_no_sram_figure_and_says_why():
    area = chip_area(_plan(), "7nm")
    with_sram = [b for b in area["blocks"] if "sram" in b]
    assert with_sram and all(b["sram"] is None and "7nm" in b["sram_reason"]
                             for b in with_sram)
    t = area["totals"]
    assert t["sram_mm2"] is None and t["chip_mm2"] is None and t["leakage_mw"] is None
    assert "7nm" in t["sram_reason"] and t["logic_mm2"] > 0
    assert "n/a" in format_area(area)


@pytest.mark.parametrize("name", ["45nm", "130nm", "7nm"])
def test_block_logic_area_and_leakage_are_its_gates_times_the_node(name):
    n = node(name)
    for b in chip_area(_plan(), name)["blocks"]:
        lg = b["logic"]
        if lg is None:
            continue
        ge, ff = lg["nand2_logic"], lg["flip_flops"]
        assert lg["leakage_mw"] == pytest.approx(
            (ge * n.ge_leakage_nw + ff * n.ff_leakage_nw) * 1e-6)
        assert lg["area_mm2"] == pytest.approx((ge + ff * n.ff_area_ge) * n.ge_area_um2 * 1e-6)


def test_a_stage_outside_its_rule_has_no_figure_and_a_reason():
    area = chip_area(_plan(sva={"compare_levels": 4}), "45nm")
    box = next(b for b in area["blocks"] if b["name"] == "sva.box_filter")
    assert box["logic"] is None and "V = 4" in box["logic_reason"]
    assert any(nc["block"] == "sva.box_filter" for nc in area["not_costed"])


def test_the_command_prints_the_table(capsys):
    assert main(["--node", "45nm"]) == 0
    out = capsys.readouterr().out
    assert "nna.sub0" in out and "sva.sgm" in out and "chip" in out
