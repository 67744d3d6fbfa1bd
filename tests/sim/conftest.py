"""Shared fixtures of the cycle-model tests."""

from __future__ import annotations

import numpy as np
import pytest

from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.readable.chip import build_chip, run_readable


@pytest.fixture
def engines_agree():
    """A function running a plan on the readable kernel and the compiled engine and asserting
    they agree: statistics, report, frame instants, the frames completed and every frame's
    words. Returns the readable run and its [(frame, words)]."""

    def check(plan, left, right, **kw):
        got = {"slow": [], "fast": []}
        slow = run_readable(plan, left, right,
                            on_frame=lambda f, w: got["slow"].append((f, w.copy())), **kw)
        fast = run_compiled(plan, left, right,
                            on_frame=lambda f, w: got["fast"].append((f, w.copy())), **kw)
        assert slow.stats == fast.stats and slow.report == fast.report
        np.testing.assert_array_equal(slow.frame_times, fast.frame_times)
        assert [f for f, _ in got["slow"]] == [f for f, _ in got["fast"]]
        for (_, a), (_, b) in zip(got["slow"], got["fast"]):
            np.testing.assert_array_equal(a, b)
        return slow, got["slow"]

    return check


def _run_cycle(left, right, cfg, *, order_seed=None, sink_stall=None, trace=None,
               on_frame=None):
    """One frame (or a stream: see ``build_chip``) of ``cfg`` (or a plan) on the readable
    kernel: (the last frame's output words (H, W) int32, cycle report, the chip -- its blocks,
    FIFOs and simulator, for tests that look inside)."""
    chip = build_chip(left, right, cfg, order_seed=order_seed, sink_stall=sink_stall,
                      trace=trace, on_frame=on_frame)
    _, report = chip.run()
    return chip.sink.words.copy(), report, chip


@pytest.fixture(scope="session")
def run_cycle():
    """The readable kernel's run with its chip: ``run_cycle(left, right, cfg, *, order_seed,
    sink_stall, trace, on_frame) -> (words, report, chip)``."""
    return _run_cycle
