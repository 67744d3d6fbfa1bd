"""The compiled engine (sim/cycle/engine) against the readable kernel (sim/cycle/readable/chip.py):
same words, same cycle report, same kernel statistics, same errors with the same state of every FIFO
and block."""

import numpy as np
import pytest

from stereosim.core.config import load_config
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.contract import BudgetExceeded, CameraOverflow, DeadlockError
from stereosim.sim.cycle.plan import build_plan


def run_cycle_fast(left, right, cfg, sink_stall=None):
    """The compiled engine: (words, report, statistics)."""
    frame = run_compiled(build_plan(cfg, left.shape), left, right, sink_stall=sink_stall)
    return frame.words, frame.report, frame.stats


SAME_CLOCKS = {"clocks.nna_mhz": 400, "clocks.sva_mhz": 400}
CENSUS = {"sva.disparities": 16, "nna.descriptor": "census"}  # unless a case sets it


def _pair(h, w, seed=0, shift=3):
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (h, w + shift), dtype=np.uint8)
    return base[:, :w].copy(), base[:, shift:].copy()


def _stall_fn(stall):
    if stall is None:
        return None
    period, phase = stall
    return lambda c: c % period != phase


def _assert_same(run_cycle, h, w, over, seed=0, stall=None):
    """The compiled engine equals the readable kernel."""
    left, right = _pair(h, w, seed=seed)
    cfg = load_config(overrides={**CENSUS, **over})
    words_r, report_r, chip = run_cycle(left, right, cfg, sink_stall=_stall_fn(stall))
    words_f, report_f, stats_f = run_cycle_fast(left, right, cfg, sink_stall=stall)
    np.testing.assert_array_equal(words_f, words_r)
    assert stats_f == chip.sim.stats()
    assert report_f == report_r


@pytest.mark.parametrize(
    "h, w, over",
    [
        (9, 35, SAME_CLOCKS),
        (13, 45, {**SAME_CLOCKS, "nna.descriptor": "cnn"}),
        (13, 45, {"sva.paths": 1, "sva.lr_check": False, "sva.median": 0}),
        (13, 45, {"sva.paths": 2, "sva.box_size": 3, "sva.median": 5}),
        (9, 41, {"sva.paths": 3, "sva.disparities": 32, "sva.subpixel": "parabola"}),
        (13, 45, {"sva.paths": 4, "fifo.source_to_nna_depth": 1, "fifo.nna_to_sva_depth": 1,
                  "fifo.sva_to_sink_depth": 1}),
        (13, 45, {"nna.descriptor": "cnn", "fifo.nna_to_sva_depth": 2,
                  "clocks.sva_mhz": 930}),
        (13, 45, {"nna.line_buffer_rows": 9, "nna.descriptor": "cnn", "sva.uniqueness": 5}),
        (13, 45, {"nna.line_buffer_rows": 3, "sva.median": 3, "fifo.nna_to_sva_depth": 2}),
        (13, 45, {"source.memory_gbps": 0.1, "clocks.nna_mhz": 300, "clocks.sva_mhz": 700}),
        (11, 37, {"source.memory_gbps": 100.0, "fifo.source_to_nna_depth": 64,
                  "fifo.nna_to_sva_depth": 64, "fifo.sva_to_sink_depth": 64,
                  "sva.lanes": 4, "clocks.sva_mhz": 150}),
        (9, 35, {"fifo.latency_cycles": 2, "fifo.sync_cycles": 3, "sva.lr_check": False,
                 "sva.median": 0, "sva.compare_levels": 32}),
        (9, 35, {**SAME_CLOCKS, "fifo.latency_cycles": 3, "fifo.sync_cycles": 1,
                 "fifo.nna_to_sva_depth": 2}),
        (11, 39, {"nna.census.window": [9, 7], "nna.census.kind": "plain",
                  "sva.p2_adaptive": True}),  # 62-bit descriptors
        (10, 33, {"nna.census.window": [5, 5], "nna.census.stride": 2,
                  "nna.line_buffer_rows": 5, "sva.box_size": 1}),
    ],
)
def test_fast_engine_equals_the_readable_engine(h, w, over, run_cycle):
    _assert_same(run_cycle, h, w, over, seed=h + w)


@pytest.mark.parametrize(
    "over",
    [
        {"source.kind": "camera", "clocks.camera_mhz": 20, "source.camera_hblank": 7},
        {"source.kind": "camera", "clocks.camera_mhz": 50, "source.camera_hblank": 3,
         "clocks.nna_mhz": 333, "clocks.sva_mhz": 400},
        {"source.kind": "camera", "clocks.camera_mhz": 30, "source.camera_hblank": 11,
         "nna.descriptor": "cnn", "clocks.nna_mhz": 460, "clocks.sva_mhz": 465},
    ],
)
def test_fast_engine_equals_the_readable_engine_with_a_camera(over, run_cycle):
    _assert_same(run_cycle, 13, 45, over, seed=7)


@pytest.mark.parametrize("stall, depth", [((3, 0), 1), ((4, 2), 2), ((2, 1), 16)])
def test_a_periodically_stalling_sink_gives_the_same_backpressure(stall, depth, run_cycle):
    _assert_same(run_cycle, 9, 35, {**SAME_CLOCKS, "fifo.sva_to_sink_depth": depth}, seed=5,
                 stall=stall)


def test_deadlock_is_reported_with_the_same_message(run_cycle):
    left, right = _pair(7, 29, seed=8)
    cfg = load_config(overrides={**CENSUS, "sim.watchdog_cycles": 500})
    never = (1 << 40, (1 << 40) - 1)  # the sink would pop first in cycle 2^40 - 1
    with pytest.raises(DeadlockError) as fast:
        run_cycle_fast(left, right, cfg, sink_stall=never)
    with pytest.raises(DeadlockError) as slow:
        run_cycle(left, right, cfg, sink_stall=_stall_fn(never))
    assert str(fast.value) == str(slow.value)
    assert "\n" not in str(fast.value)
    assert fast.value.blocks == slow.value.blocks
    assert fast.value.fifos == slow.value.fifos
    assert fast.value.cycles == slow.value.cycles
    assert fast.value.time_fs == slow.value.time_fs


def test_cycle_budget_is_enforced_with_the_same_message(run_cycle):
    """Without a watchdog a sink that never pops runs into the cycle budget of
    sim.cycle.readable.chip (equal clocks: one step per cycle keeps the readable run short)."""
    left, right = _pair(3, 20, seed=10)
    cfg = load_config(overrides={**SAME_CLOCKS, **CENSUS, "sim.watchdog_cycles": 1 << 40})
    never = (1 << 40, (1 << 40) - 1)
    with pytest.raises(BudgetExceeded) as fast:
        run_cycle_fast(left, right, cfg, sink_stall=never)
    with pytest.raises(BudgetExceeded) as slow:
        run_cycle(left, right, cfg, sink_stall=_stall_fn(never))
    assert str(fast.value) == str(slow.value)
    assert fast.value.blocks == slow.value.blocks


def test_camera_overflow_has_the_same_message(run_cycle):
    left, right = _pair(25, 29, seed=9)
    cfg = load_config(overrides={"sva.disparities": 16, "source.kind": "camera",
                                 "nna.descriptor": "cnn", "clocks.camera_mhz": 400,
                                 "source.camera_hblank": 0})
    with pytest.raises(CameraOverflow) as fast:
        run_cycle_fast(left, right, cfg)
    with pytest.raises(CameraOverflow) as slow:
        run_cycle(left, right, cfg)
    assert str(fast.value) == str(slow.value)


@pytest.mark.parametrize(
    "over, stall",
    [
        ({"nna.stereo_submodules": 4, "sim.watchdog_cycles": 500}, (1 << 40, (1 << 40) - 1)),
        ({"nna.stereo_submodules": 6, "nna.split": "rows", "fifo.nna_to_merge_depth": 1,
          "sim.watchdog_cycles": 300}, (1 << 40, (1 << 40) - 1)),
        ({"nna.stereo_submodules": 4, "nna.split": "rows", "source.kind": "camera",
          "nna.descriptor": "cnn", "clocks.camera_mhz": 400, "source.camera_hblank": 0}, None),
    ],
)
def test_split_frames_stop_with_the_same_message(over, stall, run_cycle):
    """Split frames stop as whole ones do: the same exception, message and state."""
    left, right = _pair(25, 40, seed=18)
    cfg = load_config(overrides={**CENSUS, **over})
    with pytest.raises((DeadlockError, CameraOverflow)) as fast:
        run_cycle_fast(left, right, cfg, sink_stall=stall)
    with pytest.raises((DeadlockError, CameraOverflow)) as slow:
        run_cycle(left, right, cfg, sink_stall=_stall_fn(stall))
    assert type(fast.value) is type(slow.value)
    assert str(fast.value) == str(slow.value)
    assert getattr(fast.value, "blocks", None) == getattr(slow.value, "blocks", None)
