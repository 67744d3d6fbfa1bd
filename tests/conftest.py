"""The suite's order: the RTL twin's tests first, its stage tests first of all.

pytest-xdist's work-stealing scheduler hands each worker a contiguous share of the collected
tests. With the RTL tests at the front -- first the SVA stages', whose time is Verilator's C++
compile and whose references are plain numpy -- one worker starts on those builds while the
other compiles the numba kernels that most other tests need, instead of both compiling the same
kernels at once at the start of a run on a cold cache (the on-disk cache serves a kernel to the
second worker once the first has written it). The order inside each group is pytest's."""

from __future__ import annotations

from pathlib import Path

RTL = Path(__file__).resolve().parent / "rtl"
# build-bound and numba-free: the SVA stages' co-simulations
STAGES = ("test_sva_hamming.py", "test_sva_box_sgm.py", "test_sva_wta_lr_median.py")


def _rank(item) -> int:
    path = Path(str(item.path))
    if path.parent != RTL:
        return 2
    return 0 if path.name in STAGES else 1


def pytest_collection_modifyitems(session, config, items):
    items.sort(key=_rank)
