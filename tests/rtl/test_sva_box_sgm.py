"""The RTL box filter (sva/box/sva_box.sv) and SGM path units with the path sum
(sva/sgm/sva_sgm.sv) co-simulated against stereosim (tests/rtl/box_bench.py,
tests/rtl/sgm_bench.py): every word bit-exact with sva/box/aggregation.py's and sva/sgm/sgm.py's
references on random volumes, every pixel out in the tick the chip plan's stage says, and a
slot offered back to back taken one II after the one before -- the plan's box_filter, sgm and
path_sum stages (sim.cycle.stages.sva_stages), read at test time.

Structure is build-time (the largest D, lanes, levels a cycle V, the largest box, the widest
row, the widths); D (so G = ceil(D / lanes)), the box size, P1, P2, the adaptive P2 and its
slope and the paths enabled are run-time registers. One Verilator build serves every test: a
twin top holding the box filter, the SGM stage and the one-cycle mutant of the box filter side
by side, the box filter and the SGM stage again at V = 2, and again at V = 8 with single-port
memories (ONE_PORT: sva.sram_ports = "1rw"), each bench driving its own stage's ports
(prefixed box_, sgm_, late_, box2_, sgm2_, box1_, sgm1_).

With one port the column sums need G reads and G writes a slot, the top paths' previous rows
G and G a pixel: the plan's II 2 G (the SGM's the larger of it and the left path's
recurrence; one path: no previous rows, no port), its latencies unchanged -- the runs of the
box1_ and sgm1_ instances read the plan with sva.sram_ports = "1rw", at G = 1 and G = 2. A
finding, the box filter: a slot that updates no column (a row's r right-border slots) writes
nothing, and the structure takes the next slot G ticks after it, not the plan's 2 G (the top
issues every slot one slot II apart, so only the stage alone shows it; box_bench.py checks
both spacings).
"""

import math
from pathlib import Path

import pytest

SVA = Path(__file__).resolve().parents[2] / "sva"

# box: D up to 32 in lanes of 16 (D = 16: G = 1, D = 32: G = 2), boxes up to 7, costs of 6 bits
# (a 32-bit descriptor's), sums saturating at 8 bits (sva.cost_bits = 8: box 7's auto width
# would be 11, so the saturation is exercised)
BOX = {"D_MAX": 32, "LANES": 16, "V": 8, "K_MAX": 7, "W_MAX": 24, "COST_W": 6, "A_W": 8}
# SGM: D up to 32 in lanes of 16, V = 8, rows up to 24, A of 8 bits (sva.cost_bits), path
# costs of 9 bits and sums of 10 (sva.path_bits, sva.sum_bits: both saturate here)
SGM = {"D_MAX": 32, "LANES": 16, "V": 8, "W_MAX": 24, "A_W": 8, "PATH_W": 9, "SUM_W": 10}
# the same at V = 2, where the plan's earlier box G + 2, SGM G + tree(lg(L) + [G > 1]) and
# path sum tree(lg(paths)) were short of the structure (its rules now are the structure's):
# their runs keep to what a build for the largest box, D and paths shares with the config's
# plan -- boxes 3..7 (lg(k) + 1 = 3 or 4 levels: 2 cycles), D = 32 (G = 2), 3 or 4 paths
BOX2, SGM2 = {**BOX, "V": 2}, {**SGM, "V": 2}
# single-port memories (sva.sram_ports = "1rw") at V = 8: D = 16 (G = 1) and D = 32 (G = 2)
BOX1, SGM1 = {**BOX, "ONE_PORT": 1}, {**SGM, "ONE_PORT": 1}


def box_ports(b: dict) -> list[tuple[str, str, int]]:
    d_in = b["D_MAX"] * b["COST_W"]
    ins = [("en", 1), ("ngroups", 8), ("k", 4), ("in_valid", 1),
           ("col", math.ceil(math.log2(b["W_MAX"]))), ("upd", 1), ("fresh", 1), ("fill", 1),
           ("emit", 1), ("c_add", d_in), ("c_sub", d_in)]
    outs = [("in_ready", 1), ("out_valid", 1), ("agg", b["D_MAX"] * b["A_W"])]
    return [("input", n, w) for n, w in ins] + [("output", n, w) for n, w in outs]


def sgm_ports(s: dict) -> list[tuple[str, str, int]]:
    ins = [("en", 1), ("ngroups", 8), ("dn", 9), ("width", 8), ("p1", 15), ("p2", 15),
           ("adaptive", 1), ("slope", 15), ("paths", 3), ("in_valid", 1),
           ("a", s["D_MAX"] * s["A_W"]), ("grey", 8), ("grey_up", 24), ("x_first", 1),
           ("x_last", 1), ("y_first", 1)]
    outs = [("in_ready", 1), ("lc_valid", 1), ("lc", 4 * s["D_MAX"] * s["PATH_W"]),
            ("s_valid", 1), ("s", s["D_MAX"] * s["SUM_W"])]
    return [("input", n, w) for n, w in ins] + [("output", n, w) for n, w in outs]


def late_box(text: str) -> str:
    """The box filter one cycle late: one more pipeline register in the row-sum tree (after
    its first level, the control's delay line one longer to match), renamed sva_box_late."""
    mutant = text.replace("(l < RS_LEVELS) && (l % V == 0)",
                          "(l < RS_LEVELS) && (l % V == 0 || l == 1)")
    mutant = mutant.replace("localparam int RS_T = (RS_LEVELS + V - 1) / V;",
                            "localparam int RS_T = (RS_LEVELS + V - 1) / V + 1;")
    mutant = mutant.replace("module sva_box #(", "module sva_box_late #(")
    assert mutant.count("l == 1)") == 1 and "/ V + 1;" in mutant and "sva_box_late" in mutant
    return mutant


@pytest.fixture(scope="module")
def twin(rtl_twin_top):
    """The stages' texts and a top instantiating each with its build parameters, every port
    brought out with its stage's prefix."""
    box = (SVA / "box" / "sva_box.sv").read_text()
    top = rtl_twin_top("sva_box_sgm_twin", [
        ("sva_box", "box_", BOX, box_ports(BOX)), ("sva_sgm", "sgm_", SGM, sgm_ports(SGM)),
        ("sva_box", "box2_", BOX2, box_ports(BOX2)), ("sva_sgm", "sgm2_", SGM2, sgm_ports(SGM2)),
        ("sva_box", "box1_", BOX1, box_ports(BOX1)), ("sva_sgm", "sgm1_", SGM1, sgm_ports(SGM1)),
        ("sva_box_late", "late_", BOX, box_ports(BOX))])
    return ("\n".join([box, (SVA / "sgm" / "sva_sgm.sv").read_text(), late_box(box), top]),)


def run_twin(rtl_run, twin, bench: str, case: dict, fails: bool = False) -> str:
    return rtl_run(twin, "sva_box_sgm_twin", {}, bench, case, fails=fails)


def ports(build: dict) -> str:
    """The plan's sva.sram_ports for an instance built with ``build``."""
    return "1rw" if build.get("ONE_PORT") else "1r1w"


def box_runs():
    runs = []
    for i, (pre, b, d, k, h, w, offer, stall) in enumerate([
        ("box_", BOX, 16, 3, 5, 12, 1.0, 0.0), ("box_", BOX, 32, 5, 6, 16, 0.6, 0.15),
        ("box_", BOX, 16, 7, 5, 20, 0.8, 0.1), ("box_", BOX, 32, 1, 4, 12, 1.0, 0.2),
        ("box_", BOX, 32, 7, 6, 14, 1.0, 0.0),
        ("box2_", BOX2, 32, 5, 5, 13, 0.8, 0.1), ("box2_", BOX2, 16, 3, 4, 12, 1.0, 0.0),
        ("box1_", BOX1, 16, 3, 4, 12, 1.0, 0.0), ("box1_", BOX1, 32, 5, 5, 13, 1.0, 0.0),
        ("box1_", BOX1, 32, 7, 4, 12, 0.8, 0.15),
    ]):
        runs.append({"seed": 11 + i, "h": h, "w": w, "offer": offer, "stall": stall,
                     "prefix": pre,
                     "overrides": {"sva.disparities": d, "sva.lanes": b["LANES"],
                                   "sva.compare_levels": b["V"], "sva.box_size": k,
                                   "sva.cost_bits": b["A_W"], "sva.sram_ports": ports(b)}})
    return runs


def test_the_rtl_box_filter_equals_the_model(rtl_run, twin):
    run_twin(rtl_run, twin, "box_bench", {"runs": box_runs(),
                                          "cost_w": BOX["COST_W"], "a_w": BOX["A_W"]})


def sgm_runs():
    runs = []
    for i, (pre, b, d, paths, p1, p2, adaptive, slope, h, w, offer, stall) in enumerate([
        ("sgm_", SGM, 16, 1, 10, 120, False, 16, 5, 12, 1.0, 0.0),
        ("sgm_", SGM, 32, 2, 20, 300, True, 512, 5, 14, 0.7, 0.15),
        ("sgm_", SGM, 16, 4, 30, 200, True, 1024, 6, 12, 1.0, 0.1),
        ("sgm_", SGM, 32, 4, 7, 400, False, 16, 5, 16, 1.0, 0.0),
        ("sgm_", SGM, 32, 3, 50, 30, True, 64, 4, 12, 0.8, 0.1),
        ("sgm2_", SGM2, 32, 4, 12, 250, True, 512, 5, 13, 0.8, 0.1),
        ("sgm2_", SGM2, 32, 3, 9, 180, False, 16, 4, 12, 1.0, 0.0),
        ("sgm1_", SGM1, 16, 4, 30, 200, True, 512, 4, 12, 1.0, 0.0),
        ("sgm1_", SGM1, 32, 3, 20, 300, False, 16, 4, 12, 1.0, 0.0),
        ("sgm1_", SGM1, 32, 2, 12, 250, True, 1024, 4, 13, 0.8, 0.15),
        ("sgm1_", SGM1, 32, 1, 10, 120, False, 16, 3, 12, 1.0, 0.0),
    ]):
        runs.append({"seed": 31 + i, "h": h, "w": w, "offer": offer, "stall": stall,
                     "prefix": pre,
                     "overrides": {"sva.disparities": d, "sva.lanes": b["LANES"],
                                   "sva.compare_levels": b["V"], "sva.paths": paths,
                                   "sva.p1": p1, "sva.p2": p2, "sva.p2_adaptive": adaptive,
                                   "sva.p2_slope": slope, "sva.cost_bits": b["A_W"],
                                   "sva.path_bits": b["PATH_W"], "sva.sum_bits": b["SUM_W"],
                                   "sva.sram_ports": ports(b)}})
    return runs


def test_the_rtl_sgm_and_path_sum_equal_the_model(rtl_run, twin):
    run_twin(rtl_run, twin, "sgm_bench", {"runs": sgm_runs(),
                                          "a_w": SGM["A_W"], "d_max": SGM["D_MAX"]})


def test_a_one_cycle_mutant_of_the_rtl_box_filter_is_caught_by_name(rtl_run, twin):
    """The box filter with one more register in its row-sum tree (:func:`late_box`): the sums
    stay right, every pixel leaves a tick late, and the co-simulation names the plan's
    box_filter latency."""
    xml = run_twin(rtl_run, twin, "box_bench",
                   {"runs": [{**box_runs()[0], "prefix": "late_"}], "cost_w": BOX["COST_W"],
                    "a_w": BOX["A_W"]}, fails=True)
    assert "the plan's box_filter latency" in xml
