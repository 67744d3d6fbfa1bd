"""What the cocotb modules share: a stage's ports on a twin top (several stages, or builds of
one stage, side by side in one Verilator build, each instance's ports prefixed: conftest.py's
``twin_top``). tests/rtl is the cocotb modules' test directory, so they import it by name."""

from __future__ import annotations

import json
import os

import cocotb
from cocotb.clock import Clock


class Pins:
    """The stage's ports on ``dut``: named ``prefix`` + port (clk and rst are shared)."""

    def __init__(self, dut, prefix: str):
        self._dut, self._prefix = dut, prefix

    def __getattr__(self, name: str):
        return getattr(self._dut, self._prefix + name)


async def each_run(dut, one_run) -> None:
    """The case (JSON in STEREOSIM_RTL_CASE) run by run on the one build: the clock started
    once, ``one_run(dut, run)`` with each run's keys over the case's."""
    case = json.loads(os.environ["STEREOSIM_RTL_CASE"])
    cocotb.start_soon(Clock(dut.clk, 10, unit="ns").start())
    for run in case["runs"]:
        await one_run(dut, {**case, **run})
