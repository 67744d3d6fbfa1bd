"""The SVA as one block in RTL against the readable cycle engine (tests/rtl/sva_top_check.py):
one Verilator build of the whole SVA and four frames, too long for the suite (~40 s on two
cores). Run: ``python benchmarks/rtl_sva_top.py``; prints each case's measured handshake lags."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

if __name__ == "__main__":
    test = Path(__file__).resolve().parents[1] / "tests" / "rtl" / "sva_top_check.py"
    sys.exit(pytest.main(["-n", "0", "-q", "-s", "-p", "no:cacheprovider", str(test)]))
