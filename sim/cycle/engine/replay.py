"""The chip's state at an instant, read off the event streams: what a block reported at its last
edge, every FIFO's occupancy, every traced signal. The stop message of a run that stops and the
trace of a window come from here.

Everything at an instant t depends only on events at instants <= t: a block of a domain with
period P reports at its last edge c = t // P what the readable block's ``evaluate`` would, given
how many of its beats came before c, whether one comes at c, and the few events its rule looks
at (:mod:`sim.cycle.rules`); an event the streams do not hold is later than any instant asked
for (the caller computes them up to it). Status codes: 0 idle, 1 busy, 2 starved, 3 blocked.
"""

from __future__ import annotations

from numba import njit

from sim.cycle.engine.layout import (
    A_BLOCKED,
    A_BUSY,
    A_IDLE,
    A_STARVED,
    F_MERGE,
    F_SRC,
    INF,
    K_CAMERA,
    K_MEMORY,
    K_MERGE,
    K_NNA,
    K_SINK,
    K_SVA,
)
from sim.cycle.engine.walkers import tile_input_before, tile_output_before
from sim.cycle.rules import (
    memory_first_cycle,
    nna_last_input_row,
    seen_from,
    sink_may_pop,
    sva_last_input_row,
    sva_rows_done_before_input,
    sva_word_due,
)

NEVER = -(1 << 40)


@njit(cache=True, inline="always")
def _at(net, s, i):
    st = net.streams[s]
    return net.ring[st.off + (i & st.mask)]


@njit(cache=True)
def count_le(net, s, c):
    """Known events of stream s at cycles <= c (the ring holds the ones asked about)."""
    st = net.streams[s]
    hi = st.count
    lo = max(0, hi - st.mask - 1)
    if hi == 0 or _at(net, s, hi - 1) <= c:
        return hi
    if _at(net, s, lo) > c:
        return lo
    # events lo .. hi - 1 increase; find the first > c
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if _at(net, s, mid) <= c:
            lo = mid
        else:
            hi = mid
    return hi


@njit(cache=True, inline="always")
def _event(net, s, i):
    """Event i of stream s, or INF if the streams do not hold it (later than asked)."""
    if i < net.streams[s].count:
        return _at(net, s, i)
    return INF


@njit(cache=True, inline="always")
def _lt_at(net, s, c):
    """(events before cycle c, is there one at c)."""
    le = count_le(net, s, c)
    at = le > 0 and _at(net, s, le - 1) == c
    return le - (1 if at else 0), at


# ---- blocks -------------------------------------------------------------------------------------


@njit(cache=True)
def _tile_full(net, tl, k, c):
    """Is tile ``tl``'s source FIFO full for pixel k (raster) at producer cycle c?"""
    w = net.prm[0].w
    y = k // w
    x = k - y * w
    if not (tl.ix0 <= x < tl.ix1 and tl.iy0 <= y < tl.iy1):
        return False
    i = (y - tl.iy0) * tl.iw + x - tl.ix0
    f = net.fifos[tl.src_fifo]
    if i < f.depth:
        return False
    b = _event(net, tl.b, i - f.depth)
    return b == INF or seen_from(b, f.per_dst, f.per_src, f.space_edges) > c


@njit(cache=True)
def status_memory(net, blk, c):
    prm = net.prm[0]
    side = net.blocks[blk].side
    k, at = _lt_at(net, side, c)
    if k >= prm.n:
        return A_IDLE, -1
    if at or c < memory_first_cycle(k, prm.mem_hz, prm.mem_bps):
        return A_BUSY, -1
    for t in range(prm.parts):
        tl = net.tiles[side * prm.parts + t]
        if _tile_full(net, tl, k, c):
            return A_BLOCKED, tl.src_fifo
    return A_BUSY, -1  # (not reached: it would have pushed)


@njit(cache=True, inline="always")
def _mac_start(net, tl, j):
    """The cycle the MAC array starts descriptor j of tile ``tl`` (INF: its rows are not in)."""
    prm = net.prm[0]
    r = j // tl.ow
    need = (nna_last_input_row(tl.y0 + r, prm.half, prm.h) - tl.iy0 + 1) * tl.iw
    rows_in = _event(net, tl.b, need - 1)
    if rows_in == INF:
        return INF
    prev = _event(net, tl.e, j - 1) if j > 0 else -1
    return max(prev + 1, rows_in + 1)


@njit(cache=True)
def status_nna(net, blk, c):
    prm = net.prm[0]
    tl = net.tiles[net.blocks[blk].side * prm.parts + net.blocks[blk].tile]
    received, pop_at = _lt_at(net, tl.b, c)
    emitted, push_at = _lt_at(net, tl.e, c)
    moved = pop_at
    mac_blocked = False
    if emitted < tl.n_out:
        s_j = _mac_start(net, tl, emitted)
        if c >= s_j:
            if c <= s_j + prm.cpd - 1 or push_at:
                moved = True
            else:
                mac_blocked = True
    if moved:
        return A_BUSY, -1
    if mac_blocked:
        return A_BLOCKED, tl.out_fifo
    if emitted < tl.n_out or received < tl.n_in:
        return A_STARVED, tl.src_fifo
    return A_IDLE, -1


@njit(cache=True)
def status_merge(net, blk, c):
    prm = net.prm[0]
    b = net.blocks[blk]
    m_s = net.fifos[b.fifo_out].push
    m, at = _lt_at(net, m_s, c)
    if m >= prm.n:
        return A_IDLE, -1
    if at:
        return A_BUSY, -1
    y = m // prm.w
    x = m - y * prm.w
    ti = -1
    for t in range(prm.parts):
        tl = net.tiles[b.side * prm.parts + t]
        if tl.x0 <= x < tl.x1 and tl.y0 <= y < tl.y1:
            ti = b.side * prm.parts + t
    tl = net.tiles[ti]
    e = _event(net, tl.e, (y - tl.y0) * tl.ow + x - tl.x0)
    fin = net.fifos[tl.out_fifo]
    if e == INF or seen_from(e, fin.per_src, fin.per_dst, fin.data_edges) > c:
        return A_STARVED, tl.out_fifo
    return A_BLOCKED, b.fifo_out


@njit(cache=True)
def status_sva(net, blk, c):
    prm = net.prm[0]
    b = net.blocks[blk]
    p_s = net.fifos[b.fifo_in].pop
    o_s = p_s + 1
    n, w = prm.n, prm.w
    received, pop_at = _lt_at(net, p_s, c)
    emitted, push_at = _lt_at(net, o_s, c)
    wait = -1
    if received < n and not pop_at and emitted // w >= sva_rows_done_before_input(
            received // w, prm.lookahead):
        for f in (b.fifo_in, b.fifo_in2):
            fi = net.fifos[f]
            e = _event(net, fi.push, received)
            if e == INF or seen_from(e, fi.per_src, fi.per_dst, fi.data_edges) > c:
                wait = f
                break
    if pop_at or push_at:
        return A_BUSY, -1
    if emitted < n:
        y = emitted // w
        ready = _event(net, p_s, (sva_last_input_row(y, prm.lookahead, prm.h) + 1) * w - 1)
        if ready != INF and ready + 1 <= c:
            prev = _event(net, o_s, emitted - 1) if emitted > 0 else NEVER
            due = sva_word_due(ready + 1, prm.pipe_latency, prev, prm.cpp)
            if c >= due:
                return A_BLOCKED, b.fifo_out
            return A_BUSY, -1
        return A_STARVED, wait if wait >= 0 else b.fifo_in
    return A_IDLE, -1


@njit(cache=True)
def status_sink(net, blk, c):
    prm = net.prm[0]
    f = net.blocks[blk].fifo_in
    q_s = net.fifos[f].pop
    received, at = _lt_at(net, q_s, c)
    if received >= prm.n:
        return A_IDLE, -1
    if not sink_may_pop(c, prm.stall_period, prm.stall_phase):
        return A_IDLE, -1
    if at:
        return A_BUSY, -1
    return A_STARVED, f


@njit(cache=True)
def block_status(net, blk, c):
    """(activity, FIFO waited on or -1) that block ``blk`` reports in its cycle c."""
    kind = net.blocks[blk].kind
    if kind == K_MEMORY:
        return status_memory(net, blk, c)
    if kind == K_CAMERA:
        prm = net.prm[0]
        return (A_BUSY if c // prm.line_clocks < prm.h else A_IDLE), -1
    if kind == K_NNA:
        return status_nna(net, blk, c)
    if kind == K_MERGE:
        return status_merge(net, blk, c)
    if kind == K_SVA:
        return status_sva(net, blk, c)
    return status_sink(net, blk, c)


# ---- FIFOs --------------------------------------------------------------------------------------


@njit(cache=True)
def fifo_counts(net, f, t):
    """(pushes, pops, frees the producer has seen, pushed at the producer's last edge, popped
    at the consumer's last edge) of FIFO f after the step at instant t."""
    prm = net.prm[0]
    fi = net.fifos[f]
    c_src = t // fi.per_src
    c_dst = t // fi.per_dst
    # the last pop whose free slot the producer sees at c_src
    if fi.crossing == 1:
        x = (c_src - fi.space_edges + 1) * fi.per_src
        p_seen = (x - 1) // fi.per_dst if x > 0 else -1
    else:
        p_seen = c_src - 1
    le_push = count_le(net, fi.push, c_src)
    le_pop = count_le(net, fi.pop, c_dst)
    le_seen = count_le(net, fi.pop, p_seen) if p_seen >= 0 else 0
    pushed = le_push > 0 and _at(net, fi.push, le_push - 1) == c_src
    popped = le_pop > 0 and _at(net, fi.pop, le_pop - 1) == c_dst
    if fi.kind == F_SRC:
        tl = net.tiles[fi.side * prm.parts + fi.tile]
        pushes = tile_input_before(tl, prm.w, le_push)
        pushed = pushed and tile_input_before(tl, prm.w, le_push - 1) < pushes
        return pushes, le_pop, le_seen, pushed, popped
    if fi.kind == F_MERGE:
        tl = net.tiles[fi.side * prm.parts + fi.tile]
        pops = tile_output_before(tl, prm.w, le_pop)
        popped = popped and tile_output_before(tl, prm.w, le_pop - 1) < pops
        return le_push, pops, tile_output_before(tl, prm.w, le_seen), pushed, popped
    return le_push, le_pop, le_seen, pushed, popped


# ---- traced signals -----------------------------------------------------------------------------


@njit(cache=True)
def sample(net, data, t, out):
    """Every traced signal's value after the step at instant t, in the plan's order (blocks,
    then FIFOs; :func:`sim.cycle.plan._signals`)."""
    prm = net.prm[0]
    k = 0
    w = prm.w
    for blk in range(net.blocks.shape[0]):
        b = net.blocks[blk]
        c = t // b.period
        st, _ = block_status(net, blk, c)
        out[k] = (st + 1) % 4  # idle 0, busy 1, starved 2, blocked 3
        k += 1
        if b.kind == K_MEMORY or b.kind == K_CAMERA:
            out[k] = count_le(net, b.side, c)
            k += 1
        elif b.kind == K_NNA:
            tl = net.tiles[b.side * prm.parts + b.tile]
            received = count_le(net, tl.b, c)
            emitted, push_at = _lt_at(net, tl.e, c)
            if push_at:
                emitted += 1
            y_in = tl.iy0 + received // tl.iw
            y_out = tl.y0 + emitted // tl.ow
            phase = 0
            if not push_at and emitted < tl.n_out:
                s_j = _mac_start(net, tl, emitted)
                if c >= s_j:
                    phase = c - s_j + 1 if c < s_j + prm.cpd - 1 else prm.cpd
            out[k] = y_in
            out[k + 1] = max(0, y_in - max(tl.iy0, y_out - prm.half))
            out[k + 2] = phase
            out[k + 3] = y_out
            out[k + 4] = tl.x0 + emitted % tl.ow
            out[k + 5] = 1 if push_at else 0
            desc = 0
            if emitted > 0:
                j = emitted - 1
                r = j // tl.ow
                desc = data.desc[b.side, tl.y0 + r, tl.x0 + j - r * tl.ow]
            out[k + 6] = desc
            k += 7
        elif b.kind == K_MERGE:
            m, at = _lt_at(net, net.fifos[b.fifo_out].push, c)
            out[k] = m + (1 if at else 0)
            out[k + 1] = 1 if at else 0
            k += 2
        elif b.kind == K_SVA:
            p_s = net.fifos[b.fifo_in].pop
            received = count_le(net, p_s, c)
            emitted, push_at = _lt_at(net, p_s + 1, c)
            if push_at:
                emitted += 1
            rows = received // w
            out[k] = rows
            out[k + 1] = received - rows * w
            out[k + 2] = prm.h if rows >= prm.h else max(0, rows - prm.lookahead)
            out[k + 3] = emitted // w
            out[k + 4] = emitted % w
            out[k + 5] = 1 if push_at else 0
            word = 0
            if emitted > 0:
                word = data.words[(emitted - 1) // w, (emitted - 1) % w]
            out[k + 6] = word & data.word_mask
            out[k + 7] = 1 if push_at and word < 0 else 0
            k += 8
        elif b.kind == K_SINK:
            q_s = net.fifos[b.fifo_in].pop
            got, at = _lt_at(net, q_s, c)
            out[k] = got + (1 if at else 0)
            out[k + 1] = 1 if at else 0
            k += 2
    for f in range(net.fifos.shape[0]):
        pushes, pops, seen, pushed, popped = fifo_counts(net, f, t)
        occ = pushes - pops
        out[k] = occ
        out[k + 1] = 1 if pushed else 0
        out[k + 2] = 1 if popped else 0
        out[k + 3] = 1 if pushes - seen >= net.fifos[f].depth else 0
        out[k + 4] = 1 if occ == 0 else 0
        k += 5


@njit(cache=True)
def next_instant(periods, t):
    """The first clock edge of any domain strictly after instant t (t may be -1)."""
    best = INF
    for per in periods:
        e = (t // per + 1) * per
        if e < best:
            best = e
    return best


@njit(cache=True)
def record_window(net, data, periods, end, log):
    """Record the traced signals from the instant ``log.ctl[1]`` until ``end`` (exclusive):
    every change against ``log.last`` goes to (times, ids, values) from ``log.ctl[0]`` on.
    Returns False when the arrays are full (grow them and call again: ``ctl`` holds where)."""
    ctl, last, times, ids, values, scratch = log
    n_sig = last.shape[0]
    n_log = ctl[0]
    t = ctl[1]
    while t < end:
        if n_log + n_sig > times.shape[0]:
            ctl[0], ctl[1] = n_log, t
            return False
        sample(net, data, t, scratch)
        for i in range(n_sig):
            v = scratch[i]
            if v != last[i]:
                last[i] = v
                times[n_log] = t
                ids[n_log] = i
                values[n_log] = v
                n_log += 1
        t = next_instant(periods, t)
    ctl[0], ctl[1] = n_log, t
    return True
