"""A worked example: a user's own cocotb test of their own matching-cost RTL, with stereosim
as the scoreboard (docs/rtl.md, "Your RTL against stereosim"). stereosim gives the expected
costs (its reference, sva/hamming/cost.py) and the expected cycles (its chip plan's stage for the
same configuration). The RTL under test here is sva/hamming/sva_hamming.sv built for D = 16, 16
lanes, V = 8 and one 32-bit descriptor, its ports at the top level; put yours in its place.
"""

import cocotb
import numpy as np
from cocotb.clock import Clock
from cocotb.triggers import ReadOnly, RisingEdge

from stereosim.core.config import load_config
from stereosim.sva.hamming.cost import cost_parts, hamming_cost_ref
from stereosim.sva.hamming.timing import hamming_stage

D, BITS, W = 16, 32, 24  # disparities, descriptor bits, pixels in the row driven


@cocotb.test()
async def my_costs_arrive_when_stereosim_says(dut):
    cfg = load_config(overrides={"sva.disparities": D, "sva.lanes": 16,
                                 "sva.compare_levels": 8})
    stage = hamming_stage(cfg, W, (BITS,))  # the plan's II and latency for this chip
    rng = np.random.default_rng(2026)
    left = rng.integers(0, 1 << BITS, (1, W), dtype=np.uint64)
    right = rng.integers(0, 1 << BITS, (1, W), dtype=np.uint64)
    want = hamming_cost_ref(left, right, D, cost_parts(BITS))[0]  # (W, D): stereosim's costs

    cocotb.start_soon(Clock(dut.clk, 10, unit="ns").start())
    dut.rst.value, dut.en.value, dut.in_valid.value = 1, 1, 0  # en: the pipeline advances
    dut.w0.value, dut.w1.value = 1, 0  # one part: the distance itself
    await RisingEdge(dut.clk)
    dut.rst.value = 0
    taken, out, x, cycle = [], [], 0, 0
    while len(out) < W and cycle < 20 * W:
        if x < W:  # pixel x with its right window x - d (outside the image: the largest cost)
            dut.in_valid.value = 1
            dut.dl.value = int(left[0, x])
            dut.dr.value = sum(int(right[0, x - d]) << (d * BITS) for d in range(D) if x >= d)
            dut.outside.value = sum(1 << d for d in range(D) if x < d)
        else:
            dut.in_valid.value = 0
        await ReadOnly()
        if x < W and int(dut.in_ready.value):
            taken.append(cycle)
            x += 1
        if int(dut.out_valid.value):
            word, width = int(dut.cost.value), len(dut.cost) // D
            out.append((cycle, [(word >> (d * width)) & ((1 << width) - 1) for d in range(D)]))
        await RisingEdge(dut.clk)
        cycle += 1

    assert len(out) == W, f"{len(out)} of {W} pixels came out"
    for x, (t_in, (t_out, costs)) in enumerate(zip(taken, out)):
        assert costs == want[x].tolist(), f"pixel {x}: {costs} != stereosim's {want[x].tolist()}"
        assert t_out - t_in == stage.latency, (
            f"pixel {x}: {t_out - t_in} cycles, stereosim's plan: {stage.latency} "
            f"({stage.formula})")
    assert set(np.diff(taken).tolist()) == {stage.ii}, "a pixel every II cycles"
