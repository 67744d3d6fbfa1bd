"""The RTL matching-cost stage (sva/rtl/sva_hamming.sv) co-simulated against stereosim: every
cost bit-exact with sva/cost.py and every pixel out in the cycle the chip plan's stage says
(tests/rtl/hamming_bench.py). Structure is build-time (D, lanes, levels a cycle, the parts'
bits); the weights are run-time registers, so one build serves several weight pairs."""

from pathlib import Path

import pytest

from stereosim.sim.config.widths import largest_cost
from stereosim.sva.geometry import bits_for

RTL_SOURCE = Path(__file__).resolve().parents[2] / "sva" / "rtl" / "sva_hamming.sv"

# (D, lanes, compare levels, parts): one part (a CNN's 32 bits, a census's), the hybrid's two
BUILDS = [
    (16, 16, 8, (32,)),
    (32, 8, 2, (32, 32)),
    (16, 5, 1, (32, 26)),
    (48, 48, 3, (24,)),
]


@pytest.mark.parametrize(("d", "lanes", "levels", "parts"), BUILDS)
def test_the_rtl_stage_equals_the_model(rtl_run, d, lanes, levels, parts):
    cost_w = bits_for(largest_cost(parts, ((3, 3),)) if len(parts) > 1 else parts[0])
    params = {"D": d, "LANES": lanes, "V": levels, "B0": parts[0],
              "B1": parts[1] if len(parts) > 1 else 0, "COST_W": cost_w}
    over = {"sva.disparities": 16 if d == 16 else 32 if d == 32 else 48,
            "sva.lanes": lanes, "sva.compare_levels": levels}
    weight_sets = [(3, 2), (0, 1), (2, 0)] if len(parts) > 1 else [(1, 0)]
    runs = [{"weights": list(w), "seed": 7 * i + int(10 * offer), "offer": offer}
            for i, w in enumerate(weight_sets) for offer in (1.0, 0.4)]
    rtl_run("sva/rtl/sva_hamming.sv", "sva_hamming", params, "hamming_bench",
            {"overrides": over, "parts": list(parts), "pixels": 12, "cost_w": cost_w,
             "runs": runs})


def _hybrid_case():
    parts, d, lanes, levels = (32, 26), 16, 8, 4
    params = {"D": d, "LANES": lanes, "V": levels, "B0": 32, "B1": 26,
              "COST_W": bits_for(largest_cost(parts, ((3, 3),)))}
    case = {"overrides": {"sva.disparities": d, "sva.lanes": lanes,
                          "sva.compare_levels": levels},
            "parts": list(parts), "pixels": 6, "cost_w": params["COST_W"],
            "runs": [{"weights": [3, 2], "seed": 1, "offer": 1.0}]}
    return params, case


def test_a_one_cycle_mutant_of_the_rtl_stage_is_caught_by_name(rtl_run):
    """One more pipeline register in the tree (after its first level too, the lane-group
    delay line one longer to match): the words stay right, the stage is a cycle late, and the
    co-simulation names the plan's hamming latency."""
    params, case = _hybrid_case()
    text = RTL_SOURCE.read_text()
    mutant = text.replace("(l < LEVELS) && (l % V == 0)", "(l < LEVELS) && (l % V == 0 || l == 1)")
    mutant = mutant.replace("localparam int T = (LEVELS + V - 1) / V;",
                            "localparam int T = (LEVELS + V - 1) / V + 1;")
    assert mutant.count("l == 1") == 1 and "/ V + 1;" in mutant
    xml = rtl_run((mutant,), "sva_hamming", params, "hamming_bench", case, fails=True)
    assert "the plan's hamming latency" in xml


def test_a_one_cycle_mutant_of_the_rule_is_caught_by_name(rtl_run):
    """The plan's hamming latency one cycle more than the structure gives: the unchanged RTL
    catches it, by name."""
    params, case = _hybrid_case()
    case["runs"][0]["rule_mutant"] = True
    xml = rtl_run("sva/rtl/sva_hamming.sv", "sva_hamming", params, "hamming_bench", case,
                  fails=True)
    assert "the plan's hamming latency" in xml
