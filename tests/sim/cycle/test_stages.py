"""The SVA's stages (sim/cycle/stages.py): initiation interval and latency from D, the lanes,
the paths and the LR check, checked to the cycle against the formulas of the module docstring,
written out again here by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stereosim.core.config import load_config
from stereosim.core.timing import lg, tree_cycles
from stereosim.sim.api import run
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.figures import architecture_report
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.readable.chip import run_readable
from stereosim.sva.geometry import lane_groups
from stereosim.sva.hamming.timing import hamming_stage
from stereosim.sva.median.timing import sorting_depth

# census (1 NNA cycle per descriptor, 32 bits), equal clocks: the input side is the one of
# tests/sim/cycle/readable/test_chip.py::test_census_first_and_last_output_cycles (row 0 ready
# at 6W + 3); the 3x3 median and the 5x5 box that derivation takes
BASE = {"clocks.nna_mhz": 400, "clocks.sva_mhz": 400, "nna.descriptor": "census",
        "sva.median": 3, "sva.box_size": 5}


def _ceil_log2(n):
    return math.ceil(math.log2(n)) if n > 1 else 0


def expected_ii_and_latency(d, lanes, paths, lr, *, levels=8, bits=32, box=5, median=3,
                            subpixel_bits=4):
    """The docstring's table, by hand."""
    lanes = min(lanes, d)
    g = -(-d // lanes)
    tree = lambda depth: -(-depth // levels) if depth else 0  # noqa: E731
    fold = 1 if g > 1 else 0
    left = g - 1 + tree(5) + tree(_ceil_log2(lanes) + fold)  # the step, then the min
    ii = max(g, left)
    latency = (1                            # the row buffers' read register
               + g + tree(_ceil_log2(bits))  # hamming: groups + popcount tree
               + g + tree(2) + tree(_ceil_log2(box) + 1)  # box: slide, row sum and cap
               + g + tree(5)                # SGM: the groups through the step's 5 levels
               + tree(_ceil_log2(paths) + 1)  # sum of the paths, cap
               + g + tree(_ceil_log2(lanes) + fold) + subpixel_bits + 1  # WTA, equiangular
               + ((d - 1) * ii + 1 if lr else 0)             # LR: the diagonal
               + (tree(10) if median == 3 else 0)            # 3x3 sorting network
               + 1)                                          # output register
    return ii, latency, max(1, g)  # the slot II: the row read's, the hamming's, the box's


@pytest.mark.parametrize("d", [16, 64, 128, 256])
@pytest.mark.parametrize("lanes", [16, 64, 128])
@pytest.mark.parametrize("paths", [1, 2, 3, 4])
@pytest.mark.parametrize("lr", [False, True])
def test_first_and_last_output_cycles_follow_the_stage_formulas(d, lanes, paths, lr):
    """The input side of
    tests/sim/cycle/readable/test_chip.py::test_census_first_and_last_output_cycles (input row q
    ready in (q + 3)W + 3; a free sink, so ticks are cycles), any II and slot II
    a: the four passes (rows 0, 0, 0, 1) start in 3W + 3 and take W a ticks each, so box row
    0 starts r = 2 slots after them, s_0 = 3W + 3 + 4W a + 2a; a row's words are an II
    apart and the next row starts max(II, 3a) after the last (its input rows are in by then),
    R = II (W - 1) + max(II, 3a) later. Word 0 leaves with word W + 1 (the 3x3 median's
    skew), issued at s_0 + R + II: the sink pops it L + 1 later; the last word with the
    W + 1-th flush tick after the frame's last word."""
    ii, latency, a = expected_ii_and_latency(d, lanes, paths, lr)
    # D < W; the row buffers are released as a row's words enter the pipeline, so the next
    # row is ready before the SVA needs it even when the frame is narrower than the latency
    w = max(d + 1, 40)
    h = 5
    cfg = load_config(overrides={**BASE, "sva.disparities": d, "sva.lanes": lanes,
                                 "sva.paths": paths, "sva.lr_check": lr})
    plan = build_plan(cfg, (h, w))
    sva = plan.block("sva")
    assert (sva.ii, sva.latency, sva.slot_ii) == (ii, latency, a)
    rng = np.random.default_rng(d + lanes)
    left = rng.integers(0, 256, (h, w), dtype=np.uint8)
    frame = run_compiled(plan, left, np.roll(left, -2, axis=1))
    cycles = frame.report["cycles"]
    assert (cycles["first_output"]["sva"], cycles["last_output"]["sva"]) == census_cycles(
        h, w, ii, a, latency)
    assert frame.report["throughput"]["bottleneck"] == "sva"


def census_cycles(h, w, ii, a, latency, flush=1):
    """(first, last) sink pop of :func:`test_first_and_last_output_cycles_follow_the_stage_
    formulas`'s derivation: box 5, 3x3 median, the census input side, II and slot II a; the
    median's W + 1 flush slots after the last word one ``flush`` ticks apart (its II)."""
    start = 3 * w + 3 + 4 * w * a + 2 * a
    row = ii * (w - 1) + max(ii, 3 * a)
    return (start + row + ii + latency + 1,
            start + (h - 1) * row + ii * (w - 1) + (w + 1) * flush + latency + 1)


def test_the_paper_configuration_gives_250_fps():
    """720p, D = 128, LR on, 465 MHz: II = ceil(128 / 128) + tree(7 levels) = 1 + 1 = 2, so
    the SVA's work per frame is 1280 x 720 x 2 cycles = 3.964 ms: 252.3 fps (250 within 1 %)."""
    cfg = load_config()
    plan = build_plan(cfg, (720, 1280))
    sva = plan.block("sva")
    assert sva.ii == 2
    fps = cfg.clocks.sva_mhz * 1e6 / (sva.items * sva.ii)
    assert abs(fps - 250) / 250 < 0.03
    assert round(fps, 1) == 252.3


def test_lanes_trade_against_the_left_path_recurrence():
    """Fewer lanes: more groups per pixel; the left path adds its step and its minimum tree
    once per pixel, so halving the lanes of D = 128 from 128 to 64 turns II 2 into 2 - 1 + 1 +
    1 = 3 (two groups, the step's tree(5) = 1, then tree(lg 64 + 1) = 1)."""
    ii = {lanes: build_plan(load_config(overrides={"sva.lanes": lanes}), (64, 300)).block("sva")
          .ii for lanes in (128, 64, 32, 16, 1)}
    assert ii == {128: 2, 64: 3, 32: 5, 16: 9, 1: 129}
    few_levels = load_config(overrides={"sva.compare_levels": 2})
    # 0 + tree(5 levels of the step) + tree(7) = 3 + 4
    assert build_plan(few_levels, (64, 300)).block("sva").ii == 3 + 4


def test_helpers():
    assert [lg(n) for n in (1, 2, 3, 4, 5, 128, 129)] == [0, 1, 2, 2, 3, 7, 8]
    assert [tree_cycles(t, 8) for t in (0, 1, 8, 9, 16)] == [0, 1, 1, 2, 2]
    assert sorting_depth(9) == 10 and sorting_depth(25) == 15
    assert lane_groups(load_config(overrides={"sva.disparities": 48, "sva.lanes": 32}).sva) == 2


def test_the_report_shows_each_stage_and_its_arithmetic():
    rep = architecture_report(build_plan(load_config(), (720, 1280)))["sva_pipeline"]
    assert rep["initiation_interval"] == 2
    assert [st["name"] for st in rep["stages"]] == [
        "row_read", "hamming", "box_filter", "sgm", "path_sum", "wta", "lr_check", "median",
        "output"]
    assert rep["latency"] == sum(st["latency"] for st in rep["stages"])
    lr = next(st for st in rep["stages"] if st["name"] == "lr_check")
    assert lr["latency"] == 127 * 2 + 1 and "127 x 2 + 1" in lr["formula"]


@pytest.mark.parametrize("lanes, d, ii_dual, ii_single", [
    (128, 128, 2, 2),  # the recurrence's second cycle leaves room for the second access
    (64, 128, 3, 4),  # two groups: the banks take 2 G = 4 cycles through one port
    (32, 128, 5, 8),
    (16, 64, 5, 8),
])
def test_single_port_srams_cost_what_their_accesses_need(lanes, d, ii_dual, ii_single):
    """Column sums and each top path's previous row: G reads and G writes per pixel. Two
    ports: max(G, G) = G, under the left path's II; one port: 2 G."""
    ii = {}
    for ports in ("1r1w", "1rw"):
        cfg = load_config(overrides={"sva.lanes": lanes, "sva.disparities": d,
                                     "sva.sram_ports": ports})
        ii[ports] = build_plan(cfg, (16, 300)).block("sva").ii
    assert (ii["1r1w"], ii["1rw"]) == (ii_dual, ii_single)
    g = -(-d // lanes)
    assert ii_single == max(ii_dual, 2 * g)


@pytest.mark.parametrize("lanes, d", [(16, 16), (16, 32), (8, 64)])
def test_the_descriptor_rows_cost_no_port_cycle_with_one_port(lanes, d):
    """The descriptor rows are a bank per row and view (the RTL top's ring): the arriving row's
    bank is only written, and a slot's two reads -- the row entering the column sums and the
    row leaving them -- are two other banks. One access a bank a slot: the matching cost's II
    is G with one port as with two (a bank per view would need a read and a write, 2)."""
    for ports in ("1r1w", "1rw"):
        cfg = load_config(overrides={"sva.lanes": lanes, "sva.disparities": d,
                                     "sva.sram_ports": ports})
        stage = hamming_stage(cfg, 100, (32,))
        rows = next(b for b in stage.buffers if b.name == "sva.descriptor_rows")
        assert rows.banks == 2 * (cfg.sva.box_size + 2)
        assert rows.port_cycles == 1
        assert stage.ii == -(-d // min(lanes, d))


def test_a_single_port_chip_runs_at_its_ii():
    """The cycle model follows the plan's II: a census chip (SVA-bound) with 64 lanes and
    single-port SRAM takes 4 cycles per word, and 4 per slot too (the column sums' G reads and
    G writes through one port): the passes take 4 W a = 16 W ticks. The single-port median
    takes a slot every second tick, so its W + 1 flush slots take 2 (W + 1) ticks."""
    cfg = load_config(overrides={**BASE, "sva.disparities": 128, "sva.lanes": 64,
                                 "sva.sram_ports": "1rw"})
    plan = build_plan(cfg, (5, 400))
    sva = plan.block("sva")
    assert (sva.ii, sva.slot_ii, sva.flush_ii) == (4, 4, 2)
    rng = np.random.default_rng(3)
    left = rng.integers(0, 256, (5, 400), dtype=np.uint8)
    cycles = run_compiled(plan, left, np.roll(left, -2, axis=1)).report["cycles"]
    assert (cycles["first_output"]["sva"], cycles["last_output"]["sva"]) == census_cycles(
        5, 400, 4, 4, sva.latency, flush=2)


def test_the_nna_submodules_report_says_what_the_idle_ones_could_give():
    """The pair uses 2 of the 10 submodules; all 10 (5 column tiles per camera) would give the
    NNA 5x the work rate (tile 256 columns instead of 1280: 55.459 -> 277.3 fps)."""
    rep = architecture_report(build_plan(load_config(), (720, 1280)))
    subs = rep["nna_submodules"]
    assert (subs["on_chip"], subs["stereo"], subs["idle"]) == (10, 2, 8)
    assert subs["nna_fps"] == round(460e6 / (9 * 1280 * 720), 3)
    assert subs["with_all"] == {"stereo_submodules": 10,
                                "nna_fps": round(460e6 / (9 * 256 * 720), 3)}
    mac = rep["nna_pipeline"][1]
    assert (mac["name"], mac["ii"], mac["latency"]) == ("mac_array", 9, 9)
    assert "288 MACs per cycle, 100.0 % of the array busy" in mac["formula"]
    bands = load_config(overrides={"sva.disparities": 16, "nna.split": "rows"})
    short = architecture_report(build_plan(bands, (4, 40)))["nna_submodules"]
    assert short["with_all"] is None  # 5 row bands per camera: more than the frame's 4 rows


def test_stage_activity_follows_the_words_through_the_stages():
    """SVA-bound census chip, words issued II = 2 ticks apart inside a row and max(II, (r + 1)
    a) = 3 apart at each of the H - 1 later rows' starts (the box's r = 2 look-ahead slots),
    without a stall: a stage of latency l holds word j for ticks t_j + offset + 1 .. t_j +
    offset + l, so it is busy (n - H) min(l, II) + (H - 1) min(l, 3) + l cycles, never
    blocked, and holds at most ceil(l / II) words -- the LR window exactly D; every stage
    accounts for every cycle of the run."""
    cfg = load_config(overrides={**BASE, "sva.disparities": 16})
    rng = np.random.default_rng(1)
    h, w = 8, 80
    plan = build_plan(cfg, (h, w))
    rep = run_compiled(plan, rng.integers(0, 256, (h, w), dtype=np.uint8),
                       rng.integers(0, 256, (h, w), dtype=np.uint8)).report
    stages, sva = rep["sva_stages"], rep["blocks"]["sva"]
    ii, n = plan.block("sva").ii, h * w
    assert ii == 2
    for st in plan.block("sva").stages:
        got = stages[st.name]
        assert got["busy"] + got["starved"] + got["blocked"] + got["idle"] == sva["cycles_total"]
        assert got["busy"] == ((n - h) * min(st.latency, ii) + (h - 1) * min(st.latency, 3)
                               + st.latency), st.name
        assert got["blocked"] == 0
        assert got["peak_words"] == -(-st.latency // ii) <= got["capacity_words"], st.name
        buf = rep["buffers"]["sva"][f"pipeline.{st.name}"]
        assert buf["peak_words"] == got["peak_words"]
        assert buf["capacity_bits"] == st.slots * st.slot_bits
    assert stages["lr_check"]["peak_words"] == stages["lr_check"]["capacity_words"] == 16
    assert stages["sgm"]["utilization_percent"] > stages["output"]["utilization_percent"]


@pytest.mark.parametrize("d", [16, 48])
@pytest.mark.parametrize("lanes", [8, 64])
@pytest.mark.parametrize("paths", [1, 4])
@pytest.mark.parametrize("lr", [False, True])
def test_the_readable_pipeline_is_bit_exact_across_the_stage_matrix(d, lanes, paths, lr):
    """The readable kernel computes its words from the descriptors it received, issued and
    pushed through the stages at their own II and latency (with a stalling sink): the words
    equal the functional model's for every stage configuration."""
    cfg = load_config(overrides={**BASE, "sva.disparities": d, "sva.lanes": lanes,
                                 "sva.paths": paths, "sva.lr_check": lr,
                                 "fifo.sva_to_sink_depth": 1})
    h, w = 5, d + 7
    rng = np.random.default_rng(d * lanes + paths)
    left = rng.integers(0, 256, (h, w), dtype=np.uint8)
    right = np.roll(left, -3, axis=1)
    frame = run_readable(build_plan(cfg, (h, w)), left, right, sink_stall=(11, 1))
    functional = run(left, right, mode="functional", config=cfg).disparity_fixed
    np.testing.assert_array_equal(frame.words, functional)
    assert frame.report["blocks"]["sva"]["blocked"] > 0
