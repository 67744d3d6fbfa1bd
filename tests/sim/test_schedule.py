"""The schedule engine (sim/schedule.py): equal to the readable kernel on random
configurations and to the step engine on large frames, declining exactly the runs the steps
must report, and its helper kernels equal to naive references."""

import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sim.config import load_config
from sim.cycle.chip import run_cycle
from sim.cycle.fast import run_cycle_fast
from sim.cycle.schedule import (
    _conv,
    _first_at_or_after,
    _level_walk,
    _watchdog_safe,
    run_schedule,
)
from sim.errors import UserError


def _pair(h, w, seed=0, shift=3):
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (h, w + shift), dtype=np.uint8)
    return base[:, :w].copy(), base[:, shift:].copy()


def _stall_fn(stall):
    if stall is None:
        return None
    period, phase = stall
    return lambda c: c % period != phase


@st.composite
def configurations(draw):
    """A small frame and a configuration drawn over every timing parameter of the chip, frames
    split over two or three submodules per camera (column tiles or row bands) included."""
    h = draw(st.integers(2, 9))
    w = draw(st.integers(17, 36))
    descriptor = draw(st.sampled_from(["census", "cnn"]))
    over = {
        "sva.disparities": 16,
        "nna.descriptor": descriptor,
        "clocks.nna_mhz": draw(st.sampled_from([200, 333, 400, 460])),
        "clocks.sva_mhz": draw(st.sampled_from([150, 400, 465, 700])),
        "fifo.source_to_nna_depth": draw(st.integers(1, 5)),
        "fifo.nna_to_sva_depth": draw(st.integers(1, 6)),
        "fifo.sva_to_sink_depth": draw(st.integers(1, 4)),
        "fifo.latency_cycles": draw(st.integers(1, 3)),
        "fifo.sync_cycles": draw(st.integers(1, 3)),
        "sva.cycles_per_pixel": draw(st.integers(1, 3)),
        "sva.pipeline_latency": draw(st.integers(1, 20)),
        "sva.box_size": draw(st.sampled_from([1, 3, 5])),
        "sva.median": draw(st.sampled_from([0, 3, 5])),
        "nna.line_buffer_rows": draw(st.integers(9 if descriptor == "cnn" else 3, 11)),
        "nna.macs": draw(st.sampled_from([288, 500, 2592])),
    }
    parts = draw(st.sampled_from([1, 2, 3]))
    if parts > 1:
        split = draw(st.sampled_from(["columns", "rows"]))
        if split == "rows":
            h = max(h, parts)
        over.update({"nna.stereo_submodules": 2 * parts, "nna.split": split})
    if draw(st.booleans()):
        over.update({"source.kind": "camera",
                     "clocks.camera_mhz": draw(st.sampled_from([4, 10, 25])),
                     "source.camera_hblank": draw(st.integers(0, 12))})
    else:
        over["source.memory_gbps"] = draw(st.sampled_from([0.05, 0.2, 4.0]))
    stall = None
    if draw(st.booleans()):
        period = draw(st.integers(2, 4))
        stall = (period, draw(st.integers(0, period - 1)))
    return h, w, over, stall, draw(st.integers(0, 99))


@settings(max_examples=150, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(configurations())
def test_the_schedule_equals_the_readable_kernel(case):
    """Either both runs stop with the same error (the schedule declines and the compiled steps
    report it -- splits are not stepped: the readable kernel reports them) or the schedule
    gives the readable kernel's words, report and statistics."""
    h, w, over, stall, seed = case
    left, right = _pair(h, w, seed=seed)
    cfg = load_config(overrides=over)
    try:
        words_r, report_r, chip = run_cycle(left, right, cfg, sink_stall=_stall_fn(stall))
    except UserError as slow:
        assert run_schedule(left, right, cfg, sink_stall=stall) is None
        if over.get("nna.stereo_submodules", 2) == 2:
            with pytest.raises(type(slow)) as fast:
                run_cycle_fast(left, right, cfg, sink_stall=stall)
            assert str(fast.value) == str(slow)
        return
    done = run_schedule(left, right, cfg, sink_stall=stall)
    assert done is not None
    words, report, stats = done
    np.testing.assert_array_equal(words, words_r)
    assert stats == chip.sim.stats()
    assert report == report_r


@pytest.mark.parametrize(
    "shape, over",
    [
        ((720, 1280), {"nna.descriptor": "cnn", "sva.disparities": 128}),
        ((61, 333), {"nna.descriptor": "census", "sva.disparities": 48,
                     "fifo.nna_to_sva_depth": 3, "sva.cycles_per_pixel": 3}),
        ((45, 301), {"nna.descriptor": "cnn", "sva.disparities": 32, "source.kind": "camera",
                     "clocks.camera_mhz": 30, "fifo.sva_to_sink_depth": 2}),
    ],
)
def test_the_schedule_equals_the_step_engine_on_large_frames(shape, over):
    """Frames too large for the readable kernel (a 720p CNN frame: 16.7 M edges), against the
    compiled steps, which the readable kernel checks on small ones."""
    h, w = shape
    left, right = _pair(h, w, seed=h)
    cfg = load_config(overrides=over)
    done = run_schedule(left, right, cfg)
    assert done is not None
    stepped = run_cycle_fast(left, right, cfg, method="steps")
    np.testing.assert_array_equal(done[0], stepped[0])
    assert done[1] == stepped[1]
    assert done[2] == stepped[2]


def test_runs_that_stop_are_left_to_the_steps():
    """Deadlock (a sink that never pops), an exceeded cycle budget and a camera overflow: the
    schedule declines, and the compiled engine still stops as the readable kernel does (the
    messages are compared in tests/sim/test_fast.py)."""
    never = (1 << 40, (1 << 40) - 1)
    left, right = _pair(7, 29, seed=8)
    base = {"sva.disparities": 16, "nna.descriptor": "census"}
    cfg = load_config(overrides={**base, "sim.watchdog_cycles": 500})
    assert run_schedule(left, right, cfg, sink_stall=never) is None
    cfg = load_config(overrides={**base, "sim.watchdog_cycles": 1 << 40})
    assert run_schedule(left, right, cfg, sink_stall=never) is None
    left, right = _pair(25, 29, seed=9)
    cfg = load_config(overrides={"sva.disparities": 16, "source.kind": "camera",
                                 "nna.descriptor": "cnn", "clocks.camera_mhz": 400,
                                 "source.camera_hblank": 0})
    assert run_schedule(left, right, cfg) is None


def test_a_watchdog_the_schedule_cannot_rule_out_is_stepped():
    """With a watchdog of 10 slowest periods and 41 MAC cycles per descriptor, FIFO events are
    further apart than the schedule's check allows (the MAC array counting is progress it does
    not look at), so it declines; the steps complete the run as the readable kernel does."""
    left, right = _pair(5, 21, seed=14)
    cfg = load_config(overrides={"sva.disparities": 16, "nna.descriptor": "cnn",
                                 "nna.macs": 64, "sim.watchdog_cycles": 10})
    assert run_schedule(left, right, cfg) is None
    words, report, stats = run_cycle_fast(left, right, cfg)
    words_r, report_r, chip = run_cycle(left, right, cfg)
    np.testing.assert_array_equal(words, words_r)
    assert report == report_r and stats == chip.sim.stats()


# ---- helper kernels against naive references -----------------------------------------------


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.lists(st.integers(0, 60), max_size=30, unique=True), st.integers(-5, 70),
       st.data())
def test_first_at_or_after_is_a_search(values, lo, data):
    arr = np.array(sorted(values), np.int64)
    start = data.draw(st.integers(0, arr.shape[0]))
    start = min(start, int(np.searchsorted(arr, lo)))  # every entry before start is < lo
    assert _first_at_or_after(arr, lo, start) == np.searchsorted(arr, lo)


@st.composite
def fifo_events(draw):
    """Strictly increasing inc and dec cycles with dec[k] >= inc[k] (an item leaves after it
    came, one event of each kind per cycle at most)."""
    n = draw(st.integers(1, 12))
    inc = np.cumsum(draw(st.lists(st.integers(1, 4), min_size=n, max_size=n)))
    delays = draw(st.lists(st.integers(0, 6), min_size=n, max_size=n))
    dec = []
    for k in range(n):
        dec.append(max(int(inc[k]) + delays[k], dec[-1] + 1 if dec else 0))
    return inc.astype(np.int64), np.array(dec, np.int64)


@settings(max_examples=200, deadline=None, derandomize=True)
@given(fifo_events(), st.integers(1, 4), st.integers(0, 3))
def test_level_walk_equals_a_per_edge_count(events, depth, tail):
    inc, dec = events
    c_end = int(dec[-1]) + 1 + tail
    hist = np.zeros(inc.shape[0] + 2, np.int64)
    top, at_depth = _level_walk(inc, _conv(1, 1, 0), dec, _conv(1, 1, 0), c_end, depth, hist)
    want_hist = np.zeros_like(hist)
    want_at_depth = 0
    for c in range(c_end):
        level = int(np.sum(inc <= c) - np.sum(dec <= c))
        want_hist[level] += 1
        want_at_depth += level >= depth
    want_top = max(k + 1 - int(np.sum(dec < inc[k])) for k in range(inc.shape[0]))
    np.testing.assert_array_equal(hist, want_hist)
    assert at_depth == want_at_depth
    assert top == want_top


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.lists(st.lists(st.integers(0, 400), min_size=1, max_size=20), min_size=1,
                max_size=3), st.integers(10, 40))
def test_the_watchdog_check_is_sound(rows, watchdog):
    """True only if no gap between consecutive events (from one slowest period before 0 to the
    last event) reaches watchdog x p_max; and True whenever every gap is below half of it."""
    periods = np.array([3, 5, 7][: len(rows)], np.int64)
    n = max(len(r) for r in rows)
    t = np.zeros((len(rows), n), np.int64)
    for i, r in enumerate(rows):
        r = sorted(r)
        t[i] = r + [r[-1]] * (n - len(r))
    p_max = int(periods.max())
    instants = sorted({-p_max} | {int(c) * int(periods[i]) for i in range(len(rows))
                                  for c in t[i]})
    t_end = instants[-1]
    gap = max((b - a for a, b in itertools.pairwise(instants)), default=0)
    safe = _watchdog_safe(t, np.arange(len(rows), dtype=np.int64), periods, t_end, p_max,
                          watchdog)
    if safe:
        assert gap < watchdog * p_max
    if gap < (watchdog * p_max) // 2:
        assert safe


@pytest.mark.parametrize(
    "over",
    [
        {"nna.descriptor": "cnn", "nna.stereo_submodules": 4, "fifo.nna_to_sva_depth": 8},
        {"nna.descriptor": "census", "nna.stereo_submodules": 6, "nna.split": "rows",
         "source.kind": "camera", "clocks.camera_mhz": 40},
    ],
)
def test_split_frames_equal_the_readable_kernel_on_a_larger_frame(over):
    left, right = _pair(30, 120, seed=15)
    cfg = load_config(overrides={"sva.disparities": 32, **over})
    words_r, report_r, chip = run_cycle(left, right, cfg)
    words, report, stats = run_schedule(left, right, cfg)
    np.testing.assert_array_equal(words, words_r)
    assert stats == chip.sim.stats()
    assert report == report_r


def test_column_tiles_overlap_only_with_merge_fifos_that_hold_a_tile_row():
    """The merge drains the tiles in raster order: with FIFOs shallower than a tile row the
    second tile of each row waits for the first (blocked) and the frame takes about as long as
    with one submodule; FIFOs holding a tile row let both tiles compute at once."""
    left, right = _pair(20, 96, seed=16)
    base = {"sva.disparities": 16, "nna.descriptor": "cnn"}
    frame = {}
    for parts, depth in ((1, 8), (2, 8), (2, 64)):
        cfg = load_config(overrides={**base, "nna.stereo_submodules": 2 * parts,
                                     "fifo.nna_to_sva_depth": depth})
        _, report, _ = run_schedule(left, right, cfg)
        frame[parts, depth] = report["cycles"]["last_output"]["sva"]
    assert frame[2, 8] > 0.8 * frame[1, 8]
    assert frame[2, 64] < 0.65 * frame[1, 8]


def test_sim_run_takes_split_frames_to_the_schedule_and_stops_on_the_readable_kernel():
    from sim.api import run
    from sim.cycle.blocks.sources import CameraOverflow

    left, right = _pair(19, 45, seed=17)
    over = {"sva.disparities": 16, "nna.descriptor": "census", "nna.stereo_submodules": 4}
    res = run(left, right, mode="cycle", overrides=over)
    words_r, report_r, _ = run_cycle(left, right, load_config(overrides=over))
    assert res.report["engine"] == "fast"
    assert res.report["cycles"] == report_r["cycles"]
    np.testing.assert_array_equal(res.disparity_fixed, words_r)
    over.update({"source.kind": "camera", "nna.descriptor": "cnn", "clocks.camera_mhz": 400,
                 "source.camera_hblank": 0})
    with pytest.raises(CameraOverflow, match="src_left_to_nna"):
        run(left, right, mode="cycle", overrides=over)
