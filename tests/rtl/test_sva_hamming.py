"""The RTL matching-cost stage (sva/rtl/sva_hamming.sv) co-simulated against stereosim: every
cost bit-exact with sva/cost.py and every pixel out in the cycle the chip plan's stage says
(tests/rtl/hamming_bench.py). Structure is build-time (D, lanes, levels a cycle, the parts'
bits); the weights are run-time registers, so one build serves several weight pairs."""

import pytest

from stereosim.sim.config.widths import largest_cost
from stereosim.sva.geometry import bits_for

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
