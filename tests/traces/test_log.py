"""The trace log: validation with one-line errors, the recorder hook, select and window."""

import dataclasses

import numpy as np
import pytest

from stereosim.core.errors import ConfigError
from stereosim.sim.cycle.readable.clock import Block
from stereosim.sim.cycle.readable.kernel import Simulator
from stereosim.sim.cycle.rules import ClockDomain
from stereosim.traces.log import Clock, Signal, TraceLog, TraceRecorder, select, validate, window


def _log(**over):
    base = dict(
        signals=[Signal("top.a.x", 1, "nna"), Signal("top.a.y", 8, "nna")],
        clocks=[Clock("nna", 10, 0)],
        start_fs=0, end_fs=100,
        initial=np.array([0, 5], np.uint64),
        times_fs=np.array([0, 10, 10, 30], np.int64),
        ids=np.array([0, 1, 0, 1], np.int32),
        values=np.array([1, 6, 0, 200], np.uint64),
    )
    base.update(over)
    return TraceLog(**base)


def test_a_good_log_validates():
    assert validate(_log()).n_changes == 4


@pytest.mark.parametrize("over, message", [
    (dict(signals=[Signal("x", 1, "d"), Signal("top.a.y", 8, "d")]), "has no scope"),
    (dict(signals=[Signal("top.a x", 1, "d"), Signal("top.a.y", 8, "d")]), "not an identifier"),
    (dict(signals=[Signal("top.1a.x", 1, "d"), Signal("top.a.y", 8, "d")]), "not an identifier"),
    (dict(signals=[Signal("clocks.x", 1, "d"), Signal("top.a.y", 8, "d")]), "reserved"),
    (dict(signals=[Signal("top.a.y", 1, "d"), Signal("top.a.y", 8, "d")]), "appears twice"),
    (dict(signals=[Signal("top.a", 1, "d"), Signal("top.a.y", 8, "d")]), "both a signal and"),
    (dict(signals=[Signal("top.a.x", 0, "d"), Signal("top.a.y", 8, "d")]), "from 1 to 64"),
    (dict(signals=[Signal("top.a.x", 65, "d"), Signal("top.a.y", 8, "d")]), "from 1 to 64"),
    (dict(clocks=[Clock("nna", 1, 0)]), "period_fs must be an integer >= 2"),
    (dict(clocks=[Clock("nna", 10, -1)]), "phase_fs must be an integer >= 0"),
    (dict(clocks=[Clock("nna", 10, 0), Clock("nna", 12, 0)]), "appears twice"),
    (dict(end_fs=0), "end_fs must be an integer after start_fs"),
    (dict(initial=np.array([0, 5], np.int64)), "initial has dtype int64; it must be uint64"),
    (dict(initial=np.array([0], np.uint64)), "initial has 1 values for 2 signals"),
    (dict(initial=np.array([2, 5], np.uint64)), "does not fit the 1 bits of signal 'top.a.x'"),
    (dict(ids=np.array([0, 1, 0, 1], np.int64)), "ids has dtype int64; it must be int32"),
    (dict(ids=np.array([0, 1, 0, 2], np.int32)), "ids contain 2"),
    (dict(times_fs=np.array([0, 10, 5, 30], np.int64)), "go backwards at change 2"),
    (dict(times_fs=np.array([0, 10, 10, 100], np.int64)), "outside the window"),
    (dict(values=np.array([1, 6, 0, 256], np.uint64)), "256, which does not fit the 8 bits"),
    (dict(values=np.array([1, 6, 0], np.uint64)), "must have one length"),
])
def test_bad_logs_give_one_line_errors(over, message):
    with pytest.raises(ConfigError, match=message) as exc:
        validate(_log(**over))
    assert "\n" not in str(exc.value)


def test_window_recomputes_initial_values():
    part = window(_log(), 10, 30)
    # changes at 0 (x=1) are before the window; at 10 y=6 and x=0 are inside it
    assert part.initial.tolist() == [1, 5]
    assert part.times_fs.tolist() == [10, 10] and part.ids.tolist() == [1, 0]
    assert (part.start_fs, part.end_fs) == (10, 30)
    assert window(_log(), 11, 100).initial.tolist() == [0, 6]


@pytest.mark.parametrize("a, b", [(10, 10), (-1, 50), (20, 101)])
def test_window_outside_the_log_is_refused(a, b):
    with pytest.raises(ConfigError, match="empty or outside the recorded window"):
        window(_log(), a, b)


def test_select_renumbers_ids():
    part = select(_log(), ["*.y"])
    assert [s.path for s in part.signals] == ["top.a.y"]
    assert part.ids.tolist() == [0, 0] and part.values.tolist() == [6, 200]
    assert part.initial.tolist() == [5] and part.clocks == _log().clocks


def test_select_names_some_signals_when_a_pattern_matches_nothing():
    with pytest.raises(ConfigError, match=r"'top.b.\*' matches no signal .*top.a.x, top.a.y"):
        select(_log(), ["top.a.*", "top.b.*"])


class _Counter(Block):
    """Counts its cycles in ``count`` (committed, traced, 2 bits), wrapping at 4, and is busy
    every cycle."""

    def __init__(self, name, domain):
        super().__init__(name, domain)
        self.count = 0
        self._next = 0

    def evaluate(self, now_cycle):
        self._next = (self.count + 1) % 4
        self.busy()

    def commit(self):
        self.count = self._next

    def signals(self):
        return [("count", 2)]

    def signal_values(self):
        return {"count": self.count}


def test_recorder_is_the_simulator_hook():
    fast, slow = ClockDomain("nna", 460e6), ClockDomain("camera", 74.25e6)
    signals = [Signal("top.nna.counter.count", 2, "nna"),
               Signal("top.cameras.counter.count", 2, "camera")]
    clocks = [Clock(d.name, d.period_fs, d.phase_fs) for d in (fast, slow)]
    rec = TraceRecorder(signals, clocks, names=["f.count", "s.count"])
    sim = Simulator(trace=rec)
    for d in (fast, slow):
        sim.add_domain(d)
    sim.add_block(_Counter("f", fast))
    sim.add_block(_Counter("s", slow))
    for _ in range(40):
        sim.step()
    log = rec.log()
    assert log.end_fs == sim.now_fs + 1
    for i, dom in enumerate((fast, slow)):
        mine = log.ids == i
        # value after the commit of cycle k is (k + 1) % 4, logged at edge k
        ks = (log.times_fs[mine] - dom.phase_fs) // dom.period_fs
        assert np.array_equal(log.values[mine], (ks + 1) % 4)
        assert np.all((log.times_fs[mine] - dom.phase_fs) % dom.period_fs == 0)


def test_recorder_scopes_a_window_while_recording():
    signals = [Signal("top.a.x", 8, "d")]
    rec = TraceRecorder(signals, [Clock("d", 10, 0)], start_fs=20, end_fs=50)
    for t in range(0, 80, 10):
        rec(t, {"d": t // 10}, {"top.a.x": t})
    log = rec.log()
    assert log.initial.tolist() == [10]
    assert log.times_fs.tolist() == [20, 30, 40] and log.values.tolist() == [20, 30, 40]
    assert (log.start_fs, log.end_fs) == (20, 50)


def test_recorder_packs_chunks_and_rejects_bad_input():
    rec = TraceRecorder([Signal("top.a.x", 64, "d")], [])
    for t in range(70_000):
        rec(t, {}, {"top.a.x": (t * 2654435761) % (1 << 64)})
    log = rec.log()
    assert log.n_changes == 70_000 and len(rec._chunks) == 2
    assert int(log.values[69_999]) == (69_999 * 2654435761) % (1 << 64)
    with pytest.raises(ConfigError, match="unknown signal 'top.b'"):
        rec(70_000, {}, {"top.b": 1})
    with pytest.raises(ConfigError, match="time went back"):
        rec(5, {}, {"top.a.x": 1})
    lax = TraceRecorder([Signal("top.a.x", 1, "d")], [], strict=False)
    lax(0, {}, {"top.b": 3, "top.a.x": 1})
    assert lax.log().values.tolist() == [1]
    bad = TraceRecorder([Signal("top.a.x", 1, "d")], [])
    bad(0, {}, {"top.a.x": -1})
    with pytest.raises(ConfigError, match="not an unsigned integer"):
        bad.log()


def test_log_is_a_plain_dataclass():
    assert [f.name for f in dataclasses.fields(TraceLog)] == [
        "signals", "clocks", "start_fs", "end_fs", "initial", "times_fs", "ids", "values"]


def test_dump_of_a_simulation_reads_back_as_the_simulators_state(tmp_path):
    """Record a two-domain run, dump it, and read the VCD back with pywellen: at every step the
    values equal what the simulator itself reported (signal_values after the step)."""
    import pywellen

    from stereosim.traces.vcd import write_vcd

    fast, slow = ClockDomain("nna", 460e6), ClockDomain("camera", 74.25e6, phase_fs=1_000_000)
    keys = ["f.count", "s.count"]
    signals = [Signal("top.nna.f.count", 2, "nna"), Signal("top.cameras.s.count", 2, "camera")]
    clocks = [Clock(d.name, d.period_fs, d.phase_fs) for d in (fast, slow)]
    rec = TraceRecorder(signals, clocks, names=keys, start_fs=5_000_000)
    sim = Simulator(trace=rec, order_seed=3)
    for d in (fast, slow):
        sim.add_domain(d)
    sim.add_block(_Counter("f", fast))
    sim.add_block(_Counter("s", slow))
    seen = []
    for _ in range(60):
        sim.step()
        seen.append((sim.now_fs, sim.signal_values()))
    write_vcd(tmp_path / "run.vcd", rec.log())
    w = pywellen.Waveform(str(tmp_path / "run.vcd"))
    got = {v.full_name: v.signal for v in w.all_vars()}
    checked = 0
    for t, state in seen:
        if t < 5_000_000:
            continue
        for key, sig in zip(keys, signals):
            assert int(got[sig.path].value_at(t)) == state[key], (sig.path, t)
            checked += 1
        high = (t % fast.period_fs) < fast.period_fs // 2
        assert int(got["clocks.nna"].value_at(t)) == (1 if high else 0)
    assert checked > 80
