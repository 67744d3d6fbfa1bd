"""The SVA's lock-step pipeline on the event streams: when each word is issued, reaches the
output register and is pushed, found in closed form from the readable kernel's rules
(:mod:`sim.cycle.rules`, :class:`sim.cycle.readable.blocks.sva.SvaBlock`).

The pipeline's tick counts the cycles in which it advanced; it stalls only while the word in
its output register waits for a free slot. So between one push and the next word's arrival it
advances every cycle, and everything follows from three streams: ``T`` (the tick each word is
issued at, t_j), ``O`` (the cycle each word is pushed, o_j) and the exit ticks x_j = t_j + L:

- the tick at the start of cycle c, with k words pushed before c:
  ``T(c) = min(x_{k-1} + c - o_{k-1}, x_k)`` (``sva_tick_at``; before any push o = x = 0);
- word j reaches the output register in cycle ``a_j = o_{j-1} + x_j - x_{j-1}``
  (``sva_cycle_of_tick`` of its exit tick) and is pushed at ``o_j = max(a_j, free slot)``;
- word j is issued at tick ``t_j = max(T(ready_j), t_{j-1} + II)`` (``sva_issue_tick``), in the
  first advancing cycle with that tick: ``o_k`` if it is word k's exit tick (the pipeline
  resumes with that push), else ``sva_cycle_of_tick(t_j, o_{k-1}, x_{k-1})`` with k the first
  word whose exit tick is above it.

Each of these needs only pushes that come before it in time; a value that needs a push not yet
known waits (the helpers return ok = False) and the stream loop moves on to the pushes. The
helpers read the rings through ``(offset, mask, lowest held index)`` triples; reading below the
lowest held index sets the ring error (the caller reruns with larger rings).
"""

from __future__ import annotations

from numba import njit

from stereosim.sim.cycle.compiled.layout import ERR_GAPS, ERR_RING, INF
from stereosim.sim.cycle.compiled.ring import busy, rd, view
from stereosim.sim.cycle.rules import (
    burst_of,
    dram_slot,
    dram_write_done_fs,
    first_edge_at,
    sink_allowed_between,
    sink_next_allowed,
    sva_cycle_of_tick,
    sva_issue_tick,
    sva_last_input_row,
    sva_tick_at,
)

NEVER = -(1 << 40)  # the previous issue tick before the first word


@njit(cache=True, inline="always")
def _first_at_least(ring, off, mask, lo, hi, v):
    """The first index in [lo, hi) whose (increasing) event is >= v (hi if none)."""
    while lo < hi:
        mid = (lo + hi) // 2
        if ring[off + (mid & mask)] >= v:
            hi = mid
        else:
            lo = mid + 1
    return lo


@njit(cache=True, inline="always")
def arrival(ring, o, t, lat, j):
    """The cycle word j reaches the output register (its push o_{j-1} and both issue ticks
    known)."""
    x = rd(ring, t[0], t[1], j) + lat
    if j == 0:
        return sva_cycle_of_tick(x, 0, 0)
    return sva_cycle_of_tick(x, rd(ring, o[0], o[1], j - 1), rd(ring, t[0], t[1], j - 1) + lat)


@njit(cache=True, inline="always")
def tick_at(ring, o, t, lat, ko, kt, c):
    """(T(c), ok, ring error): the pipeline's tick at the start of cycle c from the ``ko``
    pushes and ``kt`` issue ticks known; not ok while a push not yet known may come before c.
    ``o``, ``t``: (offset, mask, lowest held index) of the O and T rings."""
    if ko > 0 and rd(ring, o[0], o[1], ko - 1) >= c:
        lo = max(0, o[2] + 1)
        k = _first_at_least(ring, o[0], o[1], lo, ko, c)
        err = k == lo and lo > 0  # the answer may lie in what the ring no longer holds
    else:
        k = ko
        err = False
        if ko < kt and c > arrival(ring, o, t, lat, ko):
            return 0, False, err  # word ko waits in the output register: its push decides
    if k == 0:
        last_push, last_exit = 0, 0
    else:
        last_push, last_exit = rd(ring, o[0], o[1], k - 1), rd(ring, t[0], t[1], k - 1) + lat
    nxt = rd(ring, t[0], t[1], k) + lat if k < kt else INF
    err = err or (k > 0 and (k - 1 <= o[2] or k - 1 <= t[2]))
    return sva_tick_at(c, last_push, last_exit, nxt), True, err


@njit(cache=True, inline="always")
def exiting_from(ring, t, lat, kt, tick):
    """The first of the ``kt`` issued words whose exit tick is >= ``tick`` (``kt`` if none),
    and a ring error."""
    if kt == 0 or rd(ring, t[0], t[1], kt - 1) + lat < tick:
        return kt, False
    lo = max(0, t[2] + 1)
    k = _first_at_least(ring, t[0], t[1], lo, kt, tick - lat)
    return k, k == lo and lo > 0  # the answer may lie in what the ring no longer holds


@njit(cache=True, inline="always")
def cycle_of_after(ring, o, t, lat, ko, kt, tick, k):
    """(cycle, ok): the first advancing cycle whose tick is ``tick``, k being the first issued
    word whose exit tick is >= ``tick`` (:func:`exiting_from`), from the ``ko`` pushes and
    ``kt`` issue ticks known; not ok while it depends on a push not yet known."""
    if k < kt and rd(ring, t[0], t[1], k) + lat == tick:
        if k < ko:
            return rd(ring, o[0], o[1], k), True  # the pipeline resumes with k's push
        return 0, False
    if k == 0:
        return sva_cycle_of_tick(tick, 0, 0), True
    if k - 1 < ko:
        return sva_cycle_of_tick(tick, rd(ring, o[0], o[1], k - 1),
                                 rd(ring, t[0], t[1], k - 1) + lat), True
    return 0, False


@njit(cache=True, inline="always")
def cycle_of(ring, o, t, lat, ko, kt, tick):
    """(cycle, ok, ring error): :func:`cycle_of_after` with the word found by search."""
    k, err = exiting_from(ring, t, lat, kt, tick)
    e, ok = cycle_of_after(ring, o, t, lat, ko, kt, tick, k)
    return e, ok, err or (k > 0 and (k - 1 <= o[2] or k - 1 <= t[2]))


@njit(cache=True, inline="always")
def issued_before(ring, t, kt, tick):
    """Words (of the ``kt`` whose issue ticks are known) issued at ticks below ``tick``."""
    return _first_at_least(ring, t[0], t[1], max(0, t[2] + 1), kt, tick)


@njit(cache=True, inline="always")
def words_between(ring, t, kt, lo_tick, hi_tick):
    """Issued words (of the ``kt`` known) with issue tick in [lo_tick, hi_tick)."""
    first = max(0, t[2] + 1)
    a = _first_at_least(ring, t[0], t[1], first, kt, lo_tick)
    b = _first_at_least(ring, t[0], t[1], a, kt, hi_tick)
    return b - a


@njit(cache=True)
def advance_sva_out_and_sink(net, p_s, f_sink):
    """The SVA's issues, its pushes and the sink's pops taken in turn in one loop (an issue
    needs the rows' pops and the pushes before it, a push its issue and the pop of the word a
    FIFO depth before, a pop the push of its word). Streams: P = ``p_s``, O, Q, T after it."""
    prm = net.prm[0]
    ring, streams, gaps = net.ring, net.streams, net.gaps
    p_off, p_mask, npop, p_lo = view(streams, p_s)
    o_off, o_mask, ko, _ = view(streams, p_s + 1)
    q_off, q_mask, kq, _ = view(streams, p_s + 2)
    t_off, t_mask, kt, _ = view(streams, p_s + 3)
    so, sq, st = streams[p_s + 1], streams[p_s + 2], streams[p_s + 3]
    w_off, w_mask, kw, _ = view(streams, p_s + 5)  # W: the write-back's bursts
    dram, d_wait = prm.dram, 0
    fi = net.fifos[f_sink]
    depth, de = fi.depth, fi.data_edges
    n, w, h, per, cap, la = so.n, prm.w, prm.h, so.period, prm.cap_fs, prm.lookahead
    lat, cpp = prm.pipe_latency, prm.cpp
    period, phase, stats, g = prm.stall_period, prm.stall_phase, prm.stats, prm.watchdog_fs
    blk = sq.block
    acc = net.acc[blk]
    row_fs = net.rows[1]
    frame_out = net.frame_fs[1]
    issue_rows = net.occ[net.occ.shape[0] - 1]
    last_busy, n_gaps = acc.last_busy, acc.gaps
    err = False
    start_o, start_q, start_t = ko, kq, kt
    q_prev = rd(ring, q_off, q_mask, kq - 1) if kq > 0 else -1
    t_prev = rd(ring, t_off, t_mask, kt - 1) if kt > 0 else NEVER
    yt = kt // w
    xt = kt - yt * w
    xq = kq % w
    kx = -1  # the first issued word exiting at or after the next issue's tick (-1: search)
    ready_row = -1
    ready = 0
    ready_tick = 0
    ready_known = False
    first = -1
    empty = 0
    while True:
        moved = False
        o = (o_off, o_mask, ko - 1 - o_mask)
        t = (t_off, t_mask, kt - 1 - t_mask)
        # issues: the next word once its row is ready and the pipeline reaches its tick
        while kt < n:
            if yt != ready_row:
                ft = yt // h  # the frame of output row yt: its rows up to the look-ahead's
                need = (ft * h + sva_last_input_row(yt - ft * h, la, h) + 1) * w
                if need > npop:
                    break
                err |= need - 1 <= p_lo
                ready = rd(ring, p_off, p_mask, need - 1) + 1
                ready_row = yt
                ready_known = False
            if xt == 0:
                if not ready_known:
                    ready_tick, ok, bad = tick_at(ring, o, t, lat, ko, kt, ready)
                    err |= bad
                    if not ok:
                        break
                    ready_known = True
                tick = sva_issue_tick(ready_tick, t_prev, cpp)
            else:  # the row was ready when its first word was issued: T(ready) <= t_prev
                tick = sva_issue_tick(NEVER, t_prev, cpp)
            # the first issued word exiting at or after the tick: it only moves forward
            if kx < 0:
                kx, bad = exiting_from(ring, t, lat, kt, tick)
                err |= bad
            while kx < kt and rd(ring, t_off, t_mask, kx) + lat < tick:
                kx += 1
            err |= kx > 0 and (kx - 1 <= o[2] or kx - 1 <= t[2])
            e, ok = cycle_of_after(ring, o, t, lat, ko, kt, tick, kx)
            if not ok or e * per >= cap:
                break
            ring[t_off + (kt & t_mask)] = tick
            t_prev = tick
            kt += 1
            t = (t_off, t_mask, kt - 1 - t_mask)
            moved = True
            xt += 1
            if xt == w:
                issue_rows[yt & (issue_rows.shape[0] - 1)] = e
                xt = 0
                yt += 1
        # pushes: an issued word at its arrival, once the slot a FIFO depth back is free
        while ko < kt and ko - depth < kq:
            free = rd(ring, q_off, q_mask, ko - depth) + 1 if ko >= depth else 0
            out = max(arrival(ring, o, t, lat, ko), free)
            if out * per >= cap:
                break
            ring[o_off + (ko & o_mask)] = out
            ko += 1
            o = (o_off, o_mask, ko - 1 - o_mask)
            moved = True
        # pops: the first allowed cycle from the word's visibility (and, writing back through
        # the DRAM channel, once the write buffer has room)
        while kq < ko:
            vis = rd(ring, o_off, o_mask, kq) + de
            q = sink_next_allowed(max(q_prev + 1, vis), period, phase)
            wait = 0
            last = -1
            if dram == 1:
                u, last = burst_of(kq, prm.n, prm.d_wwords)
                if u >= prm.d_wbuf:
                    err |= u - prm.d_wbuf <= kw - 1 - w_mask
                    room = rd(ring, w_off, w_mask, u - prm.d_wbuf)
                    if room > q:
                        q0 = q
                        q = sink_next_allowed(room, period, phase)
                        wait = sink_allowed_between(q0, q, period, phase)
            if q * per >= cap:
                break
            d_wait += wait
            if dram == 1 and kq == last:  # a full burst: written in the next write slot
                slot = dram_slot(q * per, prm.d_wslot, prm.d_slot, prm.d_round, prm.d_wfirst,
                                 prm.d_wcount)
                prm.d_wslot = slot
                ring[w_off + (kw & w_mask)] = first_edge_at(dram_write_done_fs(slot,
                                                                               prm.d_slot), per)
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
                if kq <= prm.n:  # the first frame's rows
                    row_fs[kq // w] = q * per
                if kq % prm.n == 0:
                    frame_out[kq // prm.n - 1] = q * per
        if not moved:
            break
    so.count, sq.count, st.count = ko, kq, kt
    streams[p_s + 5].count = kw
    acc.blocked += d_wait
    acc.dram += d_wait
    if first >= 0:
        prm.first_pop = first
    acc.last_busy, acc.gaps = last_busy, n_gaps
    net.acc[len(net.blocks) + f_sink].empty += empty
    if err:
        prm.error = ERR_RING
    if n_gaps > gaps.shape[1]:
        prm.error = ERR_GAPS
    return ko > start_o or kq > start_q or kt > start_t
