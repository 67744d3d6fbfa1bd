"""Power from the run (sim/cycle/power.py): a stalled run costs more by exactly the clock and
leakage of its extra cycles, gated cycles cost no clock, power-gating the unused submodules
removes exactly their leakage, the totals are the blocks' sums (issue 50, acceptance 2)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from stereosim.core.config import load_config
from stereosim.core.errors import ConfigError
from stereosim.core.tech.nodes import node
from stereosim.sim.cycle.area import chip_area
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.plan import build_plan

SAME = {"clocks.nna_mhz": 400, "clocks.sva_mhz": 400, "sva.disparities": 16}
STALL = (3, 0)  # the sink pops one cycle in three: the SVA blocks behind it


def _run(over=None, stall=None, shape=(8, 40), frames=1):
    plan = build_plan(load_config(overrides={**SAME, **(over or {})}), shape, frames)
    left = np.random.default_rng(0).integers(0, 256, (frames, *shape), dtype=np.uint8)
    res = run_compiled(plan, left, np.roll(left, -2, axis=2), sink_stall=stall)
    return plan, res


def _domain(name: str) -> str | None:
    """The domain of a chip_area block in these runs (no merge blocks; a FIFO has no
    flip-flops)."""
    return {"nna": "nna", "sva": "sva"}.get(name.split(".")[0])


def test_a_stalled_sva_costs_exactly_the_clock_and_leakage_of_its_extra_cycles():
    plan, plain = _run()
    _, stalled = _run(stall=STALL)
    s0, s1 = plain.stats, stalled.stats
    assert s1["stages"]["sva"]["sgm"]["blocked"] > 0 == s0["stages"]["sva"]["sgm"]["blocked"]
    assert s1["cycles"]["sva"] > s0["cycles"]["sva"] and s1["end_time_fs"] > s0["end_time_fs"]
    n = node(plan.cfg.power.node)
    area = chip_area(plan, plan.cfg.power.node)
    clock = 0.0
    for b in area["blocks"]:
        if b["kind"] == "fifo":
            assert b["logic"] is None
        if b["logic"]:
            d = _domain(b["name"])
            clock += b["logic"]["flip_flops"] * n.ff_clock_fj * (s1["cycles"][d] - s0["cycles"][d])
    leak = area["totals"]["leakage_mw"] * (s1["end_time_fs"] - s0["end_time_fs"])
    expected_pj = clock * 1e-3 + leak * 1e-6
    p0, p1 = plain.report["power"], stalled.report["power"]
    assert p1["per_frame_pj"]["dynamic"] == pytest.approx(p0["per_frame_pj"]["dynamic"],
                                                         rel=1e-12)
    assert p1["per_frame_pj"]["total"] - p0["per_frame_pj"]["total"] == pytest.approx(
        expected_pj, rel=1e-9)
    assert expected_pj > 0


def test_stalled_cycles_cost_no_clock_when_gated():
    over = {"power.clock_gating": "stalled"}
    plan, plain = _run(over)
    _, stalled = _run(over, stall=STALL)
    n = node(plan.cfg.power.node)
    area = {b["name"]: b for b in chip_area(plan, plan.cfg.power.node)["blocks"]}
    for res in (plain, stalled):
        for name, b in res.report["power"]["blocks"].items():
            if b["kind"] == "sva_stage":
                busy = res.stats["stages"]["sva"][name.split(".")[1]]["busy"]
                ffs = area[name]["logic"]["flip_flops"] if area[name]["logic"] else 0.0
                assert b["clocked_cycles"] == busy
                assert b["clock_pj"] == pytest.approx(ffs * n.ff_clock_fj * busy * 1e-3,
                                                      rel=1e-12)
    # the work is the same, so the clock energy is: the stall's cycles cost none
    assert stalled.report["power"]["per_frame_pj"]["clock"] == pytest.approx(
        plain.report["power"]["per_frame_pj"]["clock"], rel=1e-12)
    assert stalled.report["power"]["per_frame_pj"]["total"] > \
        plain.report["power"]["per_frame_pj"]["total"]  # the leakage still counts
    # gating idle cycles clocks fewer than none gated, more than only the busy ones
    _, off = _run(stall=STALL)
    _, idle = _run({"power.clock_gating": "idle"}, stall=STALL)
    clocks = [r.report["power"]["per_frame_pj"]["clock"] for r in (off, idle, stalled)]
    assert clocks[0] > clocks[1] > clocks[2]


def test_power_gating_the_unused_submodules_removes_exactly_their_leakage():
    plan, on = _run()
    _, gated = _run({"power.gate_unused": True})
    area = chip_area(plan, plan.cfg.power.node)
    idle = [b for b in area["blocks"] if b.get("use") == "idle"]
    assert len(idle) == plan.cfg.nna.submodules - plan.cfg.nna.stereo_submodules > 0
    share_mw = sum(b["leakage_mw"] for b in idle)
    p0, p1 = on.report["power"], gated.report["power"]
    assert p0["leakage_power_mw"] - p1["leakage_power_mw"] == pytest.approx(share_mw, rel=1e-12)
    end = on.stats["end_time_fs"]
    assert end == gated.stats["end_time_fs"]
    assert p0["per_frame_pj"]["leakage"] - p1["per_frame_pj"]["leakage"] == pytest.approx(
        share_mw * end * 1e-6, rel=1e-9)
    for b in idle:
        g = p1["blocks"][b["name"]]
        assert g["power_gated"] and g["leakage_pj"] == g["clock_pj"] == g["total_pj"] == 0
    assert not p1["blocks"]["nna.sub0"]["power_gated"]


def test_totals_are_the_blocks_sums_and_the_report_is_deterministic():
    plan, res = _run(frames=3)
    p = res.report["power"]
    for k in ("dynamic", "clock", "leakage", "total"):
        assert p["per_frame_pj"][k] == pytest.approx(
            sum(b[f"{k}_pj"] for b in p["blocks"].values()), rel=1e-12)
    for b in p["blocks"].values():
        assert b["total_pj"] == pytest.approx(b["dynamic_pj"] + b["clock_pj"]
                                              + b["leakage_pj"], rel=1e-12)
    # the dynamic part is the energy report's items, all of them
    items = res.report["energy"]["items"]
    assert p["per_frame_pj"]["dynamic"] == pytest.approx(
        sum(it["count"] * it["pj_each"] for it in items), rel=1e-12)
    assert p["energy_per_frame_uj"] == pytest.approx(p["per_frame_pj"]["total"] / 1e6)
    run_s = res.stats["end_time_fs"] / 1e15
    assert p["average_power_mw"] == pytest.approx(
        p["per_frame_pj"]["total"] * 3 * 1e-9 / run_s, rel=1e-12)
    # the peak over one frame is at least the average (the first frame includes the fill)
    assert p["peak_power_mw"] >= p["average_power_mw"]
    assert p["peak_window"].startswith("peak over one frame")
    _, again = _run(frames=3)
    assert json.dumps(again.report["power"]) == json.dumps(p)


def test_an_unknown_clock_gating_is_refused():
    with pytest.raises(ConfigError):
        load_config(overrides={"power.clock_gating": "sometimes"})
