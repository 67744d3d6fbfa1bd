"""The FIFO rule, written once: when an item pushed is visible to the consumer, and when the
slot a pop frees is seen by the producer -- push k waits until pop k - depth is seen.

Every cycle engine and the estimate call these: the compiled walkers and the estimate's link
walk on cycles (:func:`visible_from`, :func:`room_from`, and read back :func:`visible_until`,
:func:`room_seen_until`), the readable :class:`~sim.cycle.fifo.readable.Fifo` on the instants
of its commits (:func:`visible_at`, :func:`room_at`; the same rule where every clock starts at
t = 0: ``tests/sim/cycle/fifo/test_fifo_primitive.py`` holds them equal), the plan on the
number of edges (:func:`fifo_edges`). ``register_jitable``
keeps each a plain Python function and lets numba inline it into the compiled kernels.
:func:`seen_from` is the clock crossing under it (also how a camera's pixel reaches a source).
"""

from __future__ import annotations

from numba.extending import register_jitable


def fifo_edges(latency_cycles: int, sync_cycles: int, crossing: bool) -> tuple[int, int]:
    """(data_edges, space_edges) of a FIFO: an item pushed at a producer edge can be popped from
    the ``data_edges``-th consumer edge after it (latency, plus the synchroniser less one when
    the FIFO crosses domains); a slot freed at a consumer edge is seen by the producer from its
    ``space_edges``-th edge after it (the next one, or the synchroniser's depth across
    domains)."""
    if crossing:
        return latency_cycles + sync_cycles - 1, sync_cycles
    return latency_cycles, 1


@register_jitable
def seen_from(cycle, period_from, period_to, edges):
    """The cycle of the receiving domain from which an event of ``cycle`` of the sending domain
    counts there: the ``edges``-th receiving edge strictly after the instant ``cycle *
    period_from`` (one domain: ``cycle + edges``). A push is visible to the consumer from
    ``seen_from(push, P_src, P_dst, data_edges)``; a pop's free slot is seen by the producer from
    ``seen_from(pop, P_dst, P_src, space_edges)``."""
    if period_from == period_to:
        return cycle + edges
    return (cycle * period_from) // period_to + edges


@register_jitable
def seen_from_scaled(cycle, period_from, period_to, ratio, edges):
    """:func:`seen_from` without a division: ``ratio`` = period_from / period_to (float), the
    quotient estimated and then corrected, exactly (the products fit an int64)."""
    if period_from == period_to:
        return cycle + edges
    x = cycle * period_from
    q = int(cycle * ratio)
    while q * period_to > x:
        q -= 1
    while (q + 1) * period_to <= x:
        q += 1
    return q + edges


@register_jitable
def visible_from(push, per_src, per_dst, ratio, data_edges):
    """The visibility rule: the consumer cycle from which the item pushed in producer cycle
    ``push`` can be popped (``ratio`` = per_src / per_dst; one domain: push + data_edges)."""
    return seen_from_scaled(push, per_src, per_dst, ratio, data_edges)


@register_jitable
def room_from(pop, per_src, per_dst, ratio, space_edges):
    """The room rule: the producer cycle from which the slot freed by the pop in consumer cycle
    ``pop`` counts as free -- push k may go from ``room_from(pop k - depth)`` on (``ratio`` =
    per_dst / per_src; one domain: pop + 1)."""
    return seen_from_scaled(pop, per_dst, per_src, ratio, space_edges)


@register_jitable
def seen_until(cycle, period_from, period_to, edges):
    """:func:`seen_from` read back: the last cycle of the sending domain whose event counts in
    the receiving domain's ``cycle`` (the largest p with ``seen_from(p) <= cycle``; -1:
    none)."""
    if period_from == period_to:
        return max(cycle - edges, -1)
    x = (cycle - edges + 1) * period_to
    return (x - 1) // period_from if x > 0 else -1


@register_jitable
def visible_until(cycle, per_src, per_dst, data_edges):
    """The visibility rule read back: the last producer cycle whose push the consumer can pop
    in its ``cycle`` (the largest p with ``visible_from(p) <= cycle``; -1: none)."""
    return seen_until(cycle, per_src, per_dst, data_edges)


@register_jitable
def room_seen_until(cycle, per_src, per_dst, space_edges):
    """The room rule read back: the last consumer cycle whose pop's free slot the producer sees
    in its ``cycle`` (the largest p with ``room_from(p) <= cycle``; -1: none)."""
    return seen_until(cycle, per_dst, per_src, space_edges)


def visible_at(push_fs: int, dst, data_edges: int) -> int:
    """:func:`visible_from` for a push committed at the instant ``push_fs`` (the readable FIFO):
    the ``data_edges``-th edge of the consumer's clock ``dst`` (its ``first_edge_after``)
    strictly after it."""
    return dst.first_edge_after(push_fs) + data_edges - 1


def room_at(pop_fs: int, src, space_edges: int) -> int:
    """:func:`room_from` for a pop committed at the instant ``pop_fs`` (the readable FIFO): the
    ``space_edges``-th edge of the producer's clock ``src`` strictly after it."""
    return src.first_edge_after(pop_fs) + space_edges - 1


def round_trip_fs(data_edges: int, space_edges: int, p_src: int, p_dst: int,
                  crossing: bool) -> float:
    """The mean time from a push to the next push its freed slot allows when the consumer pops
    at once: visible after ``data_edges`` consumer edges, seen free ``space_edges`` producer
    edges after the pop (across domains an event waits half a period on average for the first
    edge: ``(data_edges - 0.5) P_dst + (space_edges - 0.5) P_src``; one domain: whole
    cycles)."""
    if not crossing:
        return (data_edges + space_edges) * p_src
    return (data_edges - 0.5) * p_dst + (space_edges - 0.5) * p_src


def room_seen_within(data_edges: int, space_edges: int, p_src: int, p_dst: int) -> int:
    """At most how many producer cycles after a push the slot its immediate pop frees is seen
    (``floor(data_edges P_dst / P_src) + space_edges``: the estimate's shortcut)."""
    return data_edges * p_dst // p_src + space_edges
