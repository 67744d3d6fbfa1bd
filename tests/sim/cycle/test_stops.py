"""Stops you can inspect: a run stopped by the cycle budget, the watchdog, a
camera's overflow or a frame buffer it cannot get gives, on both cycle engines, the same
exception -- message, instant, cycles, every FIFO's and block's state, the rows reached -- the
same stop report and the same trace up to the stop; ``stereosim.run`` carries the stopped run's
report and trace on the exception."""

from __future__ import annotations

import numpy as np
import pytest

from stereosim.core.config import load_config
from stereosim.sim.api import run
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.contract import (
    BudgetExceeded,
    CameraOverflow,
    DeadlockError,
    FrameBufferFull,
    RunStopped,
    stop_message,
    stop_report,
)
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.readable.chip import run_readable
from stereosim.sim.tracing import TraceRequest, run_traced
from stereosim.traces.log import TraceLog
from stereosim.traces.vcd import vcd_bytes

CENSUS = {"sva.disparities": 16, "nna.descriptor": "census"}
NEVER = (1 << 40, (1 << 40) - 1)  # a sink that would pop first in cycle 2^40 - 1
EVERYTHING = (0, 1 << 62)  # a trace window holding the whole run


def _pair(h, w, seed=0, shift=3, frames=None):
    rng = np.random.default_rng(seed)
    size = (h, w + shift) if frames is None else (frames, h, w + shift)
    base = rng.integers(0, 256, size, dtype=np.uint8)
    return base[..., :w].copy(), base[..., shift:].copy()


def _stop(runner, plan, left, right, **kw) -> RunStopped:
    with pytest.raises(RunStopped) as info:
        runner(plan, left, right, **kw)
    return info.value


def _same_stop(plan, left, right, sink_stall=None, window=EVERYTHING) -> RunStopped:
    """Both engines stop the same way; returns the readable kernel's stop."""
    slow = _stop(run_readable, plan, left, right, window=window, sink_stall=sink_stall)
    fast = _stop(run_compiled, plan, left, right, window=window, sink_stall=sink_stall)
    assert type(fast) is type(slow)
    assert str(fast) == str(slow) and "\n" not in str(fast)
    assert (fast.time_fs, fast.cycles) == (slow.time_fs, slow.cycles)
    assert fast.fifos == slow.fifos and fast.blocks == slow.blocks
    np.testing.assert_array_equal(fast.row_times, slow.row_times)
    assert stop_report(fast, plan) == stop_report(slow, plan)
    assert fast.outputs_in_window == slow.outputs_in_window
    assert vcd_bytes(fast.trace, date="") == vcd_bytes(slow.trace, date="")
    # the trace ends one femtosecond after the last step the run executed
    assert fast.trace.end_fs == slow.trace.end_fs == slow.time_fs + 1
    return slow


@pytest.mark.parametrize("clocks", [(400, 400), (460, 465)])
def test_a_cycle_limit_stops_both_engines_alike_with_the_trace_up_to_it(clocks):
    left, right = _pair(12, 40)
    cfg = load_config(overrides={**CENSUS, "clocks.nna_mhz": clocks[0],
                                 "clocks.sva_mhz": clocks[1], "sim.max_cycles": 600})
    plan = build_plan(cfg, left.shape)
    stop = _same_stop(plan, left, right)
    assert isinstance(stop, BudgetExceeded)
    report = stop_report(stop, plan)
    assert report["reason"] == "max_cycles" and max(report["cycles"].values()) == 600
    assert report["time_fs"] == stop.time_fs and report["message"] == str(stop)
    assert stop.outputs_in_window > 0  # words left the SVA before the stop
    # every FIFO and block, with who is at the other end of the FIFO a block waits on
    assert set(report["fifos"]) == {f.name for f in plan.fifos}
    assert set(report["blocks"]) == {b.name for b in plan.blocks}
    for name, st in report["blocks"].items():
        fifo = st["waiting_on"]
        if fifo in report["fifos"]:
            end = "consumer" if st["waiting_for"] == "space" else "producer"
            assert st["waiting_on_block"] == report["fifos"][fifo][end] != name


def test_a_window_that_ends_before_the_stop_is_traced_whole():
    left, right = _pair(12, 40)
    plan = build_plan(load_config(overrides={**CENSUS, "sim.max_cycles": 600}), left.shape)
    end = 400 * plan.domains["sva"].period_fs
    slow = _stop(run_readable, plan, left, right, window=(0, end))
    fast = _stop(run_compiled, plan, left, right, window=(0, end))
    assert slow.trace.end_fs == fast.trace.end_fs == end
    assert vcd_bytes(fast.trace, date="") == vcd_bytes(slow.trace, date="")
    # a window that starts after the stop has no trace
    late = (slow.time_fs + 1, slow.time_fs + 10**9)
    assert _stop(run_compiled, plan, left, right, window=late).trace is None
    assert _stop(run_readable, plan, left, right, window=late).trace is None


@pytest.mark.parametrize("over", [{}, {"nna.stereo_submodules": 4}])
def test_a_deadlock_stops_both_engines_alike(over):
    left, right = _pair(7, 29, seed=8)
    plan = build_plan(load_config(overrides={**CENSUS, "sim.watchdog_cycles": 500, **over}),
                      left.shape)
    stop = _same_stop(plan, left, right, sink_stall=NEVER)
    assert isinstance(stop, DeadlockError)
    report = stop_report(stop, plan)
    assert report["reason"] == "deadlock"
    assert report["fifos"]["sva_to_sink"]["state"] == "full"
    assert report["blocks"]["sva"] == {"status": "blocked", "waiting_on": "sva_to_sink",
                                       "waiting_for": "space", "waiting_on_block": "sink"}


def test_a_camera_overflow_stops_both_engines_alike():
    left, right = _pair(25, 29, seed=9)
    plan = build_plan(load_config(overrides={"sva.disparities": 16, "source.kind": "camera",
                                             "nna.descriptor": "cnn", "clocks.camera_mhz": 400,
                                             "source.camera_hblank": 0}), left.shape)
    stop = _same_stop(plan, left, right)
    assert type(stop) is CameraOverflow
    report = stop_report(stop, plan)
    assert report["reason"] == "camera_overflow"
    assert report["fifos"]["src_left_to_nna"]["state"] == "full"
    period = plan.domains["camera"].period_fs
    assert stop.time_fs % period == 0 and f"cycle {stop.time_fs // period}" in str(stop)


def test_a_frame_without_a_free_buffer_stops_both_engines_alike():
    left, right = _pair(16, 40, frames=3)
    chip = {"clocks.nna_mhz": 400, "clocks.sva_mhz": 400, "sva.disparities": 16,
            "nna.descriptor": "cnn", "source.kind": "camera", "clocks.camera_mhz": 400,
            "source.camera_vblank": 4, "source.camera_hblank": 160, "source.frame_buffers": 1,
            "source.on_overflow": "error"}
    plan = build_plan(load_config(overrides=chip), (16, 40), 3)
    stop = _same_stop(plan, left, right)
    assert isinstance(stop, FrameBufferFull)
    assert stop_report(stop, plan)["reason"] == "frame_buffer_overflow"


def test_the_line_names_the_full_fifos_and_waits_outside_fifos():
    fifos = {f"f{k}": {"occupancy": 2, "depth": 2} for k in range(8)}
    fifos["g"] = {"occupancy": 1, "depth": 2}
    blocks = {"a": {"status": "starved", "waiting_on": ("dram", "empty")},
              "b": {"status": "blocked", "waiting_on": ("f0", "full")},
              "c": {"status": None, "waiting_on": None}}
    line = stop_message("deadlock", 1_500_000, {"clk": 3}, fifos, blocks, "tail")
    assert line == ("deadlock at 0.001500 us (cycles run: clk 3): full FIFOs: f0 2/2, f1 2/2, "
                    "f2 2/2, f3 2/2, f4 2/2, f5 2/2 and 2 more; a starved on dram; tail")
    none = {"g": {"occupancy": 0, "depth": 2}}
    assert "no FIFO is full" in stop_message("deadlock", 0, {"clk": 1}, none, {}, "tail")


def test_the_api_raises_the_stop_with_its_report_and_trace(tmp_path):
    left, right = _pair(12, 40)
    over = {**CENSUS, "sim.max_cycles": 600}
    with pytest.raises(BudgetExceeded) as info:
        run(left, right, overrides=over, trace=TraceRequest(vcd=str(tmp_path / "t.vcd"),
                                                            patterns=("top.sva.*",)))
    stop = info.value
    report = stop.report
    assert report["stopped"]["reason"] == "max_cycles" and report["engine"] == "fast"
    assert report["stopped"] == stop_report(stop, build_plan(load_config(overrides=over),
                                                             left.shape))
    for whole_frame in ("output", "metrics", "throughput", "cycles", "stream", "energy"):
        assert whole_frame not in report
    assert report["config"]["sim"]["max_cycles"] == 600 and report["image"]["width"] == 40
    assert isinstance(stop.trace, TraceLog) and stop.trace.end_fs == stop.time_fs + 1
    assert stop.trace.signals
    assert all(s.path.startswith("top.sva.") for s in stop.trace.signals)
    assert report["trace"]["value_changes"] == stop.trace.n_changes
    with pytest.raises(RunStopped) as info:  # untraced: the report, no trace
        run(left, right, overrides={**over, "sim.engine": "readable"})
    assert info.value.report["engine"] == "readable" and info.value.trace is None
    assert "trace" not in info.value.report
    assert info.value.report["stopped"] == report["stopped"]


@pytest.mark.parametrize("engine", ["fast", "readable"])
def test_a_rows_window_runs_from_its_first_row_to_the_stop(engine):
    """``--trace-window rows:A:B`` finds its instants with an untraced pass; when that pass
    stops before row B is out, the window runs to the stop (a row never reached: the end)."""
    left, right = _pair(12, 40)
    cfg = load_config(overrides={**CENSUS, "sim.max_cycles": 600, "sim.engine": engine})
    plan = build_plan(cfg, left.shape)
    with pytest.raises(BudgetExceeded) as info:
        run_traced(plan, left, right, TraceRequest(window="rows:2:12"))
    stop = info.value
    assert stop.row_times[1, 12] == -1 and stop.row_times[0, 2] > 0  # row 2 in, 11 not out
    assert (stop.trace.start_fs, stop.trace.end_fs) == (stop.row_times[0, 2], stop.time_fs + 1)
