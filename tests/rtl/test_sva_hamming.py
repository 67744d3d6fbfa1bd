"""The RTL matching-cost stage (sva/hamming/sva_hamming.sv) co-simulated against stereosim: every
cost bit-exact with sva/hamming/cost.py and every pixel out in the cycle the chip plan's stage says
(tests/rtl/hamming_bench.py). Structure is build-time (D, lanes, levels a cycle, the parts'
bits); the weights are run-time registers, so one build serves several weight pairs.

One Verilator build: a twin top holds the four structures below and a one-cycle mutant of the
stage side by side, each instance's ports prefixed (h0_ .. h3_, late_), and the RTL of the
worked example of docs/rtl.md (tests/rtl/user_example_bench.py) with its ports unprefixed."""

from pathlib import Path

import pytest

from stereosim.core.config.widths import largest_cost
from stereosim.sva.geometry import bits_for

RTL_SOURCE = Path(__file__).resolve().parents[2] / "sva" / "hamming" / "sva_hamming.sv"

# (D, lanes, compare levels, parts): one part (a CNN's 32 bits, a census's), the hybrid's two
BUILDS = [
    (16, 16, 8, (32,)),
    (32, 8, 2, (32, 32)),
    (16, 5, 1, (32, 26)),
    (48, 48, 3, (24,)),
]
HYBRID = (16, 8, 4, (32, 26))  # the mutants' structure
USER = (16, 16, 8, (32,))  # the worked example's RTL (tests/rtl/user_example_bench.py)


def _params(d, lanes, levels, parts) -> dict:
    cost_w = bits_for(largest_cost(parts, ((3, 3),)) if len(parts) > 1 else parts[0])
    return {"D": d, "LANES": lanes, "V": levels, "B0": parts[0],
            "B1": parts[1] if len(parts) > 1 else 0, "COST_W": cost_w}


def late(text: str) -> str:
    """The stage one cycle late: one more pipeline register in the tree (after its first level
    too, the lane-group delay line one longer to match), renamed sva_hamming_late."""
    mutant = text.replace("(l < LEVELS) && (l % V == 0)", "(l < LEVELS) && (l % V == 0 || l == 1)")
    mutant = mutant.replace("localparam int T = (LEVELS + V - 1) / V;",
                            "localparam int T = (LEVELS + V - 1) / V + 1;")
    mutant = mutant.replace("module sva_hamming #(", "module sva_hamming_late #(")
    assert mutant.count("l == 1") == 1 and "/ V + 1;" in mutant and "_late #(" in mutant
    return mutant


def instance(prefix: str, module: str, d, lanes, levels, parts):
    """(module, prefix, parameters, ports) of one build in the twin top."""
    p = _params(d, lanes, levels, parts)
    bits = p["B0"] + p["B1"]
    return (module, prefix, p, [
        ("input", "en", 1), ("input", "in_valid", 1), ("output", "in_ready", 1),
        ("input", "dl", bits),
        ("input", "dr", d * bits), ("input", "outside", d), ("input", "w0", 2),
        ("input", "w1", 2), ("output", "out_valid", 1), ("output", "cost", d * p["COST_W"])])


@pytest.fixture(scope="module")
def twin(rtl_twin_top):
    """The stage's text, its mutant's and a top holding every build and the mutant."""
    text = RTL_SOURCE.read_text()
    insts = [instance(f"h{i}_", "sva_hamming", *b) for i, b in enumerate(BUILDS)]
    insts.append(instance("late_", "sva_hamming_late", *HYBRID))
    insts.append(instance("", "sva_hamming", *USER))  # user_example_bench's RTL, unprefixed
    return ("\n".join([text, late(text), rtl_twin_top("sva_hamming_twin", insts)]),)


def _case(prefix, d, lanes, levels, parts, runs, pixels=12) -> dict:
    return {"prefix": prefix, "parts": list(parts), "pixels": pixels,
            "cost_w": _params(d, lanes, levels, parts)["COST_W"], "runs": runs,
            "overrides": {"sva.disparities": d, "sva.lanes": lanes,
                          "sva.compare_levels": levels}}


def test_the_rtl_stage_equals_the_model(rtl_run, twin):
    """Every build of :data:`BUILDS`, its weight sets back to back and with input gaps, in one
    simulator run (each run carries its build's prefix and plan overrides)."""
    runs = []
    for i, (d, lanes, levels, parts) in enumerate(BUILDS):
        weight_sets = [(3, 2), (0, 1), (2, 0)] if len(parts) > 1 else [(1, 0)]
        own = {k: v for k, v in _case(f"h{i}_", d, lanes, levels, parts, []).items()
               if k != "runs"}
        runs += [{**own, "weights": list(w), "seed": 7 * k + int(10 * offer), "offer": offer}
                 for k, w in enumerate(weight_sets) for offer in (1.0, 0.4)]
    rtl_run(twin, "sva_hamming_twin", {}, "hamming_bench", {"runs": runs})


def _hybrid_runs() -> list:
    return [{"weights": [3, 2], "seed": 1, "offer": 1.0}]


def test_a_one_cycle_mutant_of_the_rtl_stage_is_caught_by_name(rtl_run, twin):
    """One more pipeline register in the tree (:func:`late`): the words stay right, the stage
    is a cycle late, and the co-simulation names the plan's hamming latency."""
    xml = rtl_run(twin, "sva_hamming_twin", {}, "hamming_bench",
                  _case("late_", *HYBRID, _hybrid_runs(), pixels=6), fails=True)
    assert "the plan's hamming latency" in xml


def test_a_one_cycle_mutant_of_the_rule_is_caught_by_name(rtl_run, twin):
    """The plan's hamming latency one cycle more than the structure gives: the unchanged RTL
    of a hybrid build (h2_: 32 + 26 bits, 5 lanes, V 1) catches it, by name."""
    twin_case = _case("h2_", *BUILDS[2], [{**_hybrid_runs()[0], "rule_mutant": True}], pixels=6)
    xml = rtl_run(twin, "sva_hamming_twin", {}, "hamming_bench", twin_case, fails=True)
    assert "the plan's hamming latency" in xml


def test_the_worked_example_of_a_users_own_test_passes(rtl_run, twin):
    """docs/rtl.md's worked example: a user's cocotb test that takes its expected costs and
    cycles from stereosim (tests/rtl/user_example_bench.py)."""
    rtl_run(twin, "sva_hamming_twin", {}, "user_example_bench", {})
