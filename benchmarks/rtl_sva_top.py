"""The SVA as one block in RTL against the readable cycle engine on many random
configurations: tests/rtl/test_sva_top.py's two builds with ``--count N`` configurations in all
(half per build; default 200) drawn from ``--seed`` (default 48, the suite's), plus its rule
mutant; the co-simulation itself is stereosim.sim.rtl_check's (``stereosim rtl check`` runs one
configuration). Run: ``python benchmarks/rtl_sva_top.py [--count N] [--seed S]``; prints every
configuration and what it measured."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import pytest

if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--count", type=int, default=200, help="configurations in all")
    ap.add_argument("--seed", type=int, default=48, help="the draw's seed")
    args = ap.parse_args()
    os.environ["STEREOSIM_SVA_TOP_COUNT"] = str(max(1, args.count // 2))
    os.environ["STEREOSIM_SVA_TOP_SEED"] = str(args.seed)
    test = Path(__file__).resolve().parents[1] / "tests" / "rtl" / "test_sva_top.py"
    sys.exit(pytest.main(["-n", "2", "-q", "-s", "-p", "no:cacheprovider", str(test)]))
