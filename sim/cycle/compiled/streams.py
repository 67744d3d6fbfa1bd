"""The event streams of a frame: the cycle of every beat, from the rules of the readable kernel.

The chip's timing does not depend on the data: when a beat moves is decided by beat counters,
FIFO occupancies and clocks. Every rule of the readable kernel reads committed state, so each
event happens at the first cycle at which a few earlier events allow it (docs/compiled-engine.md
lists the recurrences; the rules themselves are :mod:`sim.cycle.rules`):

- source push  ``a[k] = max(a[k-1] + 1, first bucket cycle, free(b_t[i - depth]) per tile t)``,
  a camera's fixed by its raster (an overflow if a slot is not free by then);
- line-buffer pop ``b[i] = max(b[i-1] + 1, visible(a[k]), room: e[need - 1] + 1)``;
- MAC push ``e[j] = max(s + cycles - 1, free)``, started at ``s = max(e[j-1] + 1, b[last input]
  + 1)``;
- merge move ``m = max(m_prev + 1, visible(e_owner[j]), free)``;
- SVA pop ``p[j] = max(p[j-1] + 1, visible(left[j]), visible(right[j]), issued(window) + 1)``;
  its lock-step pipeline's issue ticks ``t[j]`` and pushes ``o[j] = max(arrival(j), q[j -
  depth] + 1)`` (:mod:`sim.cycle.compiled.pipeline`); sink pop ``q[j]`` the first allowed cycle
  from ``max(q[j-1] + 1, visible(o[j]))``.

Each event depends on earlier events of its own stream and on events of other streams that are
strictly earlier in time, so :func:`run_pass` advances the streams in turn, each as far as what
it needs is known, until the sink has the frame or no stream can move (a deadlock, or the cap:
events at instants from ``prm.cap_fs`` on are not computed). Events live in rings
(:mod:`sim.cycle.compiled.layout`); a read of an event its ring no longer holds sets
``prm.error`` and the caller reruns with larger rings.

The statistics the readable kernel accumulates edge by edge are taken on the way: here the
sources', the merges' and the FIFOs' empty counts and the busy instants of the blocks whose
events are all they do; the MAC arrays', the SVA's and every FIFO's occupancy walk in
:mod:`sim.cycle.compiled.walkers`, run behind the streams.

(Speed: the helpers take arrays and integers, never the whole
:class:`~sim.cycle.compiled.layout.Net`, and the loops read the rings through local offsets and
masks: numba then keeps a stream's state in registers and emits no reference counting in the
loops, ~70 times faster than the first version.)
"""

from __future__ import annotations

import numpy as np
from numba import njit

from stereosim.sim.cycle.compiled.layout import (
    END_CAP,
    END_DONE,
    END_OVERFLOW,
    END_STUCK,
    ERR_GAPS,
    ERR_RING,
    INF,
)
from stereosim.sim.cycle.compiled.pipeline import advance_sva_out_and_sink
from stereosim.sim.cycle.compiled.reads import decide_frame, reader_first
from stereosim.sim.cycle.compiled.ring import busy, ratio, rd, view
from stereosim.sim.cycle.compiled.walkers import walk_all
from stereosim.sim.cycle.rules import (
    camera_cycle,
    memory_first_cycle,
    nna_last_input_row,
    nna_rows_started_before_input,
    seen_from_scaled,
    sva_rows_done_before_input,
)

# ---- the sources --------------------------------------------------------------------------------


@njit(cache=True)
def _source_tables(tiles, fifos, streams, side, parts, tab):
    """Per tile of ``side`` into ``tab`` (parts, 14): input region, ring of its pops, its
    source FIFO, its input pixels per frame."""
    for t in range(parts):
        tl = tiles[side * parts + t]
        f = fifos[tl.src_fifo]
        b = streams[tl.b]
        tab[t, 0], tab[t, 1], tab[t, 2], tab[t, 3], tab[t, 4] = tl.ix0, tl.ix1, tl.iy0, \
            tl.iy1, tl.iw
        tab[t, 5], tab[t, 6], tab[t, 7], tab[t, 8] = b.off, b.mask, b.count, b.count - 1 - b.mask
        tab[t, 9], tab[t, 10], tab[t, 11], tab[t, 12] = f.depth, f.per_dst, f.per_src, \
            f.space_edges
        tab[t, 13] = tl.n_in


@njit(cache=True, inline="always")
def advance_source(net, side):
    """Source pushes of camera ``side`` (a joint push to every tile that takes the pixel)."""
    prm = net.prm[0]
    ring, streams, gaps = net.ring, net.streams, net.gaps
    a_s = net.tiles[side * prm.parts].a
    a_off, a_mask, k, _ = view(streams, a_s)
    st = streams[a_s]
    n, w, h, per, cap = st.n, prm.w, prm.h, st.period, prm.cap_fs
    parts, camera, stats, g = prm.parts, prm.camera, prm.stats, prm.watchdog_fs
    line_clocks, frame_clocks, mem_hz, mem_bps = (prm.line_clocks, prm.frame_clocks,
                                                  prm.mem_hz, prm.mem_bps)
    frame_in = net.frame_fs[0]
    blk = st.block
    acc = net.acc[blk]
    last_busy, n_gaps = acc.last_busy, acc.gaps
    tab = net.scratch
    _source_tables(net.tiles, net.fifos, streams, side, parts, tab)
    rat = ratio(tab[0, 10], tab[0, 11])
    blocked = 0
    err = False
    start = k
    a_prev = rd(ring, a_off, a_mask, k - 1) if k > 0 else -1
    full_tile = -1
    y = k // w  # row of frame fno
    x = k - y * w
    fno = y // h
    y -= fno * h
    fb = prm.fb
    rat_cam = ratio(prm.per_cam, per) if fb > 0 else 1.0
    starved = 0
    d_wait = 0
    while k < n:
        if fb > 0 and x == 0 and y == 0 and fno >= prm.fb_taken:  # a camera's next frame
            if decide_frame(net, fno, acc, prm.cap_fs) != 1:
                break
        free = 0
        ok = True
        c = camera_cycle(fno, x, y, line_clocks, frame_clocks, prm.pairs)
        for t in range(parts):
            if not (tab[t, 0] <= x < tab[t, 1] and tab[t, 2] <= y < tab[t, 3]):
                continue
            j = fno * tab[t, 13] + (y - tab[t, 2]) * tab[t, 4] + x - tab[t, 0] - tab[t, 9]
            if j >= 0:
                if j >= tab[t, 7]:
                    ok = False
                    break
                err |= j <= tab[t, 8]
                fr = seen_from_scaled(ring[tab[t, 5] + (j & tab[t, 6])], tab[t, 10],
                                      tab[t, 11], rat, tab[t, 12])
                if fr > free:
                    free = fr
                if camera == 1 and full_tile < 0 and fr > c:
                    full_tile = t
        if not ok:
            break
        if camera == 1:
            a = c
            if a * per >= cap:
                full_tile = -1
                break
            if full_tile >= 0:
                break
        else:
            first, wait, ok, bad = reader_first(net, k, side, a_prev, per, rat_cam)
            err |= bad
            if not ok:
                break
            d_wait += wait
            lo = max(first, memory_first_cycle(k, mem_hz, mem_bps))
            a = max(lo, free)
            if a * per >= cap:
                break
            if stats == 1:
                # starved waiting for the camera, then busy in every cycle but the blocked
                # ones, lo .. a - 1
                if first > a_prev + 1:
                    starved += first - a_prev - 1
                    n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy, first * per,
                                             first * per, g)
                if a > lo:
                    blocked += a - lo
                    n_gaps, last_busy = busy(gaps, blk, n_gaps,
                                             (lo - 1) * per if lo > 0 else last_busy, a * per,
                                             a * per, g)
                last_busy = a * per
        ring[a_off + (k & a_mask)] = a
        if side == 0 and x == 0 and y == 0 and fb == 0:
            frame_in[fno] = a * per
        if fb > 0 and x == w - 1 and y == h - 1:
            net.fbuf[1, fno] = a * per  # the reader is done with this frame's buffer
        a_prev = a
        k += 1
        x += 1
        if x == w:
            x = 0
            y += 1
            if y == h:
                y = 0
                fno += 1
    st.count = k
    acc.blocked += blocked
    acc.starved += starved
    acc.dram += d_wait
    acc.last_busy, acc.gaps = last_busy, n_gaps
    if full_tile >= 0:
        acc.over_cycle, acc.over_k, acc.over_tile = (
            camera_cycle(fno, x, y, line_clocks, frame_clocks, prm.pairs), k,
            side * parts + full_tile)
        prm.end = END_OVERFLOW
    if err:
        prm.error = ERR_RING
    if n_gaps > gaps.shape[1]:
        prm.error = ERR_GAPS
    return k > start


@njit(cache=True)
def advance_whole_side(net, side):
    """A camera served by one submodule: its source pushes and its line buffer's pops taken in
    turn in one loop (a push needs the pop of the item a FIFO depth before, a pop the push of
    its item), each as far as the other allows -- the same events as
    :func:`advance_source` and :func:`advance_pops`, without a call per turn."""
    prm = net.prm[0]
    ring, streams, gaps = net.ring, net.streams, net.gaps
    tl = net.tiles[side]
    a_off, a_mask, ka, _ = view(streams, tl.a)
    b_off, b_mask, kb, _ = view(streams, tl.b)
    e_off, e_mask, ne, e_lo = view(streams, tl.e)
    sa, sb = streams[tl.a], streams[tl.b]
    f = net.fifos[tl.src_fifo]
    depth, de, se = f.depth, f.data_edges, f.space_edges
    p_src, p_nna = f.per_src, f.per_dst
    rat_in, rat_back = ratio(p_src, p_nna), ratio(p_nna, p_src)
    n, w, h, cap = sa.n, prm.w, prm.h, prm.cap_fs
    camera, stats, g = prm.camera, prm.stats, prm.watchdog_fs
    line_clocks, frame_clocks, mem_hz, mem_bps = (prm.line_clocks, prm.frame_clocks,
                                                  prm.mem_hz, prm.mem_bps)
    frame_in = net.frame_fs[0]
    rows, half, oh = prm.rows, prm.half, tl.y1 - tl.y0
    blk = sa.block
    acc = net.acc[blk]
    last_busy, n_gaps = acc.last_busy, acc.gaps
    row_fs = net.rows[0]
    occ, occ_in = net.occ, 2 * side
    left = side == 0
    fb = prm.fb
    rat_cam = ratio(prm.per_cam, p_src) if fb > 0 else 1.0
    blocked = 0
    starved = 0
    empty = 0
    d_wait = 0
    start_a, start_b = ka, kb
    a_prev = rd(ring, a_off, a_mask, ka - 1) if ka > 0 else -1
    b_prev = rd(ring, b_off, b_mask, kb - 1) if kb > 0 else -1
    xa = ka % w
    ya = ka // w  # rows over the stream
    fa = ya // h  # the frame of ya
    xb = kb % w
    yb = kb // w
    room_row = -1
    room = 0
    err = False
    over = False
    while True:
        moved = False
        # pops: the line buffer takes what the source pushed, while its rows have room
        while kb < ka:
            if yb != room_row:
                started = nna_rows_started_before_input(yb, rows, half, 0, oh, h)
                if started > 0:
                    j = started * w - 1
                    if j >= ne:
                        break
                    err |= j <= e_lo
                    room = rd(ring, e_off, e_mask, j) + 1
                else:
                    room = 0
                room_row = yb
            vis = seen_from_scaled(rd(ring, a_off, a_mask, kb), p_src, p_nna, rat_in, de)
            b = max(b_prev + 1, vis, room)
            if b * p_nna >= cap:
                break
            if vis > b_prev + 1:
                empty += vis - b_prev - 1
            ring[b_off + (kb & b_mask)] = b
            if xb == 0:
                occ[occ_in, yb & (occ.shape[1] - 1)] = b
            b_prev = b
            kb += 1
            moved = True
            xb += 1
            if xb == w:
                if left and yb < h and b * p_nna > row_fs[yb + 1]:
                    row_fs[yb + 1] = b * p_nna
                xb = 0
                yb += 1
        # pushes: the source sends while the slot a FIFO depth back has been freed
        while ka < n and ka - depth < kb:
            free = 0
            if ka >= depth:
                free = seen_from_scaled(rd(ring, b_off, b_mask, ka - depth), p_nna, p_src,
                                        rat_back, se)
            c = camera_cycle(fa, xa, ya - fa * h, line_clocks, frame_clocks, prm.pairs)
            if camera == 1:
                if c * p_src >= cap:
                    break
                if free > c:
                    over = True
                    break
                a = c
            else:
                # from a camera's frame buffer: decided at each frame's start
                if fb > 0 and xa == 0 and ya == fa * h and fa >= prm.fb_taken:
                    if decide_frame(net, fa, acc, prm.cap_fs) != 1:
                        over = prm.end == END_OVERFLOW
                        break
                first, wait, ok, bad = reader_first(net, ka, side, a_prev, p_src, rat_cam)
                err |= bad
                if not ok:
                    break
                d_wait += wait
                lo = max(first, memory_first_cycle(ka, mem_hz, mem_bps))
                a = max(lo, free)
                if a * p_src >= cap:
                    break
                if stats == 1:
                    # starved waiting for the camera, then busy in every cycle but the
                    # blocked ones, lo .. a - 1
                    if first > a_prev + 1:
                        starved += first - a_prev - 1
                        n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy, first * p_src,
                                                 first * p_src, g)
                    if a > lo:
                        blocked += a - lo
                        n_gaps, last_busy = busy(gaps, blk, n_gaps,
                                                 (lo - 1) * p_src if lo > 0 else last_busy,
                                                 a * p_src, a * p_src, g)
                    last_busy = a * p_src
            ring[a_off + (ka & a_mask)] = a
            if left and xa == 0 and ya == fa * h and fb == 0:
                frame_in[fa] = a * p_src
            if fb > 0 and xa == w - 1 and ya == fa * h + h - 1:
                net.fbuf[1, fa] = a * p_src  # the reader is done with this frame's buffer
            a_prev = a
            ka += 1
            moved = True
            xa += 1
            if xa == w:
                xa = 0
                ya += 1
                if ya == (fa + 1) * h:
                    fa += 1
        if over or not moved:
            break
    sa.count, sb.count = ka, kb
    acc.blocked += blocked
    acc.starved += starved
    acc.dram += d_wait
    acc.last_busy, acc.gaps = last_busy, n_gaps
    net.acc[len(net.blocks) + tl.src_fifo].empty += empty
    if over and fb == 0:
        acc.over_cycle, acc.over_k, acc.over_tile = (
            camera_cycle(fa, xa, ya - fa * h, line_clocks, frame_clocks, prm.pairs), ka,
            side)
        prm.end = END_OVERFLOW
    if err:
        prm.error = ERR_RING
    if n_gaps > gaps.shape[1]:
        prm.error = ERR_GAPS
    return ka > start_a or kb > start_b


@njit(cache=True)
def pending_overflow(net, side):
    """After a pass in which nothing moves: a camera whose next pixel's slot never frees (or
    frees only beyond the cap) overflows when that pixel arrives, if before the cap."""
    prm = net.prm[0]
    ring, streams = net.ring, net.streams
    st = streams[net.tiles[side * prm.parts].a]
    k = st.count
    if prm.camera == 0 or k >= st.n:
        return
    w, parts = prm.w, prm.parts
    y = k // w
    x = k - y * w
    fr = y // prm.h
    y -= fr * prm.h
    a = camera_cycle(fr, x, y, prm.line_clocks, prm.frame_clocks, prm.pairs)
    if a * st.period >= prm.cap_fs:
        return
    for t in range(parts):
        ti = side * parts + t
        tl = net.tiles[ti]
        if not (tl.ix0 <= x < tl.ix1 and tl.iy0 <= y < tl.iy1):
            continue
        f = net.fifos[tl.src_fifo]
        j = fr * tl.n_in + (y - tl.iy0) * tl.iw + x - tl.ix0 - f.depth
        if j >= 0:
            b_off, b_mask, nb, _ = view(streams, tl.b)
            if j >= nb or seen_from_scaled(rd(ring, b_off, b_mask, j), f.per_dst, f.per_src,
                                           ratio(f.per_dst, f.per_src), f.space_edges) > a:
                acc = net.acc[st.block]
                acc.over_cycle, acc.over_k, acc.over_tile = a, k, ti
                prm.end = END_OVERFLOW
                return


# ---- the NNA submodules -------------------------------------------------------------------------


@njit(cache=True, inline="always")
def advance_pops(net, ti):
    """Line-buffer pops of tile ``ti``, as far as its source and its MAC array allow."""
    prm = net.prm[0]
    ring, streams = net.ring, net.streams
    tl = net.tiles[ti]
    b_off, b_mask, i, _ = view(streams, tl.b)
    e_off, e_mask, ne, e_lo = view(streams, tl.e)
    a_off, a_mask, na, a_lo = view(streams, tl.a)
    st = streams[tl.b]
    f = net.fifos[tl.src_fifo]
    per_src, per_dst, de = f.per_src, f.per_dst, f.data_edges
    rat = ratio(per_src, per_dst)
    per, cap, w, n = st.period, prm.cap_fs, prm.w, prm.n
    rows, half, top_halo = prm.rows, prm.half, tl.top_halo
    iw, ow, iy0, ix0, oh = tl.iw, tl.ow, tl.iy0, tl.ix0, tl.y1 - tl.y0
    in_rows = tl.iy1 - tl.iy0
    left = tl.side == 0
    row_fs = net.rows[0]
    per_nna = prm.per_nna
    err = False
    start = i
    b_prev = rd(ring, b_off, b_mask, i - 1) if i > 0 else -1
    need_row = -1
    room = 0
    empty = 0
    r = i // iw  # the tile's input row over the stream: row rl of frame fr
    c = i - r * iw
    fr = r // in_rows
    rl = r - fr * in_rows
    k = fr * n + (iy0 + rl) * w + ix0 + c  # the source's pixel
    while i < st.n:
        if r != need_row:
            started = nna_rows_started_before_input(r, rows, half, top_halo, oh, in_rows)
            if started > 0:
                j = started * ow - 1
                if j >= ne:
                    break
                err |= j <= e_lo
                room = rd(ring, e_off, e_mask, j) + 1
            else:
                room = 0
            need_row = r
        if k >= na:
            break
        err |= k <= a_lo
        vis = seen_from_scaled(rd(ring, a_off, a_mask, k), per_src, per_dst, rat, de)
        b = max(b_prev + 1, vis, room)
        if b * per >= cap:
            break
        if vis > b_prev + 1:
            empty += vis - b_prev - 1
        ring[b_off + (i & b_mask)] = b
        if c == 0:
            net.occ[2 * ti, r & (net.occ.shape[1] - 1)] = b
        b_prev = b
        i += 1
        c += 1
        k += 1
        if c == iw:
            if left and fr == 0:
                # the frame's row y is in once every left tile that takes it has it
                t_fs = b * per_nna
                if t_fs > row_fs[iy0 + rl + 1]:
                    row_fs[iy0 + rl + 1] = t_fs
            c = 0
            r += 1
            rl += 1
            k += w - iw
            if rl == in_rows:
                rl = 0
                fr += 1
                k = fr * n + iy0 * w + ix0
    st.count = i
    net.acc[len(net.blocks) + tl.src_fifo].empty += empty
    if err:
        prm.error = ERR_RING
    return i > start


@njit(cache=True, inline="always")
def advance_pushes(net, ti):
    """MAC-array pushes of tile ``ti``, as far as its input rows and the free slots allow."""
    prm = net.prm[0]
    ring, streams = net.ring, net.streams
    tl = net.tiles[ti]
    b_off, b_mask, nb, b_lo = view(streams, tl.b)
    e_off, e_mask, j, _ = view(streams, tl.e)
    st = streams[tl.e]
    f = net.fifos[tl.out_fifo]
    p_off, p_mask, npop, p_lo = view(streams, f.pop)
    depth, per_src, per_dst, se = f.depth, f.per_src, f.per_dst, f.space_edges
    rat = ratio(per_dst, per_src)
    per, cap, w, cpd, half, h = st.period, prm.cap_fs, prm.w, prm.cpd, prm.half, prm.h
    ow, iw, y0, x0, iy0, n_out, n_in = tl.ow, tl.iw, tl.y0, tl.x0, tl.iy0, tl.n_out, tl.n_in
    out_rows, n = tl.y1 - tl.y0, prm.n
    merge = prm.merge == 1
    err = False
    start = j
    e_prev = rd(ring, e_off, e_mask, j - 1) if j > 0 else -1
    rows_row = -1
    rows_in = 0
    r = j // ow  # the tile's output row over the stream: row rl of frame fr
    c = j - r * ow
    fr = r // out_rows
    rl = r - fr * out_rows
    while j < st.n:
        if r != rows_row:
            need = fr * n_in + (nna_last_input_row(y0 + rl, half, h) - iy0 + 1) * iw
            if need > nb:
                break
            err |= need - 1 <= b_lo
            rows_in = rd(ring, b_off, b_mask, need - 1) + 1
            rows_row = r
        free = 0
        if j >= depth:
            jj = j - depth
            if merge:  # its raster index in the merge
                fj = jj // n_out
                jl = jj - fj * n_out
                rr = jl // ow
                jj = fj * n + (y0 + rr) * w + x0 + jl - rr * ow
            if jj >= npop:
                break
            err |= jj <= p_lo
            free = seen_from_scaled(rd(ring, p_off, p_mask, jj), per_dst, per_src, rat, se)
        s_j = max(e_prev + 1, rows_in)
        e = max(s_j + cpd - 1, free)
        if e * per >= cap:
            break
        ring[e_off + (j & e_mask)] = e
        e_prev = e
        j += 1
        c += 1
        if c == ow:
            net.occ[2 * ti + 1, r & (net.occ.shape[1] - 1)] = e
            c = 0
            r += 1
            rl += 1
            if rl == out_rows:
                rl = 0
                fr += 1
    st.count = j
    if err:
        prm.error = ERR_RING
    return j > start


@njit(cache=True, inline="always")
def advance_merge(net, side, m_s):
    """The merge of ``side``: descriptor m (raster order) moves from its owner tile's FIFO to
    the SVA's in one cycle, once visible there and with a free slot."""
    prm = net.prm[0]
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
    # per tile: output region, ring of its pushes, its merge FIFO's latency, empty, last pop
    tab = net.scratch
    nb = len(net.blocks)
    for t in range(parts):
        tl = net.tiles[side * parts + t]
        e = streams[tl.e]
        fin = net.fifos[tl.out_fifo]
        tab[t, 0], tab[t, 1], tab[t, 2], tab[t, 3], tab[t, 4] = tl.x0, tl.x1, tl.y0, tl.y1, tl.ow
        tab[t, 5], tab[t, 6], tab[t, 7], tab[t, 8] = e.off, e.mask, e.count, e.count - 1 - e.mask
        tab[t, 9] = fin.data_edges
        tab[t, 10] = net.acc[nb + tl.out_fifo].empty
        tab[t, 11] = net.acc[nb + tl.out_fifo].last_pop
        tab[t, 12] = tl.n_out
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
        while not (tab[t, 0] <= x < tab[t, 1] and tab[t, 2] <= y < tab[t, 3]):
            t += 1
        j = fr * tab[t, 12] + (y - tab[t, 2]) * tab[t, 4] + x - tab[t, 0]
        if j >= tab[t, 7]:
            break
        free = 0
        if m >= depth:
            if m - depth >= npop:
                break
            err |= m - depth <= p_lo
            free = seen_from_scaled(rd(ring, p_off, p_mask, m - depth), per_dst, per_src, rat,
                                    se)
        err |= j <= tab[t, 8]
        vis = ring[tab[t, 5] + (j & tab[t, 6])] + tab[t, 9]  # (one domain)
        mg = max(mg_prev + 1, vis, free)
        if mg * per >= cap:
            break
        if stats == 1:
            starved += max(0, vis - mg_prev - 1)
            blocked += mg - max(vis, mg_prev + 1)
            tab[t, 10] += max(0, vis - tab[t, 11] - 1)
            tab[t, 11] = mg
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
        net.acc[nb + f].empty = tab[t, 10]
        net.acc[nb + f].last_pop = tab[t, 11]
    acc.starved += starved
    acc.blocked += blocked
    acc.last_busy, acc.gaps = last_busy, n_gaps
    if err:
        prm.error = ERR_RING
    if n_gaps > gaps.shape[1]:
        prm.error = ERR_GAPS
    return m > start


# ---- the SVA and the sink -----------------------------------------------------------------------


@njit(cache=True, inline="always")
def advance_sva_pops(net, p_s, f_left, f_right):
    """The SVA's joint pops, as far as both descriptor streams and its row window (released as
    output rows are issued) allow."""
    prm = net.prm[0]
    ring, streams = net.ring, net.streams
    fl, fr = net.fifos[f_left], net.fifos[f_right]
    l_off, l_mask, nl, l_lo = view(streams, fl.push)
    r_off, r_mask, nr, r_lo = view(streams, fr.push)
    p_off, p_mask, j, _ = view(streams, p_s)
    n_issued = streams[p_s + 3].count
    st = streams[p_s]
    n, w, per, cap, la = st.n, prm.w, st.period, prm.cap_fs, prm.lookahead
    l_src, l_dst, l_de = fl.per_src, fl.per_dst, fl.data_edges
    r_src, r_dst, r_de = fr.per_src, fr.per_dst, fr.data_edges
    l_rat, r_rat = ratio(l_src, l_dst), ratio(r_src, r_dst)
    err = False
    start = j
    p_prev = rd(ring, p_off, p_mask, j - 1) if j > 0 else -1
    window_row = -1
    window = 0
    empty_l = 0
    empty_r = 0
    occ = net.occ
    occ_in = occ.shape[0] - 2
    occ_out = occ.shape[0] - 1
    known = min(n, nl, nr)
    y = j // w
    x = j - y * w
    while j < known:
        if y != window_row:
            done = sva_rows_done_before_input(y, la)
            if done > 0:
                if done * w > n_issued:
                    break
                # the cycle after its last issue
                window = occ[occ_out, (done - 1) & (occ.shape[1] - 1)] + 1
            else:
                window = 0
            window_row = y
        err |= j <= l_lo or j <= r_lo
        vl = seen_from_scaled(rd(ring, l_off, l_mask, j), l_src, l_dst, l_rat, l_de)
        vr = seen_from_scaled(rd(ring, r_off, r_mask, j), r_src, r_dst, r_rat, r_de)
        p = max(p_prev + 1, vl, vr, window)
        if p * per >= cap:
            break
        empty_l += max(0, vl - p_prev - 1)
        empty_r += max(0, vr - p_prev - 1)
        ring[p_off + (j & p_mask)] = p
        if x == 0:
            occ[occ_in, y & (occ.shape[1] - 1)] = p
        p_prev = p
        j += 1
        x += 1
        if x == w:
            x = 0
            y += 1
    st.count = j
    nb = len(net.blocks)
    net.acc[nb + f_left].empty += empty_l
    net.acc[nb + f_right].empty += empty_r
    if err:
        prm.error = ERR_RING
    return j > start


# ---- the pass -----------------------------------------------------------------------------------


@njit(cache=True)
def run_pass(net, ids):
    """Advance every stream in turn until the sink has the frame, nothing can move, a camera
    overflows or a ring error stops the pass; the walkers follow whenever a stream has gone a
    quarter of its ring ahead of them, and at the end. ``ids`` = (P stream, left and right SVA
    FIFOs, sink FIFO). Sets ``prm.end``."""
    prm = net.prm[0]
    streams = net.streams
    p_s, f_left, f_right, f_sink = ids[0], ids[1], ids[2], ids[3]
    q_s = p_s + 2
    sides = prm.sides  # 1: the right side's events are the left's
    n_tiles = sides * prm.parts
    n_streams = streams.shape[0]
    walked = np.zeros(n_streams, np.int64)
    while True:
        prm.iterations += 1
        moved = False
        if prm.parts == 1:
            for side in range(sides):
                moved |= advance_whole_side(net, side)
        else:
            for side in range(sides):
                moved |= advance_source(net, side)
            for ti in range(n_tiles):
                moved |= advance_pops(net, ti)
        for ti in range(n_tiles):
            moved |= advance_pushes(net, ti)
        if prm.merge == 1:
            for side in range(sides):
                m_s = net.fifos[net.tiles[side * prm.parts].out_fifo].pop
                moved |= advance_merge(net, side, m_s)
        moved |= advance_sva_pops(net, p_s, f_left, f_right)
        moved |= advance_sva_out_and_sink(net, p_s, f_sink)
        if prm.error != 0:
            return
        if prm.stats == 1:
            due = False
            for s in range(n_streams):
                if streams[s].count - walked[s] > (streams[s].mask + 1) // 4:
                    due = True
            if due:
                walk_all(net, False)
                for s in range(n_streams):
                    walked[s] = streams[s].count
        if streams[q_s].count >= prm.target:  # every frame taken is out
            prm.end = END_DONE
            break
        if not moved:
            if prm.end != END_OVERFLOW:
                for side in range(sides):
                    pending_overflow(net, side)
            if prm.end != END_OVERFLOW:
                prm.end = END_STUCK if prm.cap_fs >= INF else END_CAP
            break
    if prm.stats == 1:
        walk_all(net, True)
