"""cocotb test module of ``stereosim rtl check`` (:mod:`stereosim.sim.rtl_check`): the SVA as one
block (sva/pipeline/sva_top.sv, under its boundary wrapper ``top.sva``) driven as the readable cycle
engine's SVA was on the same frames.

``STEREOSIM_RTL_CASES`` names a JSON file: ``cases``, run one after the other with the RTL reset
before each, and ``out``, the file for the results. A case (:func:`stereosim.sim.rtl_check.
rtl_case`) holds the run-time registers, per pair in raster order the SVA cycle from which the
model's input FIFOs made it visible (both views), its descriptors and left pixel, and per cycle
whether the model's output FIFO had room (its ``can_push`` as the SVA saw it: the scripted
sink's back-pressure). The bench offers the next pair from its cycle on, sets ``out_ready`` to
the model's room, and records every pop (cycle) and push (cycle, word) of the RTL, with the
first cycle ``overrun`` was high (None if never); cycles count from the end of each case's
reset, whose simulation time (``t0_fs``) is recorded. The clock's period is
:data:`stereosim.sim.rtl_check.RTL_PERIOD_NS`. cocotb imports it by its dotted name."""

import json
import os

import cocotb
from cocotb.clock import Clock
from cocotb.triggers import ReadOnly, RisingEdge
from cocotb.utils import get_sim_time


async def frame(dut, p: dict) -> dict:
    """Reset the RTL with the case's registers, run its frame, record the boundary."""
    dut.rst.value = 1
    dut.in_valid.value = 0
    dut.out_ready.value = 0
    for name, value in p["regs"].items():
        getattr(dut, name).value = value
    await RisingEdge(dut.clk)
    await RisingEdge(dut.clk)
    dut.rst.value = 0
    t0_fs = int(get_sim_time("fs"))  # cycle 0's inputs go in now
    vis, dl, dr, pix, ready = p["visible"], p["dl"], p["dr"], p["pix"], p["ready"]
    n, words = len(vis), p["words"]
    pops, pushes, got = [], [], []
    nxt = 0
    cycle = 0
    overrun_at = None
    while len(got) < words and cycle < p["limit"]:
        offer = nxt < n and vis[nxt] <= cycle
        dut.in_valid.value = int(offer)
        if offer:
            dut.dl.value, dut.dr.value, dut.pix.value = dl[nxt], dr[nxt], pix[nxt]
        dut.out_ready.value = ready[cycle] if cycle < len(ready) else 1
        await ReadOnly()
        if offer and int(dut.in_ready.value):
            pops.append(cycle)
            nxt += 1
        if int(dut.out_valid.value) and int(dut.out_ready.value):
            pushes.append(cycle)
            got.append(int(dut.word.value))
        if overrun_at is None and int(dut.overrun.value):
            overrun_at = cycle
        await RisingEdge(dut.clk)
        cycle += 1
    return {"pops": pops, "pushes": pushes, "words": got, "overrun": overrun_at, "t0_fs": t0_fs}


@cocotb.test()
async def boundary(dut):
    """Run every case's frame; record the RTL's boundary handshakes."""
    with open(os.environ["STEREOSIM_RTL_CASES"]) as f:
        p = json.load(f)
    cocotb.start_soon(Clock(dut.clk, p["period_ns"], unit="ns").start())
    results = [await frame(dut, case) for case in p["cases"]]
    with open(p["out"], "w") as f:
        json.dump(results, f)
