"""The SVA as a lock-step pipeline (sim/cycle/readable/blocks/sva.py, sim/cycle/compiled/sva.py):
a stall freezes every word in flight and the next issue with them, its stages' words and status
are traced, and a stage that needs more SRAM accesses than its ports allow shows in the trace.
Cycles are checked against the rules written out by hand here."""

from __future__ import annotations

import numpy as np
import pytest

from stereosim.core.config import load_config
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.readable.chip import run_readable
from stereosim.traces.log import changes_of

# the 3x3 median and 5x5 box of tests/sim/cycle/readable/test_chip.py's derivation (latency 50 at
# D = 16)
SAME = {"clocks.nna_mhz": 400, "clocks.sva_mhz": 400, "nna.descriptor": "census",
        "sva.disparities": 16, "sva.median": 3, "sva.box_size": 5}


def _pair(h, w, seed=0):
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (h, w + 3), dtype=np.uint8)
    return base[:, 3:].copy(), base[:, :w].copy()


def test_a_stall_freezes_the_words_in_flight_and_the_next_rows_issue(run_cycle):
    """Rows arrive slowly (the memory gives a pixel every 3 cycles), so row 1 becomes ready
    while the last words of row 0 are still in the pipeline; no median, so each word leaves L
    after its own issue. Box row y's first word is issued r = 2 slots after its row is ready
    (the passes are long over), its others every II. The sink (FIFO depth 1) refuses to pop
    while row 1 becomes ready: word W - k waits in the output register and the pipeline
    stalls. When the sink pops again at s1, the FIFO's slot is seen free at s1 + 1: word W - k
    leaves then, the k - 1 words behind it follow every II, and row 1 -- ready during the
    stall, when the pipeline's tick stood at word W - k's exit tick -- has its r look-ahead
    slots in the cycles the pipeline resumes with and its first word issued in s1 + 1 + r,
    leaving L cycles later. (A pipeline that did not freeze would have sent it at ready + r +
    L.)"""
    h, w = 6, 40
    over = {**SAME, "sva.median": 0, "source.memory_gbps": 0.4 / 3,
            "fifo.sva_to_sink_depth": 1}
    cfg = load_config(overrides=over)
    plan = build_plan(cfg, (h, w))
    lat, ii, r = plan.block("sva").latency, plan.block("sva").ii, 2
    assert (lat, ii, plan.block("sva").slot_ii) == (48, 2, 1)
    left, right = _pair(h, w)
    _, rep, chip = run_cycle(left, right, cfg)
    r0, r1 = (int(c) for c in chip.blocks["sva"].ready_cycle[:2])
    push = [r0 + r + lat + ii * j for j in range(w)]  # row 0 without a stall
    assert rep["cycles"]["first_output"]["sva"] == push[0] + 1
    # the first word of row 0 that reaches the output register before row 1 is ready
    k = next(k for k in range(1, w) if push[w - k] < r1 - 1)
    assert 2 * k <= lat  # row 1's issue then waits for the stall, not for the II
    s0, s1 = push[w - k - 1] + 1, r1 + 7  # the sink refuses to pop in [s0, s1)
    _, rep, chip = run_cycle(left, right, cfg, sink_stall=lambda c: s0 <= c < s1)
    last0 = (s1 + 1) + ii * (k - 1)  # word W - 1 leaves
    first1 = (s1 + 1) + r + lat  # row 1's first word
    assert chip.sink.row_cycles[0] == last0 + 1
    assert chip.sink.row_cycles[1] == first1 + ii * (w - 1) + 1
    assert first1 > r1 + r + lat  # what freezing costs row 1
    # the stall: word W - k in the output register from its arrival to its push; the block
    # counts those cycles blocked unless it took a pair of the next rows in them
    stall = (s1 + 1) - push[w - k]
    assert rep["sva_stages"]["output"]["blocked"] == stall
    assert rep["blocks"]["sva"]["blocked"] <= stall


def _trace(run, plan, left, right, window, **kw):
    frame = run(plan, left, right, window=window, **kw)
    log = frame.trace
    paths = [s.path for s in log.signals]
    return frame, log, paths


def _values_at(log, sig_id, times):
    """The signal's value after each instant of ``times`` (fs)."""
    t, v = changes_of(log, sig_id)
    out = []
    for x in times:
        i = np.searchsorted(t, x, side="right") - 1
        out.append(int(v[i]) if i >= 0 else int(log.initial[sig_id]))
    return np.array(out)


@pytest.mark.parametrize("run", [run_readable, run_compiled])
def test_the_stages_words_add_up_to_the_pipelines_and_the_lr_window_fills(run):
    """In every cycle of a window the words in the pipeline (issued, not yet pushed) are the
    words the stages hold (they partition its positions) and the S = m W + m words the
    median's row banks hold (3x3: S = W + 1; each word leaves with the word S after it), and
    in steady state the LR window holds D words."""
    h, w = 6, 60
    plan = build_plan(load_config(overrides=SAME), (h, w))
    sva = plan.block("sva")
    assert sva.skew == w + 1
    left, right = _pair(h, w, seed=2)
    per = plan.domains["sva"].period_fs
    first = run_compiled(plan, left, right).report["cycles"]["first_output"]["sva"]
    start, end = first * per, (first + 200) * per
    _, log, paths = _trace(run, plan, left, right, (start, end))
    times = np.arange(start, end, per)
    total = _values_at(log, paths.index("top.sva.pipeline.words"), times)
    stages = [s.name for s in sva.stages]
    held = sum(_values_at(log, paths.index(f"top.sva.stage.{s}.words"), times)
               for s in stages)
    np.testing.assert_array_equal(total - held, sva.skew)
    assert held.max() == -(-sva.latency // sva.ii)
    lr = _values_at(log, paths.index("top.sva.stage.lr_check.words"), times[-50:])
    assert lr.max() == 16 and lr.min() >= 15  # D = 16: a word leaves as the next enters
    status = _values_at(log, paths.index("top.sva.stage.lr_check.status"), times[-50:])
    assert set(status) == {1}  # busy


@pytest.mark.parametrize("run", [run_readable, run_compiled])
@pytest.mark.parametrize("ports, ii", [("1r1w", 3), ("1rw", 4)])
def test_single_port_sram_spaces_the_issues_in_the_trace(run, ports, ii):
    """64 lanes at D = 128: two lane groups per pixel. With a read and a write port per SGM
    bank the left path's recurrence sets the II (2 - 1 + tree(5) + tree(6 + 1) = 3); with one
    shared port each top path's bank needs 2 reads + 2 writes = 4 cycles per pixel. The
    trace's ``pipeline.issue`` pulses every II cycles; the SGM stage holds each pixel for
    its latency of G + tree(5 levels of its step) = 3 cycles of every II (with one port its
    bank is busy in the fourth, writing back)."""
    over = {**SAME, "sva.disparities": 128, "sva.lanes": 64, "sva.sram_ports": ports}
    h, w = 4, 140
    plan = build_plan(load_config(overrides=over), (h, w))
    assert plan.block("sva").ii == ii
    left, right = _pair(h, w, seed=3)
    per = plan.domains["sva"].period_fs
    first = run_compiled(plan, left, right).report["cycles"]["first_output"]["sva"]
    lat = plan.block("sva").latency
    start, end = (first - lat) * per, (first - lat + 40 * ii) * per
    _, log, paths = _trace(run, plan, left, right, (start, end))
    t, v = changes_of(log, paths.index("top.sva.pipeline.issue"))
    rises = t[v == 1] // per
    assert len(rises) >= 30
    assert set(np.diff(rises)) == {ii}
    sgm_lat = next(st.latency for st in plan.block("sva").stages if st.name == "sgm")
    assert sgm_lat == 3
    off = sum(st.latency for st in plan.block("sva").stages[:3])  # row read, hamming, box
    a, b = rises[1] + off + 1, rises[-5] + off + 1  # whole IIs, inside the window
    sgm = _values_at(log, paths.index("top.sva.stage.sgm.status"), np.arange(a, b) * per)
    assert (sgm == 1).sum() == sgm_lat * (b - a) // ii  # busy 3 of every II cycles
    assert set(sgm) <= {1, 2}  # otherwise starved: never blocked, never idle


@pytest.mark.parametrize("run", [run_readable, run_compiled])
def test_automatic_weights_hold_the_first_costs_until_the_noise_band_is_in(run):
    """The hybrid's automatic weights come from the noise statistic of the left view's first
    r + m + 1 rows (sva/hamming/noise.py: box 7, 5x5 median: rows 0 .. 5), so the frame's first
    slot --
    the column sums' first pass, the frame's first matching costs -- waits for row r + m
    (``rules.sva_first_slot_row``). The NNA gives a descriptor every 9 cycles, far slower than
    the SVA: with fixed weights the six passes start after row 0 and are over before row r = 3
    is in, so the first word goes r = 3 slots after row 3 is ready (the cycle after it is
    complete); with automatic weights the passes start once row 5 is, and the first word goes
    6 W + 3 after that."""
    h, w = 12, 40
    left, right = _pair(h, w)
    first = {}
    for mode in ("fixed", "auto"):
        cfg = load_config(overrides={"nna.descriptor": "hybrid", "sva.weight_mode": mode,
                                     "sva.disparities": 16})
        plan = build_plan(cfg, (h, w))
        sva = plan.block("sva")
        assert (sva.lookahead, sva.passes, sva.slot_ii) == (3, 6, 1)
        assert sva.first_row == (5 if mode == "auto" else 0)
        _, log, paths = _trace(run, plan, left, right, (0, 10**13))
        per = plan.domains["sva"].period_fs
        t, v = changes_of(log, paths.index("top.sva.pipeline.issue"))
        t_row, v_row = changes_of(log, paths.index("top.sva.input.row"))
        # input row y is complete in the cycle `input.row` becomes y + 1: ready the next
        ready = {int(y) - 1: int(c) // per + 1 for c, y in zip(t_row, v_row, strict=True) if y}
        first[mode] = int(t[v == 1][0]) // per
        want = ready[3] + 3 if mode == "fixed" else ready[5] + 6 * w + 3
        assert first[mode] == want, mode
    assert first["auto"] > first["fixed"]
