"""The suite's order -- the RTL twin's tests first, its stage tests first of all -- and the
fixtures more than one folder's tests use.

pytest-xdist's work-stealing scheduler hands each worker a contiguous share of the collected
tests. With the RTL tests at the front -- first the SVA stages', whose time is Verilator's C++
compile and whose references are plain numpy -- one worker starts on those builds while the
other compiles the numba kernels that most other tests need, instead of both compiling the same
kernels at once at the start of a run on a cold cache (the on-disk cache serves a kernel to the
second worker once the first has written it). The order inside each group is pytest's.

A conftest applies to its folder and below; the fixtures here serve the core's tests
(tests/core) and the cycle model's (tests/sim) alike."""

from __future__ import annotations

from pathlib import Path

import pytest

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


# ---- fixtures shared by folders (the core's tests and the cycle model's use them) ----


def write_lent_toml(path, layers, width=16, height=16, channels=1, fps="max"):
    """Write a lent network file (nna.lent_network) of ``layers`` (K, C_in, C_out, stride)
    tuples; returns its path."""
    fps_text = '"max"' if fps == "max" else repr(float(fps))
    text = [f"fps = {fps_text}", "[input]", f"width = {width}", f"height = {height}",
            f"channels = {channels}"]
    for k, c_in, c_out, s in layers:
        text += ["[[layer]]", f"kernel = {k}", f"channels_in = {c_in}",
                 f"channels_out = {c_out}", f"stride = {s}"]
    Path(path).write_text("\n".join(text) + "\n")
    return str(path)


@pytest.fixture(scope="session")
def lent_toml():
    """:func:`write_lent_toml`: write a lent network file."""
    return write_lent_toml


def _run_cycle(left, right, cfg, *, order_seed=None, sink_stall=None, trace=None,
               on_frame=None):
    """One frame (or a stream: see ``build_chip``) of ``cfg`` (or a plan) on the readable
    kernel: (the last frame's output words (H, W) int32, cycle report, the chip -- its blocks,
    FIFOs and simulator, for tests that look inside)."""
    from stereosim.sim.cycle.readable.chip import build_chip

    chip = build_chip(left, right, cfg, order_seed=order_seed, sink_stall=sink_stall,
                      trace=trace, on_frame=on_frame)
    _, report = chip.run()
    return chip.sink.words.copy(), report, chip


@pytest.fixture(scope="session")
def run_cycle():
    """The readable kernel's run with its chip: ``run_cycle(left, right, cfg, *, order_seed,
    sink_stall, trace, on_frame) -> (words, report, chip)``."""
    return _run_cycle
