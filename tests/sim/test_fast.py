"""The compiled engine (sim/fast.py, with its two methods: steps and the schedule engine of
sim/schedule.py) against the readable one (sim/chip.py): same words, same cycle report, same
kernel statistics, same errors; and its descriptor rows against the NNA kernels on whole
images."""

import numpy as np
import pytest

from nna.census import census
from nna.conv import cnn_descriptor
from nna.descriptor import layer
from sim.config import load_config
from sim.cycle.blocks.sources import CameraOverflow
from sim.cycle.chip import run_cycle
from sim.cycle.clock import BudgetExceeded, DeadlockError
from sim.cycle.fast import (
    census_tables,
    cnn_tables,
    descriptor_row_census,
    descriptor_row_cnn,
    run_cycle_fast,
)
from sim.cycle.schedule import run_schedule

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


def _assert_same(h, w, over, seed=0, stall=None):
    """Both compiled methods -- the steps of this module's loop and the schedule engine that
    ``method="auto"`` uses for a completing untraced run -- equal the readable kernel."""
    left, right = _pair(h, w, seed=seed)
    cfg = load_config(overrides={**CENSUS, **over})
    words_r, report_r, chip = run_cycle(left, right, cfg, sink_stall=_stall_fn(stall))
    assert run_schedule(left, right, cfg, sink_stall=stall) is not None
    for method in ("steps", "auto"):
        words_f, report_f, stats_f = run_cycle_fast(left, right, cfg, sink_stall=stall,
                                                    method=method)
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
                  "sva.cycles_per_pixel": 1}),
        (13, 45, {"nna.line_buffer_rows": 9, "nna.descriptor": "cnn", "sva.uniqueness": 5}),
        (13, 45, {"nna.line_buffer_rows": 3, "sva.median": 3, "fifo.nna_to_sva_depth": 2}),
        (13, 45, {"source.memory_gbps": 0.1, "clocks.nna_mhz": 300, "clocks.sva_mhz": 700}),
        (11, 37, {"source.memory_gbps": 100.0, "fifo.source_to_nna_depth": 64,
                  "fifo.nna_to_sva_depth": 64, "fifo.sva_to_sink_depth": 64,
                  "sva.cycles_per_pixel": 1, "clocks.sva_mhz": 150}),
        (9, 35, {"fifo.latency_cycles": 2, "fifo.sync_cycles": 3, "sva.pipeline_latency": 1}),
        (9, 35, {**SAME_CLOCKS, "fifo.latency_cycles": 3, "fifo.sync_cycles": 1,
                 "fifo.nna_to_sva_depth": 2}),
        (11, 39, {"nna.census.window": [9, 7], "nna.census.kind": "plain",
                  "sva.p2_adaptive": True}),  # 62-bit descriptors
        (10, 33, {"nna.census.window": [5, 5], "nna.census.stride": 2,
                  "nna.line_buffer_rows": 5, "sva.box_size": 1}),
    ],
)
def test_fast_engine_equals_the_readable_engine(h, w, over):
    _assert_same(h, w, over, seed=h + w)


@pytest.mark.parametrize(
    "over",
    [
        {"source.kind": "camera", "clocks.camera_mhz": 20, "source.camera_hblank": 7},
        {"source.kind": "camera", "clocks.camera_mhz": 50, "source.camera_hblank": 3,
         "clocks.nna_mhz": 333, "clocks.sva_mhz": 200, "sva.cycles_per_pixel": 1},
        {"source.kind": "camera", "clocks.camera_mhz": 30, "source.camera_hblank": 11,
         "nna.descriptor": "cnn", "clocks.nna_mhz": 460, "clocks.sva_mhz": 465},
    ],
)
def test_fast_engine_equals_the_readable_engine_with_a_camera(over):
    _assert_same(13, 45, over, seed=7)


@pytest.mark.parametrize("stall, depth", [((3, 0), 1), ((4, 2), 2), ((2, 1), 16)])
def test_a_periodically_stalling_sink_gives_the_same_backpressure(stall, depth):
    _assert_same(9, 35, {**SAME_CLOCKS, "fifo.sva_to_sink_depth": depth}, seed=5, stall=stall)


def test_deadlock_is_reported_with_the_same_message():
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


def test_cycle_budget_is_enforced_with_the_same_message():
    """Without a watchdog a sink that never pops runs into the cycle budget of sim.cycle.chip (equal
    clocks: one step per cycle keeps the readable run short)."""
    left, right = _pair(3, 20, seed=10)
    cfg = load_config(overrides={**SAME_CLOCKS, **CENSUS, "sim.watchdog_cycles": 1 << 40})
    never = (1 << 40, (1 << 40) - 1)
    with pytest.raises(BudgetExceeded) as fast:
        run_cycle_fast(left, right, cfg, sink_stall=never)
    with pytest.raises(BudgetExceeded) as slow:
        run_cycle(left, right, cfg, sink_stall=_stall_fn(never))
    assert str(fast.value) == str(slow.value)
    assert fast.value.blocks == slow.value.blocks


def test_camera_overflow_has_the_same_message():
    left, right = _pair(25, 29, seed=9)
    cfg = load_config(overrides={"sva.disparities": 16, "source.kind": "camera",
                                 "nna.descriptor": "cnn", "clocks.camera_mhz": 400,
                                 "source.camera_hblank": 0})
    with pytest.raises(CameraOverflow) as fast:
        run_cycle_fast(left, right, cfg)
    with pytest.raises(CameraOverflow) as slow:
        run_cycle(left, right, cfg)
    assert str(fast.value) == str(slow.value)


def test_split_frames_are_refused_by_the_steps_with_a_pointer_to_the_engines_that_run_them():
    from sim.errors import ConfigError

    left, right = _pair(9, 35)
    cfg = load_config(overrides={**CENSUS, "nna.stereo_submodules": 4})
    with pytest.raises(ConfigError, match="runs on sim.cycle.chip.simulate .* or sim.engine=readable"):
        run_cycle_fast(left, right, cfg)


# ---- descriptor rows -----------------------------------------------------------------------


def _rows(fn, img, *args):
    out = np.zeros(img.shape, np.uint64)
    for y in range(img.shape[0]):
        fn(img, y, *args, out[y])
    return out


@pytest.mark.parametrize(
    "window, kind, stride",
    [((11, 3), "plain", 1), ((9, 7), "symmetric", 1), ((7, 7), "plain", 2),
     ((9, 5), "symmetric", 3), ((3, 15), "plain", 2), ((1, 3), "plain", 1)],
)
@pytest.mark.parametrize("shape", [(13, 45), (1, 7), (5, 2)])
def test_census_rows_equal_the_census_kernel(window, kind, stride, shape):
    img = np.random.default_rng(sum(shape) + stride).integers(0, 256, shape, dtype=np.uint8)
    img[: shape[0] // 2, : shape[1] // 3] = 77  # a flat patch: ties give zero bits
    cfg = load_config(overrides={"nna.census.window": list(window), "nna.census.kind": kind,
                                 "nna.census.stride": stride}).nna.census
    offsets_a, offsets_b = census_tables(cfg)
    got = _rows(descriptor_row_census, img, offsets_a, offsets_b)
    np.testing.assert_array_equal(got, census(img, window, kind, stride).astype(np.uint64))


@pytest.mark.parametrize("shape", [(13, 45), (3, 5), (10, 1)])
def test_cnn_rows_equal_the_cnn_kernel_with_the_default_layer(shape):
    img = np.random.default_rng(shape[0]).integers(0, 256, shape, dtype=np.uint8)
    weights, bias, offset = layer(load_config(overrides={"nna.descriptor": "cnn"}).nna)
    got = _rows(descriptor_row_cnn, img, *cnn_tables(weights, bias), np.int32(offset))
    np.testing.assert_array_equal(
        got, cnn_descriptor(img, weights, bias, offset).astype(np.uint64))


# k = 23 is too large for exact float32 sums: the int32 path
@pytest.mark.parametrize("channels, k", [(40, 3), (7, 5), (64, 1), (5, 21), (3, 23)])
def test_cnn_rows_equal_the_cnn_kernel_with_random_layers(channels, k):
    rng = np.random.default_rng(channels)
    img = rng.integers(0, 256, (11, 23), dtype=np.uint8)
    weights = rng.integers(-128, 128, (channels, k, k)).astype(np.int8)
    bias = rng.integers(-5000, 5000, channels).astype(np.int32)
    got = _rows(descriptor_row_cnn, img, *cnn_tables(weights, bias), np.int32(128))
    np.testing.assert_array_equal(got, cnn_descriptor(img, weights, bias, 128).astype(np.uint64))
