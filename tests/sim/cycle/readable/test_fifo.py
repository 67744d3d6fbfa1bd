"""The clocked FIFO: throughput and latency in exact cycles, domain crossings in exact
femtoseconds, statistics, and a check against a naive event-by-event model of the same rules."""

import bisect

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stereosim.core.errors import ConfigError
from stereosim.sim.cycle.fifo.readable import Fifo, KernelError
from stereosim.sim.cycle.readable.clock import Block
from stereosim.sim.cycle.readable.kernel import Simulator
from stereosim.sim.cycle.rules import ClockDomain


def _domain(name, period_fs, phase_fs=0):
    """A domain with an exact integer period (round(1e15 / (1e15 / p)) == p)."""
    dom = ClockDomain(name, 1e15 / period_fs, phase_fs)
    assert dom.period_fs == period_fs
    return dom


class Producer(Block):
    """Pushes 0, 1, ..., n-1, one per cycle whenever ``can_push()`` and ``stall(cycle)`` is false.
    Busy in a push cycle, blocked when it has an item and the FIFO is full, idle otherwise.
    Records the instant of each push."""

    def __init__(self, name, domain, out, n, stall=None):
        super().__init__(name, domain)
        self.out = out
        self.n = n
        self.stall = stall
        self.sent = 0  # items pushed (committed)
        self.push_fs = []
        self._staged = None

    def evaluate(self, now_cycle):
        k = self.sent
        if k >= self.n or (self.stall is not None and self.stall(now_cycle)):
            self.idle()
        elif self.out.can_push():
            self.out.push(k)
            self._staged = self.domain.edge_fs(now_cycle)
            self.busy()
        else:
            self.blocked(self.out)

    def commit(self):
        if self._staged is not None:
            self.sent += 1
            self.push_fs.append(self._staged)
            self._staged = None


class Consumer(Block):
    """Pops one visible item per cycle unless ``stall(cycle)``. Busy in a pop cycle, idle when
    stalled, starved when nothing is visible. Records items and the instant of each pop."""

    def __init__(self, name, domain, inp, stall=None):
        super().__init__(name, domain)
        self.inp = inp
        self.stall = stall
        self.items = []
        self.pop_fs = []
        self.pop_cycles = []
        self._staged = None

    def evaluate(self, now_cycle):
        if self.stall is not None and self.stall(now_cycle):
            self.idle()
        elif self.inp.can_pop():
            self._staged = (self.inp.pop(), now_cycle)
            self.busy()
        else:
            self.starved(self.inp)

    def commit(self):
        if self._staged is not None:
            item, cycle = self._staged
            self.items.append(item)
            self.pop_cycles.append(cycle)
            self.pop_fs.append(self.domain.edge_fs(cycle))
            self._staged = None


def _chain(n, depth, latency=1, *, src=None, dst=None, sync=2, src_stall=None, dst_stall=None):
    src = src or _domain("clk", 10_000)
    dst = dst or src
    sim = Simulator()
    sim.add_domain(src)
    if dst != src:
        sim.add_domain(dst)
    fifo = sim.add_fifo(Fifo("p_to_c", depth, 8, latency, src=src, dst=dst, sync_cycles=sync))
    prod = sim.add_block(Producer("producer", src, fifo, n, src_stall))
    cons = sim.add_block(Consumer("consumer", dst, fifo, dst_stall))
    return sim, fifo, prod, cons


def _run(sim, cons, n, budget=100_000):
    return sim.run(lambda: len(cons.items) == n, budget_cycles=budget, watchdog_cycles=500)


# ---- one domain: exact cycles ----------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 2, 7])
def test_depth_2_latency_1_moves_n_items_in_n_plus_1_cycles(n):
    """Push in cycles 0..n-1, pop in cycles 1..n: n + 1 cycles, no stall. The physical occupancy
    never exceeds 1, but the producer needs the second slot: the pop of cycle c frees the slot
    only for cycle c + 1."""
    sim, _fifo, _prod, cons = _chain(n, depth=2)
    stats = _run(sim, cons, n)
    assert stats["cycles"] == {"clk": n + 1}
    assert cons.items == list(range(n))
    assert cons.pop_cycles == list(range(1, n + 1))
    assert stats["blocks"]["producer"] == {"blocked": 0, "busy": n, "idle": 1, "starved": 0}
    assert stats["blocks"]["consumer"] == {"blocked": 0, "busy": n, "idle": 0, "starved": 1}
    assert stats["fifos"]["p_to_c"] == {
        "bits_transferred": 8 * n,
        "cycles_empty": 1,  # cycle 0
        "cycles_full": 0,
        "depth": 2,
        "max_occupancy": 1,
        "max_producer_occupancy": 1 if n == 1 else 2,
        "occupancy_histogram": [1, n, 0],  # sampled at consumer edges 0..n
        "pops": n,
        "pushes": n,
        "width_bits": 8,
    }


@pytest.mark.parametrize("n", [1, 2, 7])
def test_depth_1_moves_one_item_every_two_cycles(n):
    """Push in cycles 0, 2, ..., 2(n-1); pop in 1, 3, ..., 2n-1: 2n cycles. The producer is
    blocked in the n - 1 odd cycles before its last push; the consumer starves in the n even
    cycles."""
    sim, _fifo, _prod, cons = _chain(n, depth=1)
    stats = _run(sim, cons, n)
    assert stats["cycles"] == {"clk": 2 * n}
    assert cons.pop_cycles == [2 * k + 1 for k in range(n)]
    assert stats["blocks"]["producer"] == {"blocked": n - 1, "busy": n, "idle": 1, "starved": 0}
    assert stats["blocks"]["consumer"]["starved"] == n
    # the producer sees it full in the odd cycles 1 .. 2n - 1
    assert stats["fifos"]["p_to_c"]["cycles_full"] == n
    assert stats["fifos"]["p_to_c"]["occupancy_histogram"] == [n, n]


def _push_cycle(k, depth, latency):
    """Cycle of the k-th push with an always-ready consumer: a slot serves one item per
    latency + 1 cycles (push c, pop c + L, free for the producer at c + L + 1), so with
    depth <= L + 1 items go in groups of ``depth`` every L + 1 cycles; deeper FIFOs never stall."""
    if depth >= latency + 1:
        return k
    return (k // depth) * (latency + 1) + k % depth


@pytest.mark.parametrize("depth", [1, 2, 3, 4, 6])
@pytest.mark.parametrize("latency", [1, 2, 3, 5])
def test_depth_latency_sweep_matches_the_slot_round_trip_formula(depth, latency):
    n = 11
    sim, _fifo, prod, cons = _chain(n, depth, latency)
    stats = _run(sim, cons, n)
    pushes = [_push_cycle(k, depth, latency) for k in range(n)]
    assert [t // 10_000 for t in prod.push_fs] == pushes
    assert cons.pop_cycles == [c + latency for c in pushes]
    assert stats["cycles"]["clk"] == pushes[-1] + latency + 1
    assert stats["fifos"]["p_to_c"]["max_producer_occupancy"] == min(depth, latency + 1)


@pytest.mark.parametrize("n", [2, 3, 8])
def test_consumer_stalling_every_other_cycle(n):
    """Depth 2, latency 1, consumer stalls in odd cycles. It pops item k in cycle 2 + 2k, so the
    run takes 2n + 1 cycles. Item k >= 2 needs the slot of item k - 2 (popped in 2k - 2, free for
    the producer in 2k - 1): pushes in 0, 1, 3, 5, ..., 2n - 3; the producer is blocked in the
    even cycles 2, 4, ..., 2n - 4 (n - 2 cycles)."""
    sim, _fifo, prod, cons = _chain(n, depth=2, dst_stall=lambda c: c % 2 == 1)
    stats = _run(sim, cons, n)
    assert stats["cycles"] == {"clk": 2 * n + 1}
    assert cons.pop_cycles == [2 + 2 * k for k in range(n)]
    assert [t // 10_000 for t in prod.push_fs] == [0, 1] + [2 * k - 1 for k in range(2, n)]
    assert stats["blocks"]["producer"]["blocked"] == n - 2
    assert stats["blocks"]["consumer"] == {"blocked": 0, "busy": n, "idle": n, "starved": 1}


def test_visible_count_and_peek_follow_the_latency():
    """Latency 3: items pushed in 0, 1, 2 become visible in 3, 4, 5 (peeked in place)."""
    clk = _domain("clk", 10_000)
    sim = Simulator()
    sim.add_domain(clk)
    fifo = sim.add_fifo(Fifo("f", 4, 8, 3, src=clk, dst=clk))
    seen = []

    class Look(Block):
        def evaluate(self, now_cycle):
            n = fifo.visible_count()
            seen.append((n, [fifo.peek(i) for i in range(n)]))
            if now_cycle < 3:
                fifo.push(now_cycle)
            self.busy()

    sim.add_block(Look("look", clk))
    for _ in range(6):
        sim.step()
    assert seen == [(0, []), (0, []), (0, []), (1, [0]), (2, [0, 1]), (3, [0, 1, 2])]


# ---- two domains: exact femtoseconds ---------------------------------------------------------


def _arrival_fs(push_fs, dst, latency, sync):
    """Hand formula: the item is visible from the (latency + sync - 1)-th consumer edge strictly
    after the push instant."""
    first = 0 if push_fs < dst.phase_fs else (push_fs - dst.phase_fs) // dst.period_fs + 1
    return dst.phase_fs + (first + latency + sync - 2) * dst.period_fs


def test_crossing_100_to_150_mhz_first_item_arrives_at_the_second_consumer_edge():
    """Pushed at t = 0 by the 100 MHz producer. 150 MHz edges strictly after 0: 6,666,667 fs (1st)
    and 13,333,334 fs (2nd): with sync_cycles 2 the consumer pops it at 13,333,334 fs."""
    src = ClockDomain("cam", 100e6)
    dst = ClockDomain("nna", 150e6)
    assert (src.period_fs, dst.period_fs) == (10_000_000, 6_666_667)
    sim, _fifo, _prod, cons = _chain(1, 4, src=src, dst=dst, sync=2)
    _run(sim, cons, 1)
    assert cons.pop_fs == [13_333_334] == [_arrival_fs(0, dst, 1, 2)]
    assert sim.now_fs == 13_333_334


def test_crossing_150_to_100_mhz_and_with_phases():
    src = ClockDomain("fast", 150e6)
    dst = ClockDomain("slow", 100e6)
    sim, _fifo, _prod, cons = _chain(1, 4, src=src, dst=dst, sync=2)
    _run(sim, cons, 1)
    assert cons.pop_fs == [20_000_000]  # 100 MHz edges after 0: 10 ns, 20 ns
    # the consumer's phase puts an edge 1 fs after the push: it counts as the first
    src = ClockDomain("a", 100e6, phase_fs=5_000_000)
    dst = ClockDomain("b", 100e6, phase_fs=5_000_001)
    sim, _fifo, _prod, cons = _chain(1, 4, src=src, dst=dst, sync=3)
    _run(sim, cons, 1)
    assert cons.pop_fs == [5_000_001 + 2 * 10_000_000] == [_arrival_fs(5_000_000, dst, 1, 3)]


def test_crossing_with_simultaneous_edges_does_not_count_the_tied_edge():
    """3:2 periods (3 ns producer, 2 ns consumer): the push at t = 0 ties with a consumer edge,
    which is not strictly after it; edges 2 ns and 4 ns are the 1st and 2nd."""
    src = _domain("p", 3_000_000)
    dst = _domain("c", 2_000_000)
    sim, _fifo, prod, cons = _chain(3, 8, src=src, dst=dst, sync=2)
    _run(sim, cons, 3)
    # pushes at 0, 3, 6 ns; the 2nd consumer edge strictly after each: 4, 6, 10 ns
    assert prod.push_fs == [0, 3_000_000, 6_000_000]
    assert cons.pop_fs == [_arrival_fs(t, dst, 1, 2) for t in prod.push_fs]
    assert cons.pop_fs == [4_000_000, 6_000_000, 10_000_000]


def test_crossing_depth_1_round_trip_in_femtoseconds():
    """Depth 1, 100 MHz -> 150 MHz, sync 2. Item k is pushed at P_k (producer edge), popped at
    A_k = 2nd consumer edge after P_k, and the slot is seen free at the 2nd producer edge after
    A_k, which is P_{k+1}. By hand: P_0 = 0, A_0 = 13,333,334; producer edges after A_0: 20 ns,
    30 ns -> P_1 = 30 ns; consumer edges after 30 ns: 33,333,335 and 40,000,002 -> A_1 =
    40,000,002; producer edges after it: 50, 60 ns -> P_2 = 60 ns; consumer edges after 60 ns:
    60,000,003 and 66,666,670 -> A_2 = 66,666,670."""
    src = ClockDomain("a", 100e6)
    dst = ClockDomain("b", 150e6)
    sim, _fifo, prod, cons = _chain(3, 1, src=src, dst=dst, sync=2)
    stats = _run(sim, cons, 3)
    assert prod.push_fs == [0, 30_000_000, 60_000_000]
    assert cons.pop_fs == [13_333_334, 40_000_002, 66_666_670]
    assert stats["end_time_fs"] == 66_666_670
    assert stats["cycles"] == {"a": 7, "b": 11}  # edges up to 66,666,670 fs: 0..60 ns; 0..10
    # the producer sees it full (and is blocked) at 10, 20 ns and at 40, 50 ns
    assert stats["fifos"]["p_to_c"]["cycles_full"] == 4
    assert stats["blocks"]["producer"] == {"blocked": 4, "busy": 3, "idle": 0, "starved": 0}


def test_crossing_fast_producer_is_throttled_to_the_consumer_rate():
    """150 MHz into 100 MHz, depth 8: the consumer pops one item per 10 ns edge from the first
    arrival (20 ns) on, so item k is popped at (k + 2) * 10 ns and the producer blocks."""
    src = ClockDomain("fast", 150e6)
    dst = ClockDomain("slow", 100e6)
    n = 30
    sim, _fifo, _prod, cons = _chain(n, 8, src=src, dst=dst, sync=2)
    stats = _run(sim, cons, n)
    assert cons.pop_fs == [(k + 2) * 10_000_000 for k in range(n)]
    assert stats["blocks"]["producer"]["blocked"] > 0
    assert stats["fifos"]["p_to_c"]["max_producer_occupancy"] == 8


# ---- against a naive model -------------------------------------------------------------------


def _naive(src, dst, depth, latency, sync, n, src_stall, dst_stall):
    """Event-by-event model of the documented rules with instants instead of cycle indices.

    At each instant the producer and consumer act on what was decided before it; an item pushed
    at t becomes visible at the time of the (L + S - 1)-th consumer edge strictly after t
    (L in one domain), a slot popped at t is seen free at the S-th producer edge strictly after
    t (the 1st in one domain). Edges are listed by repeated addition.
    """
    crossing = src != dst
    data_n = latency + (sync - 1 if crossing else 0)
    space_m = sync if crossing else 1
    horizon = 40 * (n + 2) * (depth + latency + sync + 5) * max(src.period_fs, dst.period_fs)

    def edges(dom):
        out, t = [], dom.phase_fs
        while t <= horizon:
            out.append(t)
            t += dom.period_fs
        return out

    src_edges, dst_edges = edges(src), edges(dst)
    src_index = {t: k for k, t in enumerate(src_edges)}
    dst_index = {t: k for k, t in enumerate(dst_edges)}

    def nth_after(lst, t, k):
        return lst[bisect.bisect_right(lst, t) + k - 1]

    instants = sorted(set(src_edges) | set(dst_edges))
    push_fs, pop_fs, visible_fs, free_fs = [], [], [], []
    for t in instants:
        if len(pop_fs) == n:
            break
        push_now = pop_now = False
        if t in src_index:
            seen = len(push_fs) - sum(1 for f in free_fs if f <= t)
            stalled = src_stall is not None and src_stall(src_index[t])
            push_now = len(push_fs) < n and not stalled and seen < depth
        if t in dst_index:
            head = len(pop_fs)
            stalled = dst_stall is not None and dst_stall(dst_index[t])
            pop_now = head < len(push_fs) and visible_fs[head] <= t and not stalled
        if push_now:
            push_fs.append(t)
            visible_fs.append(nth_after(dst_edges, t, data_n))
        if pop_now:
            pop_fs.append(t)
            free_fs.append(nth_after(src_edges, t, space_m))
    assert len(pop_fs) == n, "horizon too short"
    return push_fs, pop_fs


_pattern = st.lists(st.booleans(), min_size=1, max_size=7)


@settings(max_examples=120, deadline=None)
@given(
    crossing=st.booleans(),
    src_period=st.integers(2, 9),
    dst_period=st.integers(2, 9),
    src_phase=st.integers(0, 9),
    dst_phase=st.integers(0, 9),
    depth=st.integers(1, 5),
    latency=st.integers(1, 4),
    sync=st.integers(1, 3),
    n=st.integers(1, 15),
    src_pat=_pattern,
    dst_pat=_pattern,
)
def test_fifo_matches_the_naive_model_and_keeps_order_and_depth(
    crossing, src_period, dst_period, src_phase, dst_phase, depth, latency, sync, n,
    src_pat, dst_pat,
):  # fmt: skip
    src = _domain("src", src_period, src_phase)
    dst = _domain("dst", dst_period, dst_phase) if crossing else src

    def src_stall(c):
        return src_pat[c % len(src_pat)] and c % 5 != 0  # never stalls forever

    def dst_stall(c):
        return dst_pat[c % len(dst_pat)] and c % 5 != 0

    sim, _fifo, prod, cons = _chain(
        n, depth, latency, src=src, dst=dst, sync=sync, src_stall=src_stall, dst_stall=dst_stall
    )
    stats = _run(sim, cons, n)
    assert cons.items == list(range(n))
    assert (prod.push_fs, cons.pop_fs) == _naive(
        src, dst, depth, latency, sync, n, src_stall, dst_stall
    )
    fs = stats["fifos"]["p_to_c"]
    assert fs["pushes"] == fs["pops"] == n
    assert fs["max_occupancy"] <= fs["max_producer_occupancy"] <= depth
    assert sum(fs["occupancy_histogram"]) == stats["cycles"][dst.name]
    assert len(fs["occupancy_histogram"]) == depth + 1


# ---- configuration and protocol errors -------------------------------------------------------


def test_bad_parameters_raise_config_errors_with_a_fix():
    clk = ClockDomain("clk", 1e9)
    with pytest.raises(ConfigError, match=r"fifo 'x': depth must be >= 1; got 0 .*depth=1"):
        Fifo("x", 0, 8, src=clk, dst=clk)
    with pytest.raises(ConfigError, match="width_bits"):
        Fifo("x", 2, 0, src=clk, dst=clk)
    with pytest.raises(ConfigError, match="latency_cycles must be >= 1.*combinational"):
        Fifo("x", 2, 8, 0, src=clk, dst=clk)
    with pytest.raises(ConfigError, match="sync_cycles"):
        Fifo("x", 2, 8, src=clk, dst=ClockDomain("b", 1e8), sync_cycles=0)
    with pytest.raises(ConfigError, match="depth must be an integer"):
        Fifo("x", 2.0, 8, src=clk, dst=clk)
    with pytest.raises(ConfigError, match="dst must be a ClockDomain"):
        Fifo("x", 2, 8, src=clk, dst="clk")
    sim = Simulator()
    with pytest.raises(ConfigError, match="not added to this simulator"):
        sim.add_fifo(Fifo("x", 2, 8, src=clk, dst=clk))


class _Rude(Block):
    """Does whatever ``action(self, cycle)`` says, then reports busy."""

    def __init__(self, name, domain, action):
        super().__init__(name, domain)
        self.action = action

    def evaluate(self, now_cycle):
        self.action(self, now_cycle)
        self.busy()


def _one(fifo_depth, action, *, other_domain=False):
    sim = Simulator()
    clk = sim.add_domain(ClockDomain("clk", 1e9))
    other = sim.add_domain(ClockDomain("other", 0.7e9)) if other_domain else clk
    fifo = sim.add_fifo(Fifo("f", fifo_depth, 8, src=clk, dst=clk))
    sim.add_block(_Rude("rude", other, lambda b, c: action(fifo, c)))
    return sim


@pytest.mark.parametrize(
    "action, words",
    [
        (lambda f, c: (f.push(1), f.push(2)), "pushed twice"),
        (lambda f, c: f.push(c), "pushed while full"),
        (lambda f, c: f.pop(), "popped with no visible item"),
        (lambda f, c: f.peek(), "no visible item 0"),
    ],
)
def test_protocol_violations_raise_kernel_errors(action, words):
    sim = _one(1, action)
    with pytest.raises(KernelError, match=words):
        for _ in range(4):
            sim.step()


def test_pushing_outside_the_producer_domain_is_caught():
    sim = _one(4, lambda f, c: f.push(c), other_domain=True)
    with pytest.raises(KernelError, match="outside an edge of its producer domain 'clk'"):
        for _ in range(4):
            sim.step()


def test_two_pops_in_one_cycle_and_peek_after_pop_are_caught():
    def twice(f, c):
        if f.can_pop():
            f.pop()
            f.pop()
        elif f.can_push():
            f.push(c)

    def peek_after(f, c):
        if f.can_pop():
            f.pop()
            f.peek()
        elif f.can_push():
            f.push(c)

    for action, words in ((twice, "popped twice"), (peek_after, "peeked after a pop")):
        sim = _one(2, action)
        with pytest.raises(KernelError, match=words):
            for _ in range(4):
                sim.step()
