"""An NNA submodule (one tile of a camera) on the compiled engine: its line buffer's pops and its
MAC array's pushes (twin of the readable kernel's :mod:`sim.cycle.readable.blocks.nna`:
:class:`~sim.cycle.readable.blocks.nna.LineBuffer`,
:class:`~sim.cycle.readable.blocks.nna.MacArray`,
:class:`~sim.cycle.readable.blocks.nna.NnaSubmodule`; the rules are :mod:`sim.cycle.rules`).

Streams, per tile:

- ``LINE_POP``: the line buffer pops input pixel i (row r of the tile's input region)
  ``b[i] = max(b[i-1] + 1, vis(a[k]), room(r))``, ``room(r)`` the cycle after the MAC array
  pushed the last descriptor of the output rows that must have started before row r
  (:func:`~sim.cycle.rules.nna_rows_started_before_input`);
- ``MAC_PUSH``: the MAC array pushes descriptor j (output row y) ``e[j] = max(s_j + cpd - 1,
  free(p[j - depth]))``, started at ``s_j = max(e[j-1] + 1, b[last pixel of
  nna_last_input_row(y)] + 1)`` (cpd the cycles per descriptor).

Here also: the submodule's statistics (:func:`walk_nna`: the MAC array waits for input rows --
starved -- and holds a finished descriptor -- blocked; a pop in such a cycle makes it busy), and
what it reports at an instant (status, traced signals).
"""

from __future__ import annotations

from numba import njit

from stereosim.sim.cycle.compiled.layout import (
    A_BLOCKED,
    A_BUSY,
    A_IDLE,
    A_STARVED,
    ERR_GAPS,
    ERR_RING,
    INF,
)
from stereosim.sim.cycle.compiled.ring import (
    busy,
    catch_up,
    event,
    lt_at,
    pops_in,
    ratio,
    rd,
    view,
)
from stereosim.sim.cycle.rules import (
    frame_row,
    nna_last_input_row,
    nna_rows_started_before_input,
    seen_from_scaled,
)

# ---- the line buffer's pops ---------------------------------------------------------------------


@njit(cache=True, inline="always")
def line_room(ring, e, r, geometry):
    """(room, known, ring error): the first cycle the line buffer may take the tile's input row
    r (over the stream) -- the cycle after the MAC array pushed the last descriptor of the
    output rows that must have started before it (the readable ``LineBuffer.evaluate``); not
    known while that push is not. ``e`` = (offset, mask, known, highest index lost) of the MAC
    pushes; ``geometry`` = (buffer rows, window half, top halo, output rows, input rows, output
    row width)."""
    e_off, e_mask, ne, e_lo = e
    rows, half, top_halo, out_rows, in_rows, ow = geometry
    started = nna_rows_started_before_input(r, rows, half, top_halo, out_rows, in_rows)
    if started > 0:
        j = started * ow - 1
        if j >= ne:
            return 0, False, False
        return rd(ring, e_off, e_mask, j) + 1, True, j <= e_lo
    return 0, True, False

@njit(cache=True, inline="always")
def advance_line_pops(net, ti):
    """Line-buffer pops of tile ``ti``, as far as its source and its MAC array allow."""
    prm = net.prm[0]
    state = net.state[0]
    ring, streams = net.ring, net.streams
    tl = net.tiles[ti]
    b_off, b_mask, i, _ = view(streams, tl.line_pop)
    e_off, e_mask, ne, e_lo = view(streams, tl.mac_push)
    a_off, a_mask, na, a_lo = view(streams, tl.source_push)
    st = streams[tl.line_pop]
    f = net.fifos[tl.src_fifo]
    per_src, per_dst, de = f.per_src, f.per_dst, f.data_edges
    rat = ratio(per_src, per_dst)
    per, cap, w, n = st.period, prm.cap_fs, prm.w, prm.n
    rows, half, top_halo = prm.rows, prm.half, tl.top_halo
    iw, ow, iy0, ix0, oh = tl.iw, tl.ow, tl.iy0, tl.ix0, tl.y1 - tl.y0
    in_rows = tl.iy1 - tl.iy0
    geometry = (rows, half, top_halo, oh, in_rows, ow)
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
            room, ok, bad = line_room(ring, (e_off, e_mask, ne, e_lo), r, geometry)
            if not ok:
                break
            err |= bad
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
            net.occ[tl.occ_in, r & (net.occ.shape[1] - 1)] = b
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
        state.error = ERR_RING
    return i > start


# ---- the pops of a whole-frame tile (taken in turn with its source's pushes) --------------------


@njit(cache=True, inline="always")
def whole_pops_begin(net, side):
    """What :func:`whole_pops` reads of the line buffer of a camera served by one submodule:
    the constants of its loop and its cursor (pops known, the last pop, its pixel, the room of
    its row, the FIFO's empty cycles, a ring error)."""
    prm = net.prm[0]
    tl = net.tiles[side]
    a_off, a_mask, _, _ = view(net.streams, tl.source_push)
    b_off, b_mask, kb, _ = view(net.streams, tl.line_pop)
    e = view(net.streams, tl.mac_push)
    f = net.fifos[tl.src_fifo]
    oh = tl.y1 - tl.y0
    k = (a_off, a_mask, b_off, b_mask, e, f.per_src, f.per_dst, ratio(f.per_src, f.per_dst),
         f.data_edges, (prm.rows, prm.half, 0, oh, prm.h, prm.w), tl.occ_in, side)
    b_prev = rd(net.ring, b_off, b_mask, kb - 1) if kb > 0 else -1
    return k, (kb, b_prev, kb % prm.w, kb // prm.w, -1, 0, 0, False)


@njit(cache=True, inline="always")
def whole_pops(net, k, cur, ka):
    """The line buffer's pops of what the source pushed (``ka`` pushes known), while its rows
    have room. Returns (cursor, moved)."""
    prm = net.prm[0]
    ring, occ, row_fs = net.ring, net.occ, net.rows[0]
    a_off, a_mask, b_off, b_mask, e, p_src, p_nna, rat_in, de, geometry, occ_in, side = k
    kb, b_prev, xb, yb, room_row, room, empty, err = cur
    w, h, cap = prm.w, prm.h, prm.cap_fs
    moved = False
    while kb < ka:
        if yb != room_row:
            room, ok, bad = line_room(ring, e, yb, geometry)
            if not ok:
                break
            err |= bad
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
            if side == 0 and yb < h and b * p_nna > row_fs[yb + 1]:
                row_fs[yb + 1] = b * p_nna
            xb = 0
            yb += 1
    return (kb, b_prev, xb, yb, room_row, room, empty, err), moved


@njit(cache=True, inline="always")
def whole_pops_end(net, k, cur):
    """Store what :func:`whole_pops` did: the pops known, the FIFO's empty cycles."""
    kb, _, _, _, _, _, empty, err = cur
    tl = net.tiles[k[11]]
    net.streams[tl.line_pop].count = kb
    net.acc[len(net.blocks) + tl.src_fifo].empty += empty
    if err:
        net.state[0].error = ERR_RING


# ---- the MAC array's pushes ---------------------------------------------------------------------


@njit(cache=True, inline="always")
def advance_mac_pushes(net, ti):
    """MAC-array pushes of tile ``ti``, as far as its input rows and the free slots allow."""
    prm = net.prm[0]
    state = net.state[0]
    ring, streams = net.ring, net.streams
    tl = net.tiles[ti]
    b_off, b_mask, nb, b_lo = view(streams, tl.line_pop)
    e_off, e_mask, j, _ = view(streams, tl.mac_push)
    st = streams[tl.mac_push]
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
            net.occ[tl.occ_out, r & (net.occ.shape[1] - 1)] = e
            c = 0
            r += 1
            rl += 1
            if rl == out_rows:
                rl = 0
                fr += 1
    st.count = j
    if err:
        state.error = ERR_RING
    return j > start



# ---- statistics ---------------------------------------------------------------------------------


@njit(cache=True)
def walk_nna(net, ti, final):
    """Settle the activity of tile ``ti``'s descriptors whose every event is known (``final``:
    the streams have stopped; a descriptor still pending works, then waits for ever). A gap in
    the block's busy instants can only lie in a wait (for rows or for a slot), so those are the
    only places it is looked for."""
    prm = net.prm[0]
    state = net.state[0]
    ring = net.ring
    gaps = net.gaps
    tl = net.tiles[ti]
    blk = tl.block
    a = net.acc[blk]
    b_off, b_mask, nb, b_lo = view(net.streams, tl.line_pop)
    b_pops = (b_off, b_mask, nb)
    e_off, e_mask, ne, e_lo = view(net.streams, tl.mac_push)
    cpd, half, h, g = prm.cpd, prm.half, prm.h, prm.watchdog_fs
    per = net.blocks[blk].period
    ow, iw, y0, iy0, n_in = tl.ow, tl.iw, tl.y0, tl.iy0, tl.n_in
    out_rows = tl.y1 - tl.y0
    n_out, n_in_all = net.streams[tl.mac_push].n, net.streams[tl.line_pop].n  # over the stream
    j, ptr, prev = a.walk, a.ptr, a.prev
    last_busy, n_gaps = a.last_busy, a.gaps
    # every pop before cycle `known_until` is known (all of them once the streams have stopped)
    known_until = INF if nb >= n_in_all or final else (rd(ring, b_off, b_mask, nb - 1) + 1
                                                       if nb > 0 else 0)
    err = j < ne and j <= e_lo
    starved = 0
    blocked = 0
    r = j // ow  # the tile's output row over the stream
    c = j - r * ow
    rows_row = -1
    rows_in = INF
    while j < n_out:
        if r != rows_row:
            fr = r // out_rows
            need = fr * n_in + (nna_last_input_row(y0 + r - fr * out_rows, half, h) - iy0
                                + 1) * iw
            rows_in = rd(ring, b_off, b_mask, need - 1) + 1 if need <= nb else INF
            rows_row = r
        s_j = max(prev + 1, rows_in)
        done = s_j + cpd - 1
        if j >= ne:
            if final:
                ptr, lost = catch_up(ring, b_off, b_mask, ptr, b_lo + 1, prev + 1)
                err |= lost
                long = s_j == INF or (s_j - prev) * per > g
                ptr, _, n_gaps, last_busy = pops_in(ring, b_pops, ptr, prev + 1, s_j, long, gaps,
                                                     (blk, n_gaps, last_busy, per, g))
                if s_j < INF:
                    n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy, s_j * per,
                                              done * per, g)
                    _, _, n_gaps, last_busy = pops_in(ring, b_pops, ptr, done + 1, INF, True, gaps,
                                                       (blk, n_gaps, last_busy, per, g))
            break
        e = rd(ring, e_off, e_mask, j)
        if e > known_until:
            break  # a pop before e may still come
        if s_j > prev + 1:  # waiting for the row's input (phase 0)
            ptr, lost = catch_up(ring, b_off, b_mask, ptr, b_lo + 1, prev + 1)
            err |= lost
            long = (s_j - prev) * per > g
            ptr, cnt, n_gaps, last_busy = pops_in(ring, b_pops, ptr, prev + 1, s_j, long, gaps,
                                                   (blk, n_gaps, last_busy, per, g))
            starved += s_j - prev - 1 - cnt
            n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy, s_j * per, done * per, g)
        if e > done + 1:  # the finished descriptor held for a free slot
            ptr, lost = catch_up(ring, b_off, b_mask, ptr, b_lo + 1, done + 1)
            err |= lost
            long = (e - done) * per > g
            ptr, cnt, n_gaps, last_busy = pops_in(ring, b_pops, ptr, done + 1, e, long, gaps,
                                                   (blk, n_gaps, last_busy, per, g))
            blocked += e - done - 1 - cnt
            n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy, e * per, e * per, g)
        last_busy = e * per  # busy through its MAC cycles and its push
        prev = e
        j += 1
        c += 1
        if c == ow:
            c = 0
            r += 1
    a.walk, a.ptr, a.prev = j, ptr, prev
    a.starved += starved
    a.blocked += blocked
    a.last_busy, a.gaps = last_busy, n_gaps
    if err:
        state.error = ERR_RING
    if n_gaps > gaps.shape[1]:
        state.error = ERR_GAPS



# ---- at an instant ------------------------------------------------------------------------------


@njit(cache=True)
def mac_start(ring, streams, prm, tl, j):
    """The cycle the MAC array starts descriptor j of tile ``tl`` (INF: its rows are not in)."""
    r = j // tl.ow
    out_rows = tl.y1 - tl.y0
    fr = r // out_rows
    need = fr * tl.n_in + (nna_last_input_row(tl.y0 + r - fr * out_rows, prm.half, prm.h)
                           - tl.iy0 + 1) * tl.iw
    rows_in = event(ring, streams[tl.line_pop], need - 1)
    if rows_in == INF:
        return INF
    prev = event(ring, streams[tl.mac_push], j - 1) if j > 0 else -1
    return max(prev + 1, rows_in + 1)



@njit(cache=True)
def status_nna(ring, streams, cursors, prm, tl, c):
    received, pop_at = lt_at(ring, streams[tl.line_pop], cursors[tl.line_pop], c)
    emitted, push_at = lt_at(ring, streams[tl.mac_push], cursors[tl.mac_push], c)
    moved = pop_at
    mac_blocked = False
    n_out, n_in = prm.frames * tl.n_out, prm.frames * tl.n_in
    if emitted < n_out:
        s_j = mac_start(ring, streams, prm, tl, emitted)
        if c >= s_j:
            if c <= s_j + prm.cpd - 1 or push_at:
                moved = True
            else:
                mac_blocked = True
    if moved:
        return A_BUSY, -1
    if mac_blocked:
        return A_BLOCKED, tl.out_fifo
    if emitted < n_out or received < n_in:
        return A_STARVED, tl.src_fifo
    return A_IDLE, -1



@njit(cache=True)
def sample_nna(ring, streams, cursors, prm, tl, data, c, out):
    """The NNA's signals after its cycle c into out[0:7]; ``data``: the traced frames'
    descriptors."""
    received = cursors[tl.line_pop]
    emitted, push_at = lt_at(ring, streams[tl.mac_push], cursors[tl.mac_push], c)
    if push_at:
        emitted += 1
    in_rows, out_rows = tl.iy1 - tl.iy0, tl.y1 - tl.y0
    f_in, r_in = frame_row(received // tl.iw, in_rows, prm.frames)
    f_out, r_out = frame_row(emitted // tl.ow, out_rows, prm.frames)
    y_out = tl.y0 + r_out
    oldest = f_out * in_rows + max(0, y_out - prm.half - tl.iy0)
    phase = 0
    if not push_at and emitted < prm.frames * tl.n_out:
        s_j = mac_start(ring, streams, prm, tl, emitted)
        if c >= s_j:
            phase = c - s_j + 1 if c < s_j + prm.cpd - 1 else prm.cpd
    out[0] = tl.iy0 + r_in
    out[1] = max(0, f_in * in_rows + r_in - oldest)
    out[2] = phase
    out[3] = y_out
    out[4] = tl.x0 + emitted % tl.ow
    out[5] = 1 if push_at else 0
    value = 0
    if emitted > 0:
        j = emitted - 1
        fr = j // tl.n_out
        j -= fr * tl.n_out
        r = j // tl.ow
        value = data.desc[fr - data.frame0, tl.side, tl.y0 + r, tl.x0 + j - r * tl.ow]
    out[6] = value

