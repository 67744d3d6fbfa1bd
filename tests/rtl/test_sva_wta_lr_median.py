"""The RTL disparity selection (sva/wta/sva_wta.sv), LR check (sva_lr.sv) and median
(sva_median.sv) co-simulated against stereosim: every word bit-exact with sva/wta/wta.py,
sva/lr/lr_check.py and sva/median/median.py, every word out in the tick the chip plan's stage says
(tests/rtl/wta_bench.py, lr_bench.py, median_bench.py).

One Verilator build: a wrapper top holds every instance (three WTA structures, the LR check,
the 5x5 and 3x3 medians, the 5x5 median with single-port row banks (ONE_PORT: sva.sram_ports =
"1rw", the plan's median II 2), and a one-cycle mutant of the WTA), each behind its own ports. The
uniqueness margin, the sub-pixel mode, the frame size, the pipeline's II and max_diff are
run-time registers, so the one build serves every configuration below.

A finding of this co-simulation, resolved in the plan: the plan's wta latency was G +
tree(lg(D)) + [uniq] + sub, the RTL's is G + tree(lg(LANES) + [G > 1]) + [uniq] + sub -- its
lane groups fold one by one into a running node, one level after the lane tree, not a tree
over D; with G > 2 the two differed (D 16, 4 lanes, V 1: 7 ticks against 8). The plan now
states the structure's (sim/cycle/stages.py), and the instance "wc_" holds it to that. One
more the median bench's contract states, open (docs/rtl.md): the median's latency is the plan's
counted from the slot that completes its window (the word at (y + M, x + M)): the stream is
skewed by M W + M slots, which the plan's stage latency leaves out. The LR check's (D - 1) II
+ 1 holds for any row gap >= II: a row's last D - 1 words leave from a drain copy of the window
that shifts by itself (sva_lr.sv), so the runs below start rows at random gaps, whole IIs or
not.
"""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SVA = ROOT / "sva"
SW, F, DB, WB = 12, 4, 4, 9  # summed costs < 2^12, 4 fractional bits, D = 16: 9-bit words

# the WTA instances: prefix, lanes, compare levels (wc_: G = 4 at V = 1, where the plan's old
# tree over D was a tick longer than the structure's fold)
WTAS = [("wa_", 16, 2), ("wb_", 5, 2), ("wc_", 4, 1)]
# the medians: prefix, window, compare levels, one port (the row banks: sva.sram_ports 1rw)
MEDIANS = [("md_", 5, 4, 0), ("m3_", 3, 3, 0), ("m1_", 5, 4, 1)]
MUTANT = "(l < LEVELS) && (l % V == 0)"  # a register after every V levels of the lane tree


def _ports(pre: str, names: list[str]) -> str:
    return ", ".join(f".{n}({pre}{n})" for n in names)


def wrapper() -> str:
    """The one build's text: the three modules, a WTA mutant with a register after the tree's
    first level too (a cycle late, its words unchanged), and a top with every instance."""
    wta = (SVA / "wta" / "sva_wta.sv").read_text()
    mutant = wta.replace("module sva_wta", "module sva_wta_mutant").replace(
        MUTANT, "(l < LEVELS) && (l % V == 0 || l == 1)")
    assert mutant.count("l == 1") == 1 and "sva_wta_mutant" in mutant
    ports, body = ["input logic clk"], []
    wta_io = [("rst", 1, "input"), ("en", 1, "input"), ("in_valid", 1, "input"),
              ("in_ready", 1, "output"), ("s_in", 16 * SW, "input"), ("uniq", 7, "input"),
              ("mode", 2, "input"), ("out_valid", 1, "output"), ("q", WB, "output"),
              ("dstar", DB, "output"), ("s1", SW, "output")]
    wtas = [(pre, lanes, v, "sva_wta") for pre, lanes, v in WTAS]
    wtas.append(("wm_", 16, 2, "sva_wta_mutant"))
    for pre, lanes, v, mod in wtas:
        ports += [f"{io} logic [{n - 1}:0] {pre}{name}" for name, n, io in wta_io]
        body.append(f"  {mod} #(.D(16), .LANES({lanes}), .V({v}), .SW({SW}), .F({F}), "
                    f".DB({DB})) u_{pre}(.clk(clk), {_ports(pre, [x for x, _, _ in wta_io])});")
    lr_io = [("rst", 1, "input"), ("en", 1, "input"), ("in_valid", 1, "input"),
             ("s_in", 16 * SW, "input"), ("q_in", WB, "input"), ("d_in", DB, "input"),
             ("width", 8, "input"), ("ii", 8, "input"), ("max_diff", 8, "input"),
             ("out_valid", 1, "output"), ("q_out", WB, "output")]
    ports += [f"{io} logic [{n - 1}:0] lr_{name}" for name, n, io in lr_io]
    body.append(f"  sva_lr #(.D(16), .SW({SW}), .DB({DB}), .WB({WB}), .XW(8)) u_lr(.clk(clk), "
                f"{_ports('lr_', [x for x, _, _ in lr_io])});")
    md_io = [("rst", 1, "input"), ("en", 1, "input"), ("in_valid", 1, "input"),
             ("in_ready", 1, "output"), ("word", WB, "input"), ("width", 6, "input"),
             ("height", 6, "input"), ("out_valid", 1, "output"), ("med", WB, "output")]
    for pre, k, v, one in MEDIANS:
        ports += [f"{io} logic [{n - 1}:0] {pre}{name}" for name, n, io in md_io]
        body.append(f"  sva_median #(.K({k}), .V({v}), .WB({WB}), .WMAX(32), .XW(6), .YW(6), "
                    f".ONE_PORT({one})) u_{pre}(.clk(clk), "
                    f"{_ports(pre, [x for x, _, _ in md_io])});")
    top = ("module sva_select_top (\n  " + ",\n  ".join(ports) + "\n);\n" + "\n".join(body)
           + "\nendmodule\n")
    return "\n".join([wta, mutant, (SVA / "lr" / "sva_lr.sv").read_text(),
                      (SVA / "median" / "sva_median.sv").read_text(), top])


@pytest.fixture(scope="module")
def top():
    return (wrapper(),)


def _over(lanes: int, levels: int, **more) -> dict:
    return {"sva.disparities": 16, "sva.lanes": lanes, "sva.compare_levels": levels,
            "sva.subpixel_bits": F, **more}


def _wta_runs(pre: str, lanes: int, levels: int, pixels: int = 24) -> list:
    """The runs of a WTA instance: (u, mode, offer rate, stall rate) -- sub-pixel off,
    parabola and equiangular, the uniqueness check off and on, gaps and stalls."""
    runs = [(0, 0, 1.0, 0.0), (0, 1, 0.5, 0.2), (25, 2, 1.0, 0.2), (40, 1, 0.6, 0.0)]
    return [{"stage": "wta", "prefix": pre, "overrides": _over(lanes, levels),
             "pixels": pixels, "uniq": u, "mode": m, "offer": o,
             "stall": s, "seed": 11 * i + lanes}
            for i, (u, m, o, s) in enumerate(runs)]


def _median_runs(pre: str, k: int, levels: int, one: int) -> list:
    """Frames of 5 x 12 .. 8 x 23 words, with bubbles and stalls or without (one port: two
    frames)."""
    over = _over(16, levels, **{"sva.median": k, "sva.sram_ports": "1rw" if one else "1r1w"})
    top = (15 << F) + (1 << (F - 1))  # the largest word at D = 16
    frames = ({"height": 5, "width": 12, "gap": 0.0, "stall": 0.0, "seed": 1},
              {"height": 8, "width": 23, "gap": 0.3, "stall": 0.2, "seed": 2},
              {"height": 6, "width": 17, "gap": 0.1, "stall": 0.0, "seed": 3})
    return [{"stage": "median", "prefix": pre, "overrides": over, "top": top, **r}
            for r in (frames[:2] if one else frames)]


def _lr_runs() -> list:
    """Two pipeline IIs, the plan's (sim.cycle.stages.pipeline_ii) at 16 lanes, V 2 and at 4
    lanes, V 1; rows at random gaps >= II (lr_bench.row_gaps: II, II + 1 and others), the
    drain copy checked."""
    return [{"stage": "lr", "prefix": "lr_", "inst": "u_lr", "height": 5, "width": 20,
             "stall": 0.0, "seed": 4, "overrides": _over(16, 2)},
            {"stage": "lr", "prefix": "lr_", "inst": "u_lr", "height": 6, "width": 18,
             "stall": 0.2, "seed": 5, "overrides": _over(4, 1, **{"sva.lr_max_diff": 1})}]


def test_the_rtl_stages_equal_the_model(rtl_run, top):
    """Every WTA instance (four runs each), the LR check (two pipeline IIs) and the medians
    (three frames each, two with one port) in one simulation: words bit-exact, latency and II
    the plan's."""
    runs = [r for pre, lanes, levels in WTAS for r in _wta_runs(pre, lanes, levels)]
    runs += _lr_runs()
    runs += [r for pre, k, levels, one in MEDIANS for r in _median_runs(pre, k, levels, one)]
    rtl_run(top, "sva_select_top", {}, "wta_bench", {"sw": SW, "wb": WB, "runs": runs})


def test_a_one_cycle_mutant_of_the_rtl_wta_is_caught_by_name(rtl_run, top):
    """A pipeline register after the lane tree's first level too: the words stay right, the
    stage is a tick late, and the co-simulation names the plan's wta latency."""
    xml = rtl_run(top, "sva_select_top", {}, "wta_bench",
                  {"sw": SW, "wb": WB, "runs": _wta_runs("wm_", 16, 2, pixels=6)[:1]},
                  fails=True)
    assert "the plan's wta latency" in xml
