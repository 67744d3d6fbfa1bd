"""cocotb test module: the RTL NNA submodule (nna/submodule/nna_submodule.sv) against stereosim.

The case (tests/rtl/test_nna_rtl.py) carries, per run, the frame, the integer network (weights
in the RTL's tap order, biases, multiply-shift, input offset) and what the readable cycle engine
did with the same frame and configuration: the cycle each pixel became visible in the NNA's
input FIFO, the cycle each was popped and the cycle each descriptor was pushed, and the
descriptors of the functional model (nna/descriptor.py compute_descriptor). The bench offers
pixel k from the cycle the model's FIFO showed it (relative to the first), keeps out_ready
high, and checks every descriptor bit for bit and every pop and push in the model's cycle.
"""

import json
import os

import cocotb
import numpy as np
from cocotb.clock import Clock
from cocotb.triggers import ReadOnly, RisingEdge


def packed(values, dtype) -> int:
    """``values`` as one integer, element i at bits [i b, (i + 1) b) (b the dtype's bits)."""
    return int.from_bytes(np.asarray(values).astype(dtype).astype(dtype.newbyteorder("<"))
                          .tobytes(), "little")


@cocotb.test()
async def descriptors_and_cycles(dut):
    """Every run of the case (networks, frames) on the one build, reset between."""
    case = json.loads(os.environ["STEREOSIM_RTL_CASE"])
    cocotb.start_soon(Clock(dut.clk, 10, unit="ns").start())
    for run in case["runs"]:
        await one_run(dut, run)


async def one_run(dut, p: dict) -> None:
    layers = p["layers"]
    dut.offset.value = p["offset"]
    dut.w0.value = packed(layers[0]["weights"], np.dtype(np.int8))
    dut.b0.value = packed(layers[0]["bias"], np.dtype(np.int32))
    if len(layers) > 1:
        dut.m0.value = packed(layers[0]["mult"], np.dtype(np.uint16))
        dut.s0.value = packed(layers[0]["shift"], np.dtype(np.uint16))
        dut.w1.value = packed(layers[1]["weights"], np.dtype(np.int8))
        dut.b1.value = packed(layers[1]["bias"], np.dtype(np.int32))
    else:
        dut.m0.value = 0
        dut.s0.value = 0
        dut.w1.value = 0
        dut.b1.value = 0
    dut.rst.value = 1
    dut.in_valid.value = 0
    dut.out_ready.value = 1
    await RisingEdge(dut.clk)
    await RisingEdge(dut.clk)
    dut.rst.value = 0
    pixels, want = p["pixels"], p["words"]
    t0 = p["visible"][0]  # model cycle t0 + c is the RTL's cycle c
    visible = [v - t0 for v in p["visible"]]
    pops, pushes = [], []
    k, cycle = 0, 0
    limit = 4 * (p["pushes"][-1] - t0) + 100
    while len(pushes) < len(want) and cycle < limit:
        offer = k < len(pixels) and visible[k] <= cycle
        dut.in_valid.value = int(offer)
        if offer:
            dut.pixel.value = pixels[k]
        await ReadOnly()
        if offer and int(dut.in_ready.value):
            pops.append(cycle)
            k += 1
        if int(dut.out_valid.value):
            pushes.append((cycle, int(dut.descriptor.value)))
        await RisingEdge(dut.clk)
        cycle += 1
    name, width = p["name"], p["width"]
    assert len(pushes) == len(want), f"{name}: {len(pushes)} of {len(want)} descriptors left"
    # every word and every handshake before failing: each wrong rule names itself
    wrong = []
    for j, ((_, got), word) in enumerate(zip(pushes, want)):
        y, x = divmod(j, width)
        if got != word and len(wrong) < 3:
            wrong.append(f"descriptor ({x}, {y}) is {got:#x}, the functional model's "
                         f"(compute_descriptor) is {word:#x}")
    model_pops = [c - t0 for c in p["pops"]]
    if len(pops) != len(model_pops):
        wrong.append(f"{len(pops)} pops, the model's {len(model_pops)}")
    wrong += [f"pixel {i} popped in cycle {got}, the cycle model pops it in {exp} (the line "
              "buffer's nna_rows_started_before_input)"
              for i, (got, exp) in enumerate(zip(pops, model_pops)) if got != exp][:3]
    model_pushes = [c - t0 for c in p["pushes"]]
    ii = p["cycles"]
    for j, ((got, _), exp) in enumerate(zip(pushes, model_pushes)):
        y, x = divmod(j, width)
        what = "first" if j == 0 else "last" if j == len(want) - 1 else f"number {j}"
        if got != exp and (len(wrong) < 6 or what == "last"):
            wrong.append(f"the {what} descriptor ({x}, {y}) leaves in cycle {got}, the cycle "
                         f"model's MAC array (II {ii}) pushes it in {exp}")
    assert not wrong, f"{name}: " + "; ".join(wrong)
    dut._log.info("%s: %d descriptors and %d pops equal, first out %d, last %d", name,
                  len(pushes), len(pops), pushes[0][0], pushes[-1][0])
