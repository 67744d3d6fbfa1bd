"""The disparity sink, block by block: sim/cycle/compiled/sink.py against its readable twin
(sim/cycle/readable/blocks/sources.py: Sink, and the DRAM channel's write side). Each test runs
one plan on both engines and holds the sink's own results equal -- its statistics, the FIFO it
pops, its traced signals, the instants it holds each row and each frame's last word, or its
state when the run stops -- on a configuration that stresses the sink."""

import numpy as np
import pytest

from stereosim.sim.cycle.contract import DeadlockError
from stereosim.sim.cycle.rules import sink_may_pop, sink_pattern

FAST_SVA = {"sva.disparities": 16, "nna.descriptor": "census", "source.memory_gbps": 4.0,
            "sva.lanes": 128}


def _script(n, p, seed):
    script = np.random.default_rng(seed).random(n) < p
    script[n // 2] = True
    return script


def _pops_follow(plan, got, stall):
    """Every word the sink counted, it popped in a cycle its pattern allows (its ``count``
    changes at the sink's clock edges)."""
    pattern = sink_pattern(stall)
    period = plan.domains["sva"].period_fs
    _, changes = got["signal top.sink.count"]
    assert changes and all(t % period == 0 for t, _ in changes)
    return all(sink_may_pop(t // period, pattern) for t, _ in changes)


@pytest.mark.parametrize("stall", [(2, 1), (3, 0), (12, 11), "sparse", "dense"])
@pytest.mark.parametrize("depth", [1, 3])
def test_periodic_and_scripted_stalls(bench, stall, depth):
    """Sink: periodic stalls ``(period, phase)`` and random scripts of 0/1 (a fifth or most of
    the cycles allowed) on a one- or three-slot FIFO from a fast SVA: the sink pops only in the
    cycles its pattern allows, so its FIFO fills."""
    if isinstance(stall, str):
        stall = _script(61, 0.2 if stall == "sparse" else 0.8, seed=len(stall))
    over = {**FAST_SVA, "fifo.sva_to_sink_depth": depth}
    plan, slow, fast = bench.run(over, (5, 30), sink_stall=stall)
    got = bench.agree(plan, slow, fast, "sink")
    assert got["stats"]["busy"] == 5 * 30
    assert got["fifo sva_to_sink stats"]["cycles_full"] > 0
    assert _pops_follow(plan, got, stall)
    np.testing.assert_array_equal(slow.row_times[1], fast.row_times[1])  # rows the sink holds


def test_the_pattern_check_sees_a_wrong_pattern(bench):
    """The check above can fail: a run with one pattern does not follow another."""
    plan, slow, fast = bench.run(FAST_SVA, (5, 30), sink_stall=(3, 0))
    assert not _pops_follow(plan, bench.results(plan, slow, "sink"), (3, 1))


@pytest.mark.parametrize("buffer,burst,gbps", [(1, 8, 0.3), (2, 4, 0.3), (1, 64, 2.0)])
def test_the_write_back_through_the_dram_channel(bench, buffer, burst, gbps):
    """Sink with write-back (dram.model = "tdm"): its write buffer of one or two bursts leaves
    only in the channel's write slots, so a full buffer holds the sink back (blocked)."""
    over = {**FAST_SVA, "dram.model": "tdm", "dram.gbps": gbps, "dram.burst_bytes": burst,
            "dram.write_buffer_bursts": buffer, "dram.latency_ns": 50}
    plan, slow, fast = bench.run(over, (5, 30))
    got = bench.agree(plan, slow, fast, "sink")
    assert got["stats"]["blocked"] > 0


def test_a_stream_with_stalls(bench):
    """Sink over a stream: three frames through a stalling sink; each frame's last word
    reaches it at the same instant on both engines (the frame instants' second row)."""
    plan, slow, fast = bench.run({**FAST_SVA, "fifo.sva_to_sink_depth": 2}, (4, 24),
                                 frames=3, sink_stall=(4, 2))
    got = bench.agree(plan, slow, fast, "sink")
    assert got["stats"]["busy"] == 3 * 4 * 24
    np.testing.assert_array_equal(slow.frame_times[1], fast.frame_times[1])
    assert (slow.frame_times[1] > 0).all()


def test_a_sink_that_never_pops(bench):
    """Sink that never pops (its first allowed cycle lies past the run): the SVA fills the
    FIFO and the watchdog stops the run; both engines stop at the same instant with the sink
    and its FIFO in the same state."""
    over = {**FAST_SVA, "sim.watchdog_cycles": 50, "fifo.sva_to_sink_depth": 3}
    plan, slow, fast = bench.stop(over, (5, 30), sink_stall=(1 << 40, (1 << 40) - 1))
    assert type(slow) is DeadlockError
    got = bench.agree(plan, slow, fast, "sink")
    assert got["fifo sva_to_sink"] == {"occupancy": 3, "depth": 3}
