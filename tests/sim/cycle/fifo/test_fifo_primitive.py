"""The FIFO primitive (sim/cycle/fifo/rule.py): its cycle forms (the compiled engine, the
estimate) and its instant forms (the readable FIFO) are one rule, and the room rule read back
is its inverse."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from stereosim.core.kernel_cache import njit
from stereosim.sim.cycle.fifo.rule import (
    fifo_edges,
    room_at,
    room_from,
    room_seen_until,
    round_trip_fs,
    seen_from,
    visible_at,
    visible_from,
    visible_until,
)
from stereosim.sim.cycle.rules import ClockDomain

PERIODS = st.sampled_from([1_000_000, 2_150_538, 2_173_913, 3_000_000, 13_468_013])


@given(c=st.integers(0, 10**7), p_src=PERIODS, p_dst=PERIODS, lat=st.integers(1, 3),
       sync=st.integers(1, 4))
@settings(max_examples=400, deadline=None)
def test_the_cycle_and_instant_forms_are_one_rule(c, p_src, p_dst, lat, sync):
    crossing = p_src != p_dst
    de, se = fifo_edges(lat, sync, crossing)
    push_fs = c * p_src  # every clock of the chip starts at t = 0
    v = visible_from(c, p_src, p_dst, p_src / p_dst, de)
    # the readable FIFO's form, on the domain objects it holds
    dst, src = ClockDomain("dst", 1e15 / p_dst), ClockDomain("src", 1e15 / p_src)
    assert (dst.period_fs, src.period_fs) == (p_dst, p_src)
    assert v == visible_at(push_fs, dst, de) == seen_from(c, p_src, p_dst, de)
    r = room_from(c, p_src, p_dst, p_dst / p_src, se)
    assert r == room_at(c * p_dst, src, se) == seen_from(c, p_dst, p_src, se)


@given(c=st.integers(0, 10**6), p_src=PERIODS, p_dst=PERIODS, edges=st.integers(1, 5))
@settings(max_examples=300, deadline=None)
def test_the_rules_read_back_give_the_last_event_they_let_through(c, p_src, p_dst, edges):
    """room_seen_until: the last pop whose free slot the producer sees in its cycle c;
    visible_until: the last push the consumer can pop in its cycle c."""
    for forward, back, rat in ((room_from, room_seen_until, p_dst / p_src),
                               (visible_from, visible_until, p_src / p_dst)):
        last = back(c, p_src, p_dst, edges)
        assert last == -1 or forward(last, p_src, p_dst, rat, edges) <= c
        assert forward(last + 1, p_src, p_dst, rat, edges) > c


def test_one_domain_is_whole_cycles():
    assert fifo_edges(1, 2, False) == (1, 1)
    assert fifo_edges(2, 3, True) == (4, 3)
    assert visible_from(7, 5, 5, 1.0, 1) == 8
    assert room_from(7, 5, 5, 1.0, 1) == 8
    assert room_seen_until(8, 5, 5, 1) == 7
    assert visible_until(8, 5, 5, 2) == 6
    assert round_trip_fs(1, 1, 5, 5, False) == 10
    assert round_trip_fs(2, 2, 4, 6, True) == 1.5 * 6 + 1.5 * 4


@njit(cache=False)
def _compiled(c, p_src, p_dst, de, se):
    return (visible_from(c, p_src, p_dst, p_src / p_dst, de),
            room_from(c, p_src, p_dst, p_dst / p_src, se),
            room_seen_until(c, p_src, p_dst, se))


def test_the_compiled_engine_inlines_the_same_rule():
    rng = np.random.default_rng(1)
    for _ in range(200):
        c = int(rng.integers(0, 10**8))
        p_src, p_dst = (int(p) for p in rng.choice([1_000_000, 2_173_913, 3_000_000], 2))
        de, se = (int(v) for v in rng.integers(1, 4, 2))
        assert _compiled(c, p_src, p_dst, de, se) == (
            visible_from(c, p_src, p_dst, p_src / p_dst, de),
            room_from(c, p_src, p_dst, p_dst / p_src, se),
            room_seen_until(c, p_src, p_dst, se))
