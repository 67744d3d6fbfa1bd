"""The clock kernel: domains and steps, two-phase evaluation, activity accounting, the progress
watchdog, the cycle budget, order independence and the trace hook -- all in exact cycles."""

import pytest

from stereosim.core.errors import ConfigError, UserError
from stereosim.sim.cycle.contract import BudgetExceeded, DeadlockError, count_instants
from stereosim.sim.cycle.fifo.readable import Fifo, KernelError
from stereosim.sim.cycle.readable.clock import Block
from stereosim.sim.cycle.readable.kernel import Simulator
from stereosim.sim.cycle.rules import ClockDomain

P = 10_000_000  # 100 MHz in fs


class Source(Block):
    """Pushes 0, 1, ..., n-1 into ``out``, one per cycle whenever ``can_push()``.
    Ports: out. Busy in a push cycle, blocked while it has items and ``out`` is full, idle when
    done. Traces ``sent`` (items pushed, committed)."""

    def __init__(self, name, domain, out, n):
        super().__init__(name, domain)
        self.out = out
        self.n = n
        self.sent = 0
        self._pushed = False

    def evaluate(self, now_cycle):
        k = self.sent
        if k >= self.n:
            self.idle()
        elif self.out.can_push():
            self.out.push(k)
            self._pushed = True
            self.busy()
        else:
            self.blocked(self.out)

    def commit(self):
        if self._pushed:
            self.sent += 1
            self._pushed = False

    def signals(self):
        return [("sent", 16)]

    def signal_values(self):
        return {"sent": self.sent}


class Sink(Block):
    """Pops one visible item per cycle, except in cycles where ``stall(cycle)`` is true.
    Ports: inp. Busy in a pop cycle, idle when stalled, starved when nothing is visible.
    Traces ``received`` (items popped, committed); the items are collected in ``items`` at
    commit."""

    def __init__(self, name, domain, inp, stall=None):
        super().__init__(name, domain)
        self.inp = inp
        self.stall = stall
        self.items = []
        self.received = 0
        self._got = None

    def evaluate(self, now_cycle):
        if self.stall is not None and self.stall(now_cycle):
            self.idle()
        elif self.inp.can_pop():
            self._got = self.inp.pop()
            self.busy()
        else:
            self.starved(self.inp)

    def commit(self):
        if self._got is not None:
            self.items.append(self._got)
            self.received += 1
            self._got = None

    def signals(self):
        return [("received", 16)]

    def signal_values(self):
        return {"received": self.received}


class Stage(Block):
    """A unit with initiation interval ``ii`` and latency ``lat`` (>= 1) computing ``f(item)``.

    Ports: inp, out. It accepts (pops) an input item in cycle t if one is visible, t >= the
    previous accept + ii, and one of its ceil(lat / ii) slots is free; the result is pushed in
    cycle t + lat, or in the first later cycle in which ``out`` has space. Activity: busy when it
    accepts or pushes, while an accepted item is in flight, and in the ii - 1 cycles after an
    accept (the unit is occupied); otherwise blocked if a finished result cannot be pushed,
    starved if no input is visible.
    """

    def __init__(self, name, domain, inp, out, ii, lat, f=lambda x: x):
        super().__init__(name, domain)
        self.inp, self.out, self.ii, self.lat, self.f = inp, out, ii, lat, f
        self.slots = -(-lat // ii)
        self.inflight = []  # (cycle the result is ready, result), committed
        self.next_accept = 0  # committed
        self.accepts = 0  # committed
        self._staged = None

    def evaluate(self, now_cycle):
        flight = list(self.inflight)
        pushed = stuck = False
        if flight and flight[0][0] <= now_cycle:
            if self.out.can_push():
                self.out.push(flight.pop(0)[1])
                pushed = True
            else:
                stuck = True
        accepted = False
        next_accept = self.next_accept
        if now_cycle >= next_accept and len(flight) < self.slots and self.inp.can_pop():
            flight.append((now_cycle + self.lat, self.f(self.inp.pop())))
            next_accept = now_cycle + self.ii
            accepted = True
        self._staged = (flight, next_accept, self.accepts + accepted)
        if pushed or accepted:
            self.busy()
        elif stuck:
            self.blocked(self.out)
        elif flight or now_cycle < next_accept:
            self.busy()
        else:
            self.starved(self.inp)

    def commit(self):
        self.inflight, self.next_accept, self.accepts = self._staged

    def signals(self):
        return [("accepts", 16)]

    def signal_values(self):
        return {"accepts": self.accepts}


class Window3(Block):
    """Sliding sum of 3: when 3 items are visible in ``inp`` (read in place, like a line buffer)
    and ``out`` has space, pushes their sum and pops one. Starved while fewer than 3 are visible.
    Needs an input FIFO of depth >= 3, otherwise it waits forever."""

    def __init__(self, name, domain, inp, out):
        super().__init__(name, domain)
        self.inp, self.out = inp, out

    def evaluate(self, now_cycle):
        if self.inp.visible_count() < 3:
            self.starved(self.inp)
        elif not self.out.can_push():
            self.blocked(self.out)
        else:
            self.out.push(sum(self.inp.peek(i) for i in range(3)))
            self.inp.pop()
            self.busy()


def _sim(*domains, **kw):
    sim = Simulator(**kw)
    for d in domains:
        sim.add_domain(d)
    return sim


# ---- domains and steps -----------------------------------------------------------------------


def test_domain_period_is_rounded_to_whole_femtoseconds():
    assert ClockDomain("a", 100e6).period_fs == 10_000_000
    assert ClockDomain("b", 150e6).period_fs == 6_666_667
    assert ClockDomain("c", 460.8e6).period_fs == 2_170_139
    dom = ClockDomain("d", 1e9, phase_fs=250)
    assert [dom.edge_fs(k) for k in range(3)] == [250, 1_000_250, 2_000_250]
    assert [dom.first_edge_after(t) for t in (0, 249, 250, 1_000_249, 1_000_250)] == [0, 0, 1, 1, 2]


@pytest.mark.parametrize(
    "kw, words",
    [
        ({"name": "", "freq_hz": 1e6}, "name must be a non-empty string"),
        ({"name": "a", "freq_hz": 0}, "freq_hz must be a positive number"),
        ({"name": "a", "freq_hz": float("nan")}, "freq_hz must be a positive number"),
        ({"name": "a", "freq_hz": 1e16}, "below 1 fs"),
        ({"name": "a", "freq_hz": 1e6, "phase_fs": -1}, "phase_fs must be >= 0"),
        ({"name": "a", "freq_hz": 1e6, "phase_fs": 1.5}, "phase_fs must be an integer"),
    ],
)
def test_bad_domains_raise_config_errors(kw, words):
    with pytest.raises(ConfigError, match=words):
        ClockDomain(**kw)


class Counter(Block):
    """Counts its cycles (``count``, committed and traced) and records the cycle indices it was
    given."""

    def __init__(self, name, domain):
        super().__init__(name, domain)
        self.count = 0
        self.seen = []
        self._next = 0

    def evaluate(self, now_cycle):
        self.seen.append(now_cycle)
        self._next = self.count + 1
        self.busy()

    def commit(self):
        self.count = self._next

    def signals(self):
        return [("count", 32)]

    def signal_values(self):
        return {"count": self.count}


def test_steps_visit_every_edge_in_time_order_and_ties_tick_together():
    """Periods 2 ns, 3 ns (phase 1 ns) and 2 ns: steps at 0, 1, 2, 4, 6, 7, 8 ns... the two 2 ns
    domains always tick in the same step."""
    a = ClockDomain("a", 500e6)
    b = ClockDomain("b", 1e15 / 3_000_000, phase_fs=1_000_000)
    c = ClockDomain("c", 500e6)
    steps = []
    sim = _sim(a, b, c, trace=lambda t, cyc, ch: steps.append((t // 1_000_000, cyc)))
    blocks = [sim.add_block(Counter(f"n{d.name}", d)) for d in (a, b, c)]
    sim.run(lambda: sim.now_fs >= 10_000_000, budget_cycles=100)
    assert steps == [
        (0, {"a": 0, "c": 0}),
        (1, {"b": 0}),
        (2, {"a": 1, "c": 1}),
        (4, {"a": 2, "b": 1, "c": 2}),
        (6, {"a": 3, "c": 3}),
        (7, {"b": 2}),
        (8, {"a": 4, "c": 4}),
        (10, {"a": 5, "b": 3, "c": 5}),
    ]
    assert sim.cycles == {"a": 6, "b": 4, "c": 6}
    assert [b.seen for b in blocks] == [list(range(6)), list(range(4)), list(range(6))]
    assert [b.count for b in blocks] == [6, 4, 6]


def test_registers_commit_only_after_every_block_evaluated():
    """A swaps its register with B's every cycle, B with A's: with two phases they exchange
    values (no block sees the other's new value in the same cycle)."""

    class Swap(Block):
        def __init__(self, name, domain, reset):
            super().__init__(name, domain)
            self.r = reset  # committed
            self._next = reset
            self.other = None

        def evaluate(self, now_cycle):
            self._next = self.other.r
            self.busy()

        def commit(self):
            self.r = self._next

    clk = ClockDomain("clk", 100e6)
    for seed in (None, 1, 2, 3):
        sim = _sim(clk, order_seed=seed)
        x, y = sim.add_block(Swap("x", clk, 1)), sim.add_block(Swap("y", clk, 2))
        x.other, y.other = y, x
        values = []
        for _ in range(3):
            sim.step()
            values.append((x.r, y.r))
        assert values == [(2, 1), (1, 2), (2, 1)]


# ---- pipelines in exact cycles ---------------------------------------------------------------


def _throttled(n, depth=2, ii=3, lat=1):
    clk = ClockDomain("clk", 100e6)
    sim = _sim(clk)
    a = sim.add_fifo(Fifo("src_to_stage", depth, 16, src=clk, dst=clk))
    b = sim.add_fifo(Fifo("stage_to_sink", 2, 16, src=clk, dst=clk))
    src = sim.add_block(Source("source", clk, a, n))
    stage = sim.add_block(Stage("stage", clk, a, b, ii, lat, f=lambda x: 10 * x))
    sink = sim.add_block(Sink("sink", clk, b))
    return sim, src, stage, sink


@pytest.mark.parametrize("n", [3, 4, 10])
def test_stage_with_ii_3_throttles_the_source(n):
    """Source -> fifo (depth 2, latency 1) -> Stage(ii=3, lat=1) -> fifo (depth 2) -> Sink.

    The stage accepts item k in cycle 1 + 3k and pushes it in 2 + 3k; the sink pops it in
    3 + 3k, so n items take 3n + 1 cycles (= ii (n - 1) + lat + 3). The source pushes in 0, 1, 2
    and then item k >= 2 when the slot of item k - 2 (popped in 3k - 5) is seen free: cycle
    3k - 4. It is blocked in cycles 3 .. 3n - 7 except the n - 3 push cycles: 2 (n - 3) cycles.
    The first FIFO is seen full in cycles 3m and 3m + 1 for m = 1 .. n - 2: 2 (n - 2) cycles.
    """
    sim, _src, _stage, sink = _throttled(n)
    stats = sim.run(lambda: len(sink.items) == n, budget_cycles=1000, watchdog_cycles=20)
    assert sink.items == [10 * k for k in range(n)]
    assert stats["cycles"] == {"clk": 3 * n + 1}
    assert stats["blocks"] == {
        "sink": {"blocked": 0, "busy": n, "idle": 0, "starved": 2 * n + 1},
        "source": {"blocked": 2 * (n - 3), "busy": n, "idle": 7, "starved": 0},
        "stage": {"blocked": 0, "busy": 3 * n, "idle": 0, "starved": 1},
    }
    up = stats["fifos"]["src_to_stage"]
    assert up["max_occupancy"] == 2 and up["max_producer_occupancy"] == 2
    assert up["cycles_full"] == 2 * (n - 2)
    assert sum(up["occupancy_histogram"]) == 3 * n + 1


def test_stage_latency_longer_than_ii_pipelines_several_items():
    """Stage(ii=1, lat=4) has 4 slots: item k accepted in 1 + k, pushed in 5 + k, popped by the
    sink in 6 + k: n items in n + 6 cycles (= ii (n - 1) + lat + 3)."""
    n = 9
    sim, _src, _stage, sink = _throttled(n, depth=2, ii=1, lat=4)
    stats = sim.run(lambda: len(sink.items) == n, budget_cycles=1000, watchdog_cycles=20)
    assert stats["cycles"] == {"clk": n + 6}
    assert stats["blocks"]["source"] == {"blocked": 0, "busy": n, "idle": 6, "starved": 0}


def test_blocked_stage_counts_blocked_cycles():
    """Source -> fifo (depth 2) -> Stage(ii=1, lat=1) -> fifo b (depth 1) -> Sink stalling in odd
    cycles. Sink pops item k in 4 + 2k (item 0 is visible in 3, a stall cycle), so n items take
    2n + 3 cycles. The slot of item k is free for the stage in 5 + 2k, so item k >= 1 enters b
    in 3 + 2k. The stage is blocked holding item 1 in cycles 3, 4 and item k >= 2 (ready in
    2k + 2) for one cycle: n blocked cycles. b is seen full in 3, 4 and in 4 + 2k for k >= 1:
    n + 1 cycles (the last one after the stage has nothing left)."""
    n = 5
    clk = ClockDomain("clk", 100e6)
    sim = _sim(clk)
    a = sim.add_fifo(Fifo("a", 2, 8, src=clk, dst=clk))
    b = sim.add_fifo(Fifo("b", 1, 8, src=clk, dst=clk))
    sim.add_block(Source("source", clk, a, n))
    sim.add_block(Stage("stage", clk, a, b, 1, 1))
    sink = sim.add_block(Sink("sink", clk, b, stall=lambda c: c % 2 == 1))
    stats = sim.run(lambda: len(sink.items) == n, budget_cycles=1000)
    assert sink.items == list(range(n))
    assert stats["cycles"] == {"clk": 2 * n + 3}
    assert stats["blocks"]["stage"]["blocked"] == n
    assert stats["fifos"]["b"]["cycles_full"] == n + 1


# ---- deadlock and budget ---------------------------------------------------------------------


def _window(depth, n=6):
    clk = ClockDomain("clk", 100e6)
    sim = _sim(clk)
    a = sim.add_fifo(Fifo("src_to_win", depth, 8, src=clk, dst=clk))
    b = sim.add_fifo(Fifo("win_to_sink", 4, 10, src=clk, dst=clk))
    sim.add_block(Source("source", clk, a, n))
    sim.add_block(Window3("win", clk, a, b))
    sink = sim.add_block(Sink("sink", clk, b))
    return sim, sink


@pytest.mark.parametrize("depth, cycles", [(3, lambda n: 2 * n - 1), (4, lambda n: n + 2)])
def test_window_of_3_needs_depth_4_for_full_rate(depth, cycles):
    """Source -> fifo (latency 1) -> Window3 -> fifo -> Sink with n items (n - 2 sums).

    Depth 3: items 0..2 are pushed in 0..2 and all visible in 3, where the window emits and pops
    item 0; that slot is free for the source in 4, the new item visible in 5: one sum every 2
    cycles, sums in 3 + 2j, popped in 4 + 2j, so 2n - 1 cycles. Depth 4: the fourth item is
    already in flight, so a sum leaves every cycle from 3 on: popped in 4 .. n + 1, n + 2 cycles.
    """
    n = 6
    sim, sink = _window(depth, n)
    stats = sim.run(lambda: len(sink.items) == n - 2, budget_cycles=100, watchdog_cycles=10)
    assert sink.items == [3 * k + 3 for k in range(n - 2)]
    assert stats["cycles"] == {"clk": cycles(n)}


def test_window_of_3_on_a_depth_2_fifo_deadlocks_with_every_fifo_and_wait_named():
    """The source pushes in cycles 0 and 1 and is then blocked; nothing moves from cycle 2 on, so
    with a watchdog of W periods (one clock: W steps) the error is raised after the step of
    cycle 1 + W, W periods after the last progress."""
    w = 10
    sim, sink = _window(2)
    with pytest.raises(DeadlockError) as info:
        sim.run(lambda: len(sink.items) == 4, budget_cycles=1000, watchdog_cycles=w)
    err = info.value
    assert isinstance(err, UserError)
    # the line names the full FIFO; every FIFO's and block's state is on the exception
    assert str(err) == (
        f"deadlock at {(1 + w) * P / 1e9:.6f} us (cycles run: clk {w + 2}): "
        "full FIFOs: src_to_win 2/2; "
        f"no FIFO moved and no block was busy for {w * P / 1e9:.6f} us ({w} periods of the "
        "slowest clock): deepen a FIFO or change what a block waits for"
    )
    assert "\n" not in str(err)
    assert err.time_fs == (1 + w) * P
    assert err.cycles == {"clk": w + 2}
    assert err.fifos == {
        "src_to_win": {"occupancy": 2, "depth": 2},
        "win_to_sink": {"occupancy": 0, "depth": 4},
    }
    assert err.blocks == {
        "source": {"status": "blocked", "waiting_on": ("src_to_win", "full")},
        "win": {"status": "starved", "waiting_on": ("src_to_win", "empty")},
        "sink": {"status": "starved", "waiting_on": ("win_to_sink", "empty")},
    }


def _pair(n):
    clk = ClockDomain("clk", 100e6)
    sim = _sim(clk)
    f = sim.add_fifo(Fifo("a_to_b", 2, 8, src=clk, dst=clk))
    sim.add_block(Source("a", clk, f, n))
    sink = sim.add_block(Sink("b", clk, f))
    return sim, sink


def test_a_budget_of_exactly_the_needed_cycles_suffices():
    """Depth 2, latency 1: 5 items need n + 1 = 6 cycles; the stage pipeline of
    test_stage_with_ii_3 with ii = 1 needs ii (n - 1) + lat + 3 = 8."""
    sim, sink = _pair(5)
    assert sim.run(lambda: len(sink.items) == 5, budget_cycles=6)["cycles"] == {"clk": 6}
    sim, _src, _stage, sink = _throttled(5, ii=1)
    assert sim.run(lambda: len(sink.items) == 5, budget_cycles=8)["cycles"] == {"clk": 8}


def test_budget_exceeded_reports_the_same_state():
    """One cycle short: the run stops after cycles 0 .. 4, when the source pushes its last item
    and the sink pops item 3."""
    sim, sink = _pair(5)
    with pytest.raises(BudgetExceeded) as info:
        sim.run(lambda: len(sink.items) == 5, budget_cycles={"clk": 5})
    err = info.value
    assert isinstance(err, UserError)
    assert err.cycles == {"clk": 5} and err.time_fs == 4 * P
    assert str(err) == (
        f"cycle budget exceeded at {4 * P / 1e9:.6f} us (cycles run: clk 5): no FIFO is full; "
        "clk ran its budget of 5 cycles before the until condition "
        "held: raise budget_cycles or check the until condition"
    )
    assert err.fifos == {"a_to_b": {"occupancy": 1, "depth": 2}}
    assert err.blocks == {
        "a": {"status": "busy", "waiting_on": None},
        "b": {"status": "busy", "waiting_on": None},
    }


def test_budget_per_domain_lets_other_domains_run_until_the_limited_one_would_tick():
    fast = ClockDomain("fast", 300e6)
    slow = ClockDomain("slow", 100e6)
    sim = _sim(fast, slow)
    sim.add_block(Counter("f", fast))
    sim.add_block(Counter("s", slow))
    with pytest.raises(BudgetExceeded):
        sim.run(lambda: False, budget_cycles={"slow": 2}, watchdog_cycles=None)
    # slow ticks at 0 and 10 ns and may not tick at 20 ns; fast (period 3,333,333 fs) has ticked
    # at k * 3,333,333 fs for k = 0 .. 6 (the last at 19,999,998 fs, before 20 ns)
    assert sim.cycles == {"fast": 7, "slow": 2}
    assert sim.now_fs == 19_999_998
    with pytest.raises(ConfigError, match="unknown clock domain 'nope'"):
        sim.run(lambda: False, budget_cycles={"nope": 2})
    with pytest.raises(ConfigError, match="budget_cycles must be >= 0"):
        sim.run(lambda: False, budget_cycles=-1)


def test_a_second_run_continues_and_budgets_count_from_its_start():
    clk = ClockDomain("clk", 100e6)
    sim = _sim(clk)
    c = sim.add_block(Counter("c", clk))
    sim.run(lambda: c.count == 5, budget_cycles=5)
    stats = sim.run(lambda: c.count == 10, budget_cycles=5)
    assert stats["cycles"] == {"clk": 10} and stats["end_time_fs"] == 9 * P
    assert stats["blocks"] == {"c": {"blocked": 0, "busy": 10, "idle": 0, "starved": 0}}


# ---- order independence and tracing ----------------------------------------------------------


def _busy_chip(trace=None, seed=None):
    """Two domains, a crossing, a stage with backpressure, a stalling sink and a second chain,
    so that many blocks evaluate in the same steps."""
    cam = ClockDomain("cam", 100e6)
    core = ClockDomain("core", 150e6)
    sim = _sim(cam, core, order_seed=seed, trace=trace)
    x = sim.add_fifo(Fifo("cam_to_stage", 3, 8, src=cam, dst=core, sync_cycles=2))
    y = sim.add_fifo(Fifo("stage_to_sink", 2, 8, 2, src=core, dst=core))
    z = sim.add_fifo(Fifo("gen_to_win", 3, 8, src=core, dst=core))
    w = sim.add_fifo(Fifo("win_to_out", 1, 10, src=core, dst=cam, sync_cycles=3))
    sim.add_block(Source("camera", cam, x, 20))
    sim.add_block(Stage("stage", core, x, y, 2, 3, f=lambda v: v + 100))
    sink = sim.add_block(Sink("sink", core, y, stall=lambda c: c % 3 != 0))
    sim.add_block(Source("gen", core, z, 25))
    sim.add_block(Window3("win", core, z, w))
    out = sim.add_block(Sink("out", cam, w, stall=lambda c: c % 4 == 0))
    return sim, sink, out


def test_shuffled_evaluation_orders_give_identical_stats_and_traces():
    results = []
    for seed in (None, 0, 1, 2, 3, 4):
        trace = []
        sim, sink, out = _busy_chip(lambda t, c, ch, trace=trace: trace.append((t, c, ch)), seed)
        stats = sim.run(
            lambda sink=sink, out=out: len(sink.items) == 20 and len(out.items) == 23,
            budget_cycles=10_000,
            watchdog_cycles=50,
        )
        assert sink.items == [k + 100 for k in range(20)]
        assert out.items == [3 * k + 3 for k in range(23)]
        results.append((stats, trace, sink.items, out.items))
    assert all(r == results[0] for r in results[1:])
    stats = results[0][0]
    assert stats["blocks"]["camera"]["blocked"] > 0 and stats["blocks"]["stage"]["blocked"] > 0
    assert len(results[0][1]) == stats["steps"]


@pytest.mark.parametrize(
    "domains",
    [
        [(0, 7, 30), (0, 5, 40)],
        [(3, 6, 25), (1, 4, 40), (0, 9, 20)],
        [(0, 2173913, 900), (0, 2150538, 910), (0, 13468013, 150)],
        [(2, 4, 10), (0, 4, 10)],  # never coincide
        [(0, 6, 0), (5, 5, 7)],
    ],
)
def test_count_instants_equals_the_union_of_the_edges(domains):
    brute = {ph + k * per for ph, per, n in domains for k in range(n)}
    assert count_instants(domains) == len(brute)


def test_count_instants_equals_the_steps_the_kernel_runs():
    sim, sink, out = _busy_chip()
    stats = sim.run(lambda: len(sink.items) == 20 and len(out.items) == 23,
                    budget_cycles=10_000, watchdog_cycles=50)
    doms = [(0, ClockDomain("cam", 100e6).period_fs, stats["cycles"]["cam"]),
            (0, ClockDomain("core", 150e6).period_fs, stats["cycles"]["core"])]
    assert count_instants(doms) == stats["steps"]


def test_watchdog_counts_periods_of_the_slowest_clock():
    """A 100 MHz source fills a depth-2 FIFO to a 150 MHz window of 3 that can never fire: the
    last progress is the push in source cycle 1 (t = 10 ns); the watchdog of W periods of the
    slowest clock (10 ns) fires at the first edge at or after 10 ns + W * 10 ns."""
    w = 12
    slow = ClockDomain("slow", 100e6)
    fast = ClockDomain("fast", 150e6)
    sim = _sim(slow, fast)
    a = sim.add_fifo(Fifo("src_to_win", 2, 8, src=slow, dst=fast, sync_cycles=2))
    b = sim.add_fifo(Fifo("win_to_sink", 4, 10, src=fast, dst=fast))
    sim.add_block(Source("source", slow, a, 10))
    sim.add_block(Window3("win", fast, a, b))
    sink = sim.add_block(Sink("sink", fast, b))
    with pytest.raises(DeadlockError) as info:
        sim.run(lambda: len(sink.items) == 4, budget_cycles=10_000, watchdog_cycles=w)
    p_slow = slow.period_fs
    t_last = p_slow  # the source's second push
    deadline = t_last + w * p_slow
    assert info.value.time_fs == deadline  # an edge of both clocks (3 fast per 2 slow periods)
    assert f"busy for {w * p_slow / 1e9:.6f} us ({w} periods of the slowest clock)" in \
        str(info.value)


def test_shuffling_does_change_the_order_a_combinational_path_would_see():
    """Control: two blocks that talk through a plain attribute (a combinational path the kernel
    forbids) see different values under different seeds -- so the shuffle is real."""

    class Shared:
        value = 0

    class Writer(Block):
        def evaluate(self, now_cycle):
            Shared.value = now_cycle + 1
            self.busy()

    class Reader(Block):
        def __init__(self, name, domain):
            super().__init__(name, domain)
            self.seen = []

        def evaluate(self, now_cycle):
            self.seen.append(Shared.value - now_cycle)
            self.busy()

    clk = ClockDomain("clk", 100e6)
    seen = set()
    for seed in range(6):
        Shared.value = 0
        sim = _sim(clk, order_seed=seed)
        sim.add_block(Writer("w", clk))
        r = sim.add_block(Reader("r", clk))
        sim.run(lambda sim=sim: sim.steps == 30, budget_cycles=30)
        seen.add(tuple(r.seen))
    assert len(seen) > 1


def test_trace_reports_every_signal_first_then_only_changes():
    clk = ClockDomain("clk", 100e6)
    calls = []
    sim = _sim(clk, trace=lambda t, c, ch: calls.append((t, c, ch)))
    f = sim.add_fifo(Fifo("a_to_b", 1, 8, src=clk, dst=clk))
    sim.add_block(Source("a", clk, f, 2))
    sink = sim.add_block(Sink("b", clk, f))
    sim.run(lambda: len(sink.items) == 2, budget_cycles=10)
    assert calls == [
        (0, {"clk": 0}, {"a.sent": 1, "a_to_b.occupancy": 1, "b.received": 0}),
        (P, {"clk": 1}, {"a_to_b.occupancy": 0, "b.received": 1}),
        (2 * P, {"clk": 2}, {"a.sent": 2, "a_to_b.occupancy": 1}),
        (3 * P, {"clk": 3}, {"a_to_b.occupancy": 0, "b.received": 2}),
    ]
    assert sim.signals() == [("a.sent", 16), ("b.received", 16), ("a_to_b.occupancy", 1)]
    assert sim.signal_values() == {"a.sent": 2, "b.received": 2, "a_to_b.occupancy": 0}


# ---- rules enforced --------------------------------------------------------------------------


def test_activity_must_be_reported_exactly_once():
    class Silent(Block):
        def evaluate(self, now_cycle):
            pass

    class Chatty(Block):
        def evaluate(self, now_cycle):
            self.busy()
            self.idle()

    clk = ClockDomain("clk", 100e6)
    for cls, words in ((Silent, "reported no activity in cycle 0"), (Chatty, "both busy and idle")):
        sim = _sim(clk)
        sim.add_block(cls("x", clk))
        with pytest.raises(KernelError, match=words):
            sim.step()


def test_wiring_errors():
    clk = ClockDomain("clk", 100e6)
    sim = _sim(clk)
    with pytest.raises(ConfigError, match="already added"):
        sim.add_domain(ClockDomain("clk", 200e6))
    other = ClockDomain("other", 100e6)
    with pytest.raises(ConfigError, match="clock domain 'other', which is not added"):
        sim.add_block(Counter("c", other))
    sim.add_block(Counter("c", clk))
    with pytest.raises(ConfigError, match="name 'c' is already used"):
        sim.add_fifo(Fifo("c", 1, 1, src=clk, dst=clk))
    with pytest.raises(ConfigError, match="no clock domain"):
        Simulator().step()
    sim.step()
    with pytest.raises(KernelError, match="after the simulation has started"):
        sim.add_block(Counter("d", clk))
    with pytest.raises(ConfigError, match="watchdog_cycles must be >= 1"):
        sim.run(lambda: False, budget_cycles=1, watchdog_cycles=0)
