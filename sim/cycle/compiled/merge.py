"""The merge of split frames on the compiled engine (twin of the readable kernel's
:class:`~sim.cycle.readable.blocks.nna.Merge`, in :mod:`sim.cycle.readable.blocks.nna`).

Stream ``MERGE_MOVE``, per side: the merge moves descriptor m (raster order of the frame) from
its owner tile's FIFO to the SVA's in one cycle, once visible there and with a free slot:
``g[m] = max(g[m-1] + 1, vis(e_owner[j]), free(p[m - depth]))``. Its statistics are taken on the
way (starved while the owner tile's head is not visible, blocked while the SVA's FIFO is full,
busy at each move; each tile FIFO's empty cycles), and what it reports at an instant is read
off the same events.
"""

from __future__ import annotations

from stereosim.core.kernel_cache import njit, njit_borrowing
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
    ratio,
    rd,
    store_activity,
    view,
)
from stereosim.sim.cycle.fifo.rule import room_from, visible_from


@njit(cache=True, inline="always")
def _merge_tables(net, side, tab):
    """Per tile of ``side`` into ``tab`` (TABLE): output region, ring of its MAC pushes, its
    merge FIFO's latency, empty cycles and last pop."""
    streams = net.streams
    nb = len(net.blocks)
    parts = net.prm[0].parts
    for t in range(parts):
        tl = net.tiles[side * parts + t]
        e = streams[tl.mac_push]
        fin = net.fifos[tl.out_fifo]
        r = tab[t]
        r.x0, r.x1, r.y0, r.y1, r.width, r.items = tl.x0, tl.x1, tl.y0, tl.y1, tl.ow, tl.n_out
        r.off, r.mask, r.count, r.lost = e.off, e.mask, e.count, e.count - 1 - e.mask
        r.edges = fin.data_edges
        r.empty = net.acc[nb + tl.out_fifo].empty
        r.last_pop = net.acc[nb + tl.out_fifo].last_pop


@njit_borrowing(cache=True)
def advance_merge(net, side):
    """The merge of ``side`` (the readable ``Merge.evaluate``): descriptor m (raster order)
    moves from its owner tile's FIFO to the SVA's in one cycle, once visible there and with a
    free slot."""
    prm = net.prm[0]
    m_s = net.tiles[side * prm.parts].merge_move
    state = net.state[0]
    ring, streams, gaps = net.ring, net.streams, net.gaps
    m_off, m_mask, m, _ = view(streams, m_s)
    st = streams[m_s]
    n, w, per, cap, parts, g = st.n, prm.w, st.period, prm.cap_fs, prm.parts, prm.watchdog_fs
    blk = st.block
    acc = net.acc[blk]
    out = net.fifos[net.blocks[blk].fifo_out]
    p_off, p_mask, npop, p_lo = view(streams, out.pop)
    depth, per_dst, per_src, se = out.depth, out.per_dst, out.per_src, out.space_edges
    rat = ratio(per_dst, per_src)
    stats = prm.stats
    last_busy, n_gaps = acc.last_busy, acc.gaps
    tab = net.scratch
    nb = len(net.blocks)
    _merge_tables(net, side, tab)
    err = False
    start = m
    mg_prev = rd(ring, m_off, m_mask, m - 1) if m > 0 else -1
    starved = 0
    blocked = 0
    y = m // w  # row of frame fr
    x = m - y * w
    fr = y // prm.h
    y -= fr * prm.h
    while m < n:
        t = 0
        while not (tab[t].x0 <= x < tab[t].x1 and tab[t].y0 <= y < tab[t].y1):
            t += 1
        r = tab[t]
        j = fr * r.items + (y - r.y0) * r.width + x - r.x0
        if j >= r.count:
            break
        free = 0
        if m >= depth:
            if m - depth >= npop:
                break
            err |= m - depth <= p_lo
            free = room_from(rd(ring, p_off, p_mask, m - depth), per_src, per_dst, rat, se)
        err |= j <= r.lost
        vis = visible_from(ring[r.off + (j & r.mask)], per, per, 1.0, r.edges)  # (one domain)
        mg = max(mg_prev + 1, vis, free)
        if mg * per >= cap:
            break
        if stats == 1:
            starved += max(0, vis - mg_prev - 1)
            blocked += mg - max(vis, mg_prev + 1)
            r.empty += max(0, vis - r.last_pop - 1)
            r.last_pop = mg
            n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy, mg * per, mg * per, g)
        ring[m_off + (m & m_mask)] = mg
        mg_prev = mg
        m += 1
        x += 1
        if x == w:
            x = 0
            y += 1
            if y == prm.h:
                y = 0
                fr += 1
    st.count = m
    for t in range(parts):
        f = net.tiles[side * parts + t].out_fifo
        net.acc[nb + f].empty = tab[t].empty
        net.acc[nb + f].last_pop = tab[t].last_pop
    store_activity(acc, state, (starved, blocked, 0), (n_gaps, last_busy), err, gaps.shape[1])
    return m > start



@njit(cache=True)
def status_merge(ring, streams, cursors, prm, tables, b, c):
    """(activity, FIFO waited on or -1) the merge ``b`` (its record) reports in its cycle c."""
    tiles, fifos = tables.tiles, tables.fifos
    m_s = fifos[b.fifo_out].push
    m, at_c = lt_at(ring, streams[m_s], cursors[m_s], c)
    if m >= prm.frames * prm.n:
        return A_IDLE, -1
    if at_c:
        return A_BUSY, -1
    fr = m // prm.n
    y = (m - fr * prm.n) // prm.w
    x = m - fr * prm.n - y * prm.w
    ti = -1
    for t in range(prm.parts):
        tl = tiles[b.side * prm.parts + t]
        if tl.x0 <= x < tl.x1 and tl.y0 <= y < tl.y1:
            ti = b.side * prm.parts + t
    tl = tiles[ti]
    if not visible_by(ring, streams, fifos[tl.out_fifo],
                      fr * tl.n_out + (y - tl.y0) * tl.ow + x - tl.x0, c):
        return A_STARVED, tl.out_fifo
    return A_BLOCKED, b.fifo_out



@njit(cache=True, inline="always")
def sample_merge(ring, streams, cursors, fifos, b, c, out):
    """The merge's traced values besides its status, after its cycle c, into out[0:2]: the
    descriptors moved and whether it moved one in that cycle."""
    m_s = fifos[b.fifo_out].push
    m, at_c = lt_at(ring, streams[m_s], cursors[m_s], c)
    out[0] = m + (1 if at_c else 0)
    out[1] = 1 if at_c else 0
