"""The disparity sink on the compiled engine, with the DRAM channel's write-back (twin of the
readable kernel's :class:`~sim.cycle.readable.blocks.sources.Sink` and the write side of
:class:`~sim.cycle.readable.blocks.sources.DramChannel`, in
:mod:`sim.cycle.readable.blocks.sources`; the rules are :mod:`sim.cycle.rules`).

Stream ``SINK_POP``: the sink pops word j in the first cycle its stall pattern allows
(:func:`~sim.cycle.rules.sink_next_allowed`) at or after ``max(q[j-1] + 1, vis(o[j]))`` -- and,
writing back through the DRAM channel, once the write buffer has room: the burst a write buffer
back has left (``DRAM_WRITE``, the first sink cycle write-back burst u has left the buffer, a
full burst being written in the next write slot). Its statistics are taken on the way (busy at
each pop, blocked while the write buffer is full, the FIFO's empty cycles), and what it reports
at an instant is read off the same events.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from stereosim.core.kernel_cache import njit
from stereosim.sim.cycle.compiled.fifo import visible_by
from stereosim.sim.cycle.compiled.layout import (
    A_BLOCKED,
    A_BUSY,
    A_IDLE,
    A_STARVED,
)
from stereosim.sim.cycle.compiled.ring import (
    busy,
    lt_at,
    rd,
    store_activity,
    view,
)
from stereosim.sim.cycle.compiled.source import DRAM
from stereosim.sim.cycle.fifo.rule import visible_from
from stereosim.sim.cycle.rules import (
    burst_of,
    dram_slot,
    dram_write_done_fs,
    first_edge_at,
    sink_allowed_between,
    sink_may_pop,
    sink_next_allowed,
)


class SinkLoop(NamedTuple):
    """The constants of :func:`pops`' loop: the rings of the sink's pops, of the SVA's pushes
    and of the write-back bursts, the FIFO's data edges, the clock period (fs), the sink's
    block, its stall pattern, whether it writes back through the DRAM channel, the cap, a
    frame's columns and words, whether statistics are taken, the watchdog's time (fs) and the
    channel's write side (words a burst, bursts the write buffer holds, slot, round, first
    write slot, write slots a round); with the arrays it writes (taken from the Net once, not
    per turn): the ring, the long gaps, the first frame's rows out, the frames out and the
    run's state."""

    pop_off: int
    pop_mask: int
    push_off: int
    push_mask: int
    write_off: int
    write_mask: int
    data_edges: int
    period: int
    block: int
    allowed: np.ndarray  # the stall pattern (Net.sink)
    dram: int
    cap_fs: int
    w: int
    n: int
    stats: int
    watchdog_fs: int
    d_wwords: int
    d_wbuf: int
    d_slot: int
    d_round: int
    d_wfirst: int
    d_wcount: int
    ring: np.ndarray
    gaps: np.ndarray
    row_fs: np.ndarray
    frame_out: np.ndarray
    state: np.void  # Net.state's record


class SinkCursor(NamedTuple):
    """Where :func:`pops` stands: the pops known, the last pop (cycle), the next pop's column,
    the write-back bursts known, the cycles waited for the write buffer, the FIFO's empty
    cycles, the first pop (-1: not in this pass), the long gaps noted, the last busy instant
    and a ring error."""

    pops: int
    last_pop: int
    x: int
    bursts: int
    dram_wait: int
    empty: int
    first: int
    n_gaps: int
    last_busy_fs: int
    ring_error: bool


@njit(cache=True, inline="always")
def pops_begin(net):
    """What :func:`pops` reads: the constants of its loop and the arrays it writes (a
    :class:`SinkLoop`) and its cursor (a :class:`SinkCursor`)."""
    prm = net.prm[0]
    ids = net.ids[0]
    streams = net.streams
    q_off, q_mask, kq, _ = view(streams, ids.sink_pop)
    o_off, o_mask, _, _ = view(streams, ids.sva_push)
    w_off, w_mask, kw, _ = view(streams, ids.dram_write)
    sq = streams[ids.sink_pop]
    fi = net.fifos[ids.fifo_sink]
    acc = net.acc[sq.block]
    k = SinkLoop(
        pop_off=q_off, pop_mask=q_mask, push_off=o_off, push_mask=o_mask, write_off=w_off,
        write_mask=w_mask, data_edges=fi.data_edges, period=sq.period, block=sq.block,
        allowed=net.sink, dram=prm.dram, cap_fs=prm.cap_fs, w=prm.w, n=prm.n, stats=prm.stats,
        watchdog_fs=prm.watchdog_fs, d_wwords=prm.d_wwords, d_wbuf=prm.d_wbuf,
        d_slot=prm.d_slot, d_round=prm.d_round, d_wfirst=prm.d_wfirst, d_wcount=prm.d_wcount,
        ring=net.ring, gaps=net.gaps, row_fs=net.rows[1], frame_out=net.frame_fs[1],
        state=net.state[0])
    q_prev = rd(net.ring, q_off, q_mask, kq - 1) if kq > 0 else -1
    return k, SinkCursor(pops=kq, last_pop=q_prev, x=kq % prm.w, bursts=kw, dram_wait=0,
                         empty=0, first=-1, n_gaps=acc.gaps, last_busy_fs=acc.last_busy,
                         ring_error=False)


@njit(cache=True, inline="always")
def pops(k, cur, ko):
    """The sink's next pops of the words pushed (``ko`` known): the first allowed cycle from the
    word's visibility (and, writing back through the DRAM channel, once the write buffer has
    room), from the :class:`SinkCursor` ``cur`` with the constants ``k`` (a
    :class:`SinkLoop`). Returns (cursor, moved)."""
    ring, gaps, row_fs, frame_out, state = k.ring, k.gaps, k.row_fs, k.frame_out, k.state
    q_off, q_mask, o_off, o_mask = k.pop_off, k.pop_mask, k.push_off, k.push_mask
    w_off, w_mask, de, per, blk = k.write_off, k.write_mask, k.data_edges, k.period, k.block
    allowed, dram, cap, w, n = k.allowed, k.dram, k.cap_fs, k.w, k.n
    stats, g, d_wwords, d_wbuf = k.stats, k.watchdog_fs, k.d_wwords, k.d_wbuf
    d_slot, d_round, d_wfirst, d_wcount = k.d_slot, k.d_round, k.d_wfirst, k.d_wcount
    kq, q_prev, xq, kw, d_wait = cur.pops, cur.last_pop, cur.x, cur.bursts, cur.dram_wait
    empty, first, n_gaps = cur.empty, cur.first, cur.n_gaps
    last_busy, err = cur.last_busy_fs, cur.ring_error
    moved = False
    while kq < ko:
        vis = visible_from(rd(ring, o_off, o_mask, kq), per, per, 1.0, de)  # (one domain)
        q = sink_next_allowed(max(q_prev + 1, vis), allowed)
        wait = 0
        last = -1
        if dram == 1:
            u, last = burst_of(kq, n, d_wwords)
            if u >= d_wbuf:
                err |= u - d_wbuf <= kw - 1 - w_mask
                room = rd(ring, w_off, w_mask, u - d_wbuf)
                if room > q:
                    q0 = q
                    q = sink_next_allowed(room, allowed)
                    wait = sink_allowed_between(q0, q, allowed)
        if q * per >= cap:
            break
        d_wait += wait
        if dram == 1 and kq == last:  # a full burst: written in the next write slot
            slot = dram_slot(q * per, state.d_wslot, d_slot, d_round, d_wfirst, d_wcount)
            state.d_wslot = slot
            ring[w_off + (kw & w_mask)] = first_edge_at(dram_write_done_fs(slot, d_slot), per)
            kw += 1
        empty += max(0, vis - q_prev - 1)
        ring[q_off + (kq & q_mask)] = q
        if kq == 0:
            first = q
        if stats == 1:
            n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy, q * per, q * per, g)
        q_prev = q
        kq += 1
        moved = True
        xq += 1
        if xq == w:
            xq = 0
            if kq <= n:  # the first frame's rows
                row_fs[kq // w] = q * per
            if kq % n == 0:
                frame_out[kq // n - 1] = q * per
    return SinkCursor(pops=kq, last_pop=q_prev, x=xq, bursts=kw, dram_wait=d_wait,
                      empty=empty, first=first, n_gaps=n_gaps, last_busy_fs=last_busy,
                      ring_error=err), moved


@njit(cache=True, inline="always")
def pops_end(net, k, cur):
    """Store what :func:`pops` did: the pops and write-back bursts known, the statistics."""
    state = net.state[0]
    ids = net.ids[0]
    net.streams[ids.sink_pop].count = cur.pops
    net.streams[ids.dram_write].count = cur.bursts
    if cur.first >= 0:
        state.first_pop = cur.first
    net.acc[len(net.blocks) + ids.fifo_sink].empty += cur.empty
    # (the sink waits only for the write buffer: blocked)
    store_activity(net.acc[k.block], state, (0, cur.dram_wait, cur.dram_wait),
                   (cur.n_gaps, cur.last_busy_fs), cur.ring_error, net.gaps.shape[1])


# ---- at an instant ------------------------------------------------------------------------------


@njit(cache=True)
def status_sink(ring, streams, cursors, prm, tables, b, c):
    """(activity, FIFO waited on, DRAM or -1) the sink ``b`` (its record) reports in its cycle
    c (the readable ``Sink.evaluate``)."""
    fifos, ids, allowed = tables.fifos, tables.ids, tables.sink
    q_s = ids.sink_pop
    received, at_c = lt_at(ring, streams[q_s], cursors[q_s], c)
    if received >= prm.frames * prm.n:
        return A_IDLE, -1
    if not sink_may_pop(c, allowed):
        return A_IDLE, -1
    if at_c:
        return A_BUSY, -1
    # its word is visible: the write buffer is full
    if prm.dram == 1 and visible_by(ring, streams, fifos[b.fifo_in], received, c):
        return A_BLOCKED, DRAM
    return A_STARVED, b.fifo_in


@njit(cache=True, inline="always")
def sample_sink(ring, streams, cursors, ids, c, out):
    """The sink's traced values besides its status, after its cycle c, into out[0:2]: the words
    received and whether it popped one in that cycle."""
    q_s = ids.sink_pop
    got, at_c = lt_at(ring, streams[q_s], cursors[q_s], c)
    out[0] = got + (1 if at_c else 0)
    out[1] = 1 if at_c else 0
