"""cocotb test module: the RTL matching-cost stage (sva/hamming/sva_hamming.sv) against stereosim.

Random pixels (left descriptor, the D right descriptors of its window, which lie outside the
right image, the weights) are offered with random gaps; every output must equal the cost of
sva/hamming/cost.py's definition, leave in the cycle the chip plan's stage says (taken + latency),
and the stage must take a pixel every II cycles when offered one -- the plan's II and latency
(sva.hamming.timing.hamming_stage), read from the plan, not from the RTL's parameters.
"""

import dataclasses

import cocotb
import numpy as np
from cocotb.triggers import ReadOnly, RisingEdge
from twin import Pins, each_run

from stereosim.core.config import load_config
from stereosim.sva.hamming.cost import cost_parts, hamming_cost_ref
from stereosim.sva.hamming.timing import hamming_stage


def expected(dl: int, dr: list[int], outside: list[bool], parts, weights) -> list[int]:
    """The D costs of one pixel by sva/hamming/cost.py's reference (a 1 x D view of the volume)."""
    spec = cost_parts(parts, weights[:len(parts)])
    d = len(dr)
    dtype = np.uint64
    left = np.array([[0] * (d - 1) + [dl]], dtype)  # pixel x = D - 1, right x - d = dr[d]
    right = np.array([[dr[d - 1 - i] for i in range(d)]], dtype)
    cost = hamming_cost_ref(left, right, d, spec)[0, d - 1]
    top = spec.top
    return [top if outside[i] else int(cost[i]) for i in range(d)]


@cocotb.test()
async def costs_and_cycles(dut):
    """Every run of the case (weight pairs, offer rates) on the one build, reset between."""
    await each_run(dut, one_run)


async def one_run(top, p: dict) -> None:
    dut = Pins(top, p.get("prefix", ""))
    cfg = load_config(overrides=p["overrides"])
    parts = tuple(p["parts"])
    stage = hamming_stage(cfg, 64, parts)
    if p.get("rule_mutant"):  # the rule one cycle late: the RTL must catch it by name
        stage = dataclasses.replace(stage, latency=stage.latency + 1)
    d, width = cfg.sva.disparities, sum(parts)
    rng = np.random.default_rng(p["seed"])
    top.rst.value = 1
    dut.en.value = 1  # the pipeline always advances: the stage alone, no stall
    dut.in_valid.value = 0
    await RisingEdge(top.clk)
    top.rst.value = 0
    pixels, taken, outs = [], [], []
    cycle = 0
    n = p["pixels"]
    pending = None
    weights = (1, 0) if len(parts) == 1 else tuple(p["weights"])
    while len(outs) < n and cycle < 50 * n * (stage.ii + stage.latency):
        if pending is None and len(pixels) < n and rng.random() < p["offer"]:
            dl = int(rng.integers(0, 1 << width, dtype=np.uint64))
            dr = [int(x) for x in rng.integers(0, 1 << width, d, dtype=np.uint64)]
            outside = [bool(x) for x in rng.random(d) < 0.2]
            pending = (dl, dr, outside)
        if pending is not None:
            dl, dr, outside = pending
            dut.in_valid.value = 1
            dut.dl.value = dl
            dut.dr.value = sum(v << (i * width) for i, v in enumerate(dr))
            dut.outside.value = sum(int(o) << i for i, o in enumerate(outside))
            dut.w0.value, dut.w1.value = weights
        else:
            dut.in_valid.value = 0
        await ReadOnly()
        if pending is not None and int(dut.in_ready.value):
            pixels.append(pending)
            taken.append(cycle)
            pending = None
        if int(dut.out_valid.value):
            word = int(dut.cost.value)
            cw = p["cost_w"]
            outs.append((cycle, [(word >> (i * cw)) & ((1 << cw) - 1) for i in range(d)]))
        await RisingEdge(top.clk)
        cycle += 1
    assert len(outs) == n, f"{len(outs)} of {n} pixels left the stage"
    for i, ((dl, dr, outside), t, (t_out, got)) in enumerate(zip(pixels, taken, outs)):
        want = expected(dl, dr, outside, parts, weights)
        assert got == want, f"pixel {i}: costs {got} != {want}"
        assert t_out - t == stage.latency, (
            f"pixel {i}: taken in cycle {t}, out in {t_out}: {t_out - t} cycles, the plan's "
            f"hamming latency is {stage.latency} ({stage.formula})")
    gaps = np.diff(taken)
    assert gaps.min() >= stage.ii, f"two pixels {gaps.min()} cycles apart, the II is {stage.ii}"
    if p["offer"] == 1.0:  # offered every cycle: taken exactly every II
        assert set(gaps.tolist()) == {stage.ii}, f"gaps {sorted(set(gaps.tolist()))}"
