"""The block tests' bench (conftest.py) can fail: a signal's waveform is what a viewer shows,
and the comparison of one block's results names what differs."""

import numpy as np

from stereosim.traces.log import Clock, Signal, TraceLog


def _log(initial, changes):
    times, ids, values = (np.array(c, dtype) for c, dtype in
                          zip(zip(*changes), (np.int64, np.int32, np.uint64)))
    return TraceLog([Signal("top.a.x", 8, "d"), Signal("top.a.y", 8, "d")],
                    [Clock("d", 10, 0)], 0, 100, np.array(initial, np.uint64),
                    times, ids, values)


def test_a_waveform_keeps_the_last_change_of_an_instant_and_drops_no_ops(bench):
    """A signal's waveform: its value entering the window, then one change an instant (the
    last logged), none where the value stays."""
    wave = bench.waveform
    log = _log([3, 0], [(0, 0, 3), (10, 0, 4), (10, 0, 5), (10, 1, 1), (20, 0, 5), (30, 0, 3)])
    assert wave(log, "top.a.x") == (3, [(10, 5), (30, 3)])
    assert wave(log, "top.a.y") == (0, [(10, 1)])


def test_the_comparison_names_what_differs(bench):
    """The sink's results under two stall patterns differ in its statistics and its signals;
    under the same pattern, in nothing."""
    over = {"sva.disparities": 16, "nna.descriptor": "census", "source.memory_gbps": 4.0,
            "sva.lanes": 128}
    plan, a, _ = bench.run(over, (4, 24), sink_stall=(2, 0))
    _, b, b_fast = bench.run(over, (4, 24), sink_stall=(3, 0))
    diff = bench.differences(bench.results(plan, a, "sink"), bench.results(plan, b, "sink"))
    assert {"stats", "report", "signal top.sink.count", "fifo sva_to_sink stats"} <= set(diff)
    assert bench.agree(plan, b, b_fast, "sink")["stats"]["busy"] == 4 * 24
