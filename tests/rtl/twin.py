"""What the cocotb modules share: a stage's ports on a twin top (several stages, or builds of
one stage, side by side in one Verilator build, each instance's ports prefixed: conftest.py's
``twin_top``). tests/rtl is the cocotb modules' test directory, so they import it by name."""

from __future__ import annotations


class Pins:
    """The stage's ports on ``dut``: named ``prefix`` + port (clk and rst are shared)."""

    def __init__(self, dut, prefix: str):
        self._dut, self._prefix = dut, prefix

    def __getattr__(self, name: str):
        return getattr(self._dut, self._prefix + name)
