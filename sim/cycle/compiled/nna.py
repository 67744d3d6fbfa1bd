"""An NNA submodule (one tile of a camera) on the compiled engine: a pipeline of layers, each a
line buffer and a MAC array (twin of the readable kernel's :mod:`sim.cycle.readable.blocks.nna`:
:class:`~sim.cycle.readable.blocks.nna.LineBuffer`,
:class:`~sim.cycle.readable.blocks.nna.MacArray`,
:class:`~sim.cycle.readable.blocks.nna.NnaSubmodule`; the rules are :mod:`sim.cycle.rules`, its
FIFOs' :mod:`sim.cycle.fifo.rule`).
One layer (and the census) is one stage: the same streams, loops and walker as ever.

Streams, per tile (layer l of L, its record ``Net.layers``: regions, h_l, rows_l, II_l):

- ``LINE_POP``: layer 0's line buffer pops input pixel i (row r of the tile's input region)
  ``b[i] = max(b[i-1] + 1, vis(a[k]), room_0(r))``, ``room_l(r)`` the cycle after layer l's
  MAC array let the last output of the output rows that must have started before row r leave
  (:func:`~sim.cycle.rules.nna_rows_started_before_input`, :func:`line_room`);
- ``LAYER_PUSH`` (l < L - 1) and ``MAC_PUSH`` (the last layer): layer l's output k (output row
  y) starts at ``s_k = max(e[k-1] + 1, in_l[last item of nna_last_input_row(y, h_l)] + 1)``
  (``in_l``: layer 0's pops, else layer l - 1's outputs), finishes at ``f_k = s_k + II_l - 1``
  and leaves at ``e[k] = max(f_k, room_l+1(k // W_l))`` into the next layer's line buffer, or,
  the last layer, ``max(f_k, free(p[k - depth]))`` into the tile's FIFO
  (:func:`advance_layer`, layer after layer).

Here also: the submodule's statistics -- one layer: :func:`walk_nna` (the MAC array waits for
input rows -- starved -- and holds a finished descriptor -- blocked; a pop in such a cycle
makes it busy); several: :func:`walk_layers`, for each layer and the submodule --, and what it
reports at an instant (status, traced signals, per layer).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from stereosim.core.kernel_cache import njit, njit_borrowing
from stereosim.nna.submodule.timing import mac_done
from stereosim.sim.cycle.compiled.layout import (
    A_BLOCKED,
    A_BUSY,
    A_IDLE,
    A_STARVED,
    ERR_RING,
    INF,
)
from stereosim.sim.cycle.compiled.ring import (
    BusyWatch,
    busy,
    event,
    lt_at,
    note_wait,
    pops_in,
    ratio,
    rd,
    store_activity,
    view,
)
from stereosim.sim.cycle.fifo.rule import room_from, visible_from
from stereosim.sim.cycle.rules import (
    frame_row,
    nna_last_input_row,
    nna_rows_started_before_input,
)

# ---- the line buffer's pops ---------------------------------------------------------------------


class LineGeometry(NamedTuple):
    """What :func:`line_room` reads of a layer's line buffer: its rows, the window's half
    height, the top halo, the layer's output rows (a frame's) and output row width, and the
    rows of a frame of its input (the tile's input region, or the layer before's output)."""

    rows: int
    half: int
    top_halo: int
    out_rows: int
    out_width: int
    in_rows: int


@njit(cache=True, inline="always")
def line_geometry(lr, in_rows):
    """The :class:`LineGeometry` of layer ``lr`` (its record), taking ``in_rows`` rows a
    frame."""
    return LineGeometry(rows=lr.rows, half=lr.half, top_halo=lr.top_halo,
                        out_rows=lr.y1 - lr.y0, out_width=lr.ow, in_rows=in_rows)


@njit(cache=True, inline="always")
def line_room(ring, e, r, geometry):
    """(room, known, ring error): the first cycle the line buffer may take the tile's input row
    r (over the stream) -- the cycle after the MAC array pushed the last descriptor of the
    output rows that must have started before it (the readable ``LineBuffer.evaluate``); not
    known while that push is not. ``e`` = (offset, mask, known, highest index lost) of the MAC
    pushes; ``geometry`` a :class:`LineGeometry`."""
    e_off, e_mask, ne, e_lo = e
    started = nna_rows_started_before_input(r, geometry.rows, geometry.half, geometry.top_halo,
                                            geometry.out_rows, geometry.in_rows)
    if started > 0:
        j = started * geometry.out_width - 1
        if j >= ne:
            return 0, False, False
        return rd(ring, e_off, e_mask, j) + 1, True, j <= e_lo
    return 0, True, False

@njit_borrowing(cache=True)
def advance_line_pops(net, ti):
    """Line-buffer pops of tile ``ti``, as far as its source and its MAC array allow."""
    prm = net.prm[0]
    state = net.state[0]
    ring, streams = net.ring, net.streams
    tl = net.tiles[ti]
    b_off, b_mask, i, _ = view(streams, tl.line_pop)
    lr = net.layers[tl.layer0]  # the first layer: its outputs make room in its line buffer
    e_off, e_mask, ne, e_lo = view(streams, lr.out_stream)
    a_off, a_mask, na, a_lo = view(streams, tl.source_push)
    st = streams[tl.line_pop]
    f = net.fifos[tl.src_fifo]
    per_src, per_dst, de = f.per_src, f.per_dst, f.data_edges
    rat = ratio(per_src, per_dst)
    per, cap, w, n = st.period, prm.cap_fs, prm.w, prm.n
    iw, iy0, ix0 = tl.iw, tl.iy0, tl.ix0
    in_rows = tl.iy1 - tl.iy0
    geometry = line_geometry(lr, in_rows)
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
        vis = visible_from(rd(ring, a_off, a_mask, k), per_src, per_dst, rat, de)
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


class WholePops(NamedTuple):
    """The constants of :func:`whole_pops`' loop (the line buffer of a camera served by one
    submodule): the rings of the source's pushes and of its pops, the view of the MAC
    array's pushes (:func:`~.ring.view`), the FIFO's clock periods (fs), their ratio and its
    data edges, the line buffer's :class:`LineGeometry`, its occupancy row and its side."""

    push_off: int
    push_mask: int
    pop_off: int
    pop_mask: int
    macs: tuple  # (offset, mask, known, highest index lost) of the MAC array's pushes
    per_src: int
    per_nna: int
    rat_in: float  # per_src / per_nna (visible_from's ratio)
    data_edges: int
    geometry: LineGeometry
    occ_in: int
    side: int


class PopCursor(NamedTuple):
    """Where :func:`whole_pops` stands: the pops known, the last pop (cycle), the next pop's
    column and row over the stream, the row whose room is known (-1: none) and that room, the
    FIFO's empty cycles so far and a ring error."""

    pops: int
    last_pop: int
    x: int
    row: int
    room_row: int
    room: int
    empty: int
    ring_error: bool


@njit(cache=True, inline="always")
def whole_pops_begin(net, side):
    """What :func:`whole_pops` reads of the line buffer of a camera served by one submodule:
    the constants of its loop (a :class:`WholePops`) and its cursor (a :class:`PopCursor`)."""
    prm = net.prm[0]
    tl = net.tiles[side]
    lr = net.layers[tl.layer0]  # the first layer: its outputs make room in its line buffer
    a_off, a_mask, _, _ = view(net.streams, tl.source_push)
    b_off, b_mask, kb, _ = view(net.streams, tl.line_pop)
    f = net.fifos[tl.src_fifo]
    k = WholePops(push_off=a_off, push_mask=a_mask, pop_off=b_off, pop_mask=b_mask,
                  macs=view(net.streams, lr.out_stream), per_src=f.per_src, per_nna=f.per_dst,
                  rat_in=ratio(f.per_src, f.per_dst), data_edges=f.data_edges,
                  geometry=line_geometry(lr, prm.h), occ_in=tl.occ_in, side=side)
    b_prev = rd(net.ring, b_off, b_mask, kb - 1) if kb > 0 else -1
    return k, PopCursor(pops=kb, last_pop=b_prev, x=kb % prm.w, row=kb // prm.w, room_row=-1,
                        room=0, empty=0, ring_error=False)


@njit(cache=True, inline="always")
def whole_pops(net, k, cur, ka):
    """The line buffer's pops of what the source pushed (``ka`` pushes known), while its rows
    have room, from the :class:`PopCursor` ``cur`` with the constants ``k`` (a
    :class:`WholePops`). Returns (cursor, moved)."""
    prm = net.prm[0]
    ring, occ, row_fs = net.ring, net.occ, net.rows[0]
    a_off, a_mask, b_off, b_mask = k.push_off, k.push_mask, k.pop_off, k.pop_mask
    e, geometry, occ_in, side = k.macs, k.geometry, k.occ_in, k.side
    p_src, p_nna, rat_in, de = k.per_src, k.per_nna, k.rat_in, k.data_edges
    kb, b_prev, xb, yb = cur.pops, cur.last_pop, cur.x, cur.row
    room_row, room, empty, err = cur.room_row, cur.room, cur.empty, cur.ring_error
    w, h, cap = prm.w, prm.h, prm.cap_fs
    moved = False
    while kb < ka:
        if yb != room_row:
            room, ok, bad = line_room(ring, e, yb, geometry)
            if not ok:
                break
            err |= bad
            room_row = yb
        vis = visible_from(rd(ring, a_off, a_mask, kb), p_src, p_nna, rat_in, de)
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
    return PopCursor(pops=kb, last_pop=b_prev, x=xb, row=yb, room_row=room_row, room=room,
                     empty=empty, ring_error=err), moved


@njit(cache=True, inline="always")
def whole_pops_end(net, k, cur):
    """Store what :func:`whole_pops` did: the pops known, the FIFO's empty cycles."""
    tl = net.tiles[k.side]
    net.streams[tl.line_pop].count = cur.pops
    net.acc[len(net.blocks) + tl.src_fifo].empty += cur.empty
    if cur.ring_error:
        net.state[0].error = ERR_RING


# ---- the MAC arrays' outputs --------------------------------------------------------------------


@njit_borrowing(cache=True)
def advance_layer(net, ti, li):
    """Outputs of layer ``li`` (its record) of tile ``ti`` as far as its input rows and the room
    after it allow: a layer before the last writes into the next layer's line buffer (room: its
    :func:`line_room`, row by row), the last pushes into the tile's FIFO (room: the slot a
    FIFO depth back, :func:`~sim.cycle.fifo.rule.room_from`, item by item). Output k starts at
    max(e[k-1] + 1, its input rows in), is done ``ii - 1`` cycles later and leaves once the
    room is there."""
    prm = net.prm[0]
    state = net.state[0]
    ring, streams, occ = net.ring, net.streams, net.occ
    tl = net.tiles[ti]
    lr = net.layers[li]
    last = li == tl.layer0 + tl.n_layers - 1
    b_off, b_mask, nb, b_lo = view(streams, lr.in_stream)
    out_s = tl.mac_push if last else lr.out_stream
    e_off, e_mask, j, _ = view(streams, out_s)
    st = streams[out_s]
    per, cap, w, h, n = st.period, prm.cap_fs, prm.w, prm.h, prm.n
    ii, half = lr.ii, lr.half
    # the output region (the last layer's: the tile's) and the input region
    ow, y0, x0, n_out, out_rows, occ_out = lr.ow, lr.y0, lr.x0, lr.n_out, lr.y1 - lr.y0, \
        lr.occ_out
    iw, iy0, n_in = lr.iw, lr.iy0, lr.n_in
    if last:
        ow, y0, x0, n_out, out_rows, occ_out = tl.ow, tl.y0, tl.x0, tl.n_out, tl.y1 - tl.y0, \
            tl.occ_out
        if li == tl.layer0:
            iw, iy0, n_in = tl.iw, tl.iy0, tl.n_in
    nx = net.layers[li + 1] if not last else lr  # its outputs make room in its line buffer
    nxt = view(streams, nx.out_stream)
    geometry = line_geometry(nx, out_rows)
    f = net.fifos[tl.out_fifo]
    p_off, p_mask, npop, p_lo = view(streams, f.pop)
    depth, per_src, per_dst, se = f.depth, f.per_src, f.per_dst, f.space_edges
    rat = ratio(per_dst, per_src)
    merge = prm.merge == 1
    occ_in, occ_mask = nx.occ_in, occ.shape[1] - 1
    err = False
    start = j
    e_prev = rd(ring, e_off, e_mask, j - 1) if j > 0 else -1
    rows_row = -1
    rows_in = 0
    room = 0
    r = j // ow  # the output row over the stream: row rl of frame fr
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
            if not last:
                room, ok, bad = line_room(ring, nxt, r, geometry)  # the row it writes
                if not ok:
                    break
                err |= bad
            rows_row = r
        if last:
            room = 0
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
                room = room_from(rd(ring, p_off, p_mask, jj), per_src, per_dst, rat, se)
        e = max(mac_done(max(e_prev + 1, rows_in), ii), room)
        if e * per >= cap:
            break
        ring[e_off + (j & e_mask)] = e
        if c == 0 and not last:  # the next layer's input row starts to enter
            occ[occ_in, r & occ_mask] = e
        e_prev = e
        j += 1
        c += 1
        if c == ow:
            occ[occ_out, r & occ_mask] = e
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


@njit_borrowing(cache=True)
def advance_mac_pushes(net, ti):
    """The MAC arrays' outputs of tile ``ti``, layer after layer (:func:`advance_layer`): the
    layers before the last into the next one's line buffer, the last into the tile's FIFO."""
    tl = net.tiles[ti]
    moved = False
    for li in range(tl.layer0, tl.layer0 + tl.n_layers):
        moved |= advance_layer(net, ti, li)
    return moved


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
    if tl.n_layers > 1:
        walk_layers(net, ti, final)
        return
    blk = tl.block
    a = net.acc[blk]
    b_off, b_mask, nb, b_lo = view(net.streams, tl.line_pop)
    b_pops = (b_off, b_mask, nb, b_lo + 1)
    e_off, e_mask, ne, e_lo = view(net.streams, tl.mac_push)
    lr = net.layers[tl.layer0]
    ii, half, h, g = lr.ii, lr.half, prm.h, prm.watchdog_fs
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
        done = mac_done(s_j, ii)
        if j >= ne:
            if final:
                ptr, _, lost, watch = note_wait(ring, b_pops, ptr, prev, s_j, gaps,
                                                BusyWatch(blk, n_gaps, last_busy, per, g))
                err |= lost
                n_gaps, last_busy = watch.n_gaps, watch.last_busy_fs
                if s_j < INF:
                    n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy, s_j * per,
                                              done * per, g)
                    _, _, n_gaps, last_busy = pops_in(ring, (b_off, b_mask, nb), ptr, done + 1, INF,
                                                       np.bool_(True), gaps,
                                                       BusyWatch(blk, n_gaps, last_busy, per, g))
            break
        e = rd(ring, e_off, e_mask, j)
        if e > known_until:
            break  # a pop before e may still come
        if s_j > prev + 1:  # waiting for the row's input (phase 0)
            ptr, waited, lost, watch = note_wait(ring, b_pops, ptr, prev, s_j, gaps,
                                                 BusyWatch(blk, n_gaps, last_busy, per, g))
            err |= lost
            starved += waited
            n_gaps, last_busy = busy(gaps, blk, watch.n_gaps, watch.last_busy_fs, s_j * per,
                                     done * per, g)
        if e > done + 1:  # the finished descriptor held for a free slot
            ptr, waited, lost, watch = note_wait(ring, b_pops, ptr, done, e, gaps,
                                                 BusyWatch(blk, n_gaps, last_busy, per, g))
            err |= lost
            blocked += waited
            n_gaps, last_busy = busy(gaps, blk, watch.n_gaps, watch.last_busy_fs, e * per,
                                     e * per, g)
        last_busy = e * per  # busy through its MAC cycles and its push
        prev = e
        j += 1
        c += 1
        if c == ow:
            c = 0
            r += 1
    a.walk, a.ptr, a.prev = j, ptr, prev
    store_activity(a, state, (starved, blocked, 0), (n_gaps, last_busy), err,
                   gaps.shape[1])



@njit(cache=True, inline="always")
def mark_layer(ring, streams, lr, h, cover, c0, c1):
    """Mark layer ``lr``'s known outputs from ``lr.wk`` on in the chunk of cycles [c0, c1):
    output k starts once the previous one has left and its input rows are in, works ``ii``
    cycles [s, f] and leaves at e when there is room -- busy over [s, f] and at e (``cover`` row 0),
    the last layer blocked over (f, e) (row 1). Each output that has left before c1 adds to the
    layer's own busy, blocked and first output. Returns (the first output not settled, a ring
    error). The input rows are read once per output row."""
    st = streams[lr.out_stream]
    e_off, e_mask, _, e_lo = view(streams, lr.out_stream)
    b_off, b_mask, _, b_lo = view(streams, lr.in_stream)
    k, count, ii, ow = lr.wk, st.count, lr.ii, lr.ow
    out_rows = lr.y1 - lr.y0
    r = k // ow
    col = k - r * ow
    prev = rd(ring, e_off, e_mask, k - 1) if k > 0 else -1
    err = k > 0 and k - 1 <= e_lo  # later outputs read later events
    row, rows_in = -1, 0
    l_busy, l_blocked, l_first = 0, 0, lr.first  # written back once
    n_in, iw, iy0, y0, half = lr.n_in, lr.iw, lr.iy0, lr.y0, lr.half
    last = lr.last == 1
    while k < count:
        if r != row:
            fr = r // out_rows
            need = fr * n_in + (nna_last_input_row(y0 + r - fr * out_rows, half, h) - iy0
                                + 1) * iw
            rows_in = rd(ring, b_off, b_mask, need - 1) + 1
            err |= need - 1 <= b_lo
            row = r
        s = max(prev + 1, rows_in)
        if s >= c1:
            break
        f = mac_done(s, ii)
        e = rd(ring, e_off, e_mask, k)
        mark(cover, c0, c1, s, f, 0)
        mark(cover, c0, c1, e, e, 0)
        if last:
            mark(cover, c0, c1, f + 1, e - 1, 1)
        if e >= c1:
            break
        # the layer's own activity: busy over [s, f] and at e, blocked over (f, e)
        l_busy += f - s + 1 + (1 if e > f else 0)
        l_blocked += max(0, e - f - 1)
        if k == 0:
            l_first = e
        prev = e
        k += 1
        col += 1
        if col == ow:
            col = 0
            r += 1
    lr.busy += l_busy
    lr.blocked += l_blocked
    lr.first = l_first
    return k, err


@njit(cache=True, inline="always")
def mark(cover, c0, c1, lo, hi, row):
    """Count the chunk's cycles [lo, hi] within [c0, c1) once more in ``cover[row]``, a
    difference array (+1 at the first cycle, -1 after the last: its running sum is the count)."""
    lo, hi = max(lo, c0), min(hi, c1 - 1)
    if lo <= hi:
        cover[row, lo - c0] += 1
        cover[row, hi - c0 + 1] -= 1


@njit(cache=True)
def walk_layers(net, ti, final):
    """Settle the activity of tile ``ti``'s submodule with several layers, cycle by cycle over
    the cycles every event of which is known (``final``: the streams have stopped; an output
    pending whose rows are in works, then waits for ever): busy in a cycle with a pop or in
    which any layer works on an output or lets one leave, blocked when only the last layer
    holds a finished output, starved otherwise. The cycles are counted in chunks (:func:`mark`: a
    difference array per class); the busy ones are the block's busy instants (its long gaps)."""
    prm = net.prm[0]
    state = net.state[0]
    ring, streams, gaps = net.ring, net.streams, net.gaps
    tl = net.tiles[ti]
    blk = tl.block
    a = net.acc[blk]
    per, g, h = net.blocks[blk].period, prm.watchdog_fs, prm.h
    b_off, b_mask, nb, b_lo = view(streams, tl.line_pop)
    # the cycles before `stop` are settled by the events known
    end = rd(ring, b_off, b_mask, nb - 1) + 1 if nb > 0 else 0
    front = INF
    if nb < streams[tl.line_pop].n and not final:
        front = end
    for li in range(tl.layer0, tl.layer0 + tl.n_layers):
        lr = net.layers[li]
        st = streams[lr.out_stream]
        e_last = rd(ring, st.off, st.mask, st.count - 1) if st.count > 0 else -1
        end = max(end, e_last + 1)
        if st.count < st.n:
            if not final:
                front = min(front, e_last + 1)
            else:
                s = layer_start(ring, streams, lr, h, st.count)  # works, then waits
                if s < INF:
                    end = max(end, mac_done(s, lr.ii) + 1)
    stop = min(front, end)
    c0 = a.walk
    chunk = 1 << 14
    cover = np.zeros((2, chunk + 1), np.int32)
    starved, blocked = 0, 0
    last_busy, n_gaps = a.last_busy, a.gaps
    ptr = a.ptr
    err = c0 < stop and ptr < nb and ptr <= b_lo
    while c0 < stop:
        c1 = min(stop, c0 + chunk)
        cover[:, :c1 - c0 + 1] = 0
        while ptr < nb:
            c = rd(ring, b_off, b_mask, ptr)
            if c >= c1:
                break
            cover[0, c - c0] += 1
            cover[0, c - c0 + 1] -= 1
            ptr += 1
        for li in range(tl.layer0, tl.layer0 + tl.n_layers):
            lr = net.layers[li]
            st = streams[lr.out_stream]
            k, bad = mark_layer(ring, streams, lr, h, cover, c0, c1)
            err |= bad
            if k == st.count and k < st.n and final:
                s = layer_start(ring, streams, lr, h, k)
                if s < INF:
                    mark(cover, c0, c1, s, mac_done(s, lr.ii), 0)
            lr.wk = k
        n_busy, n_blocked = 0, 0  # the running sums of cover's rows
        for i in range(c1 - c0):
            n_busy += cover[0, i]
            n_blocked += cover[1, i]
            if n_busy > 0:
                t = (c0 + i) * per
                n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy, t, t, g)
            elif n_blocked > 0:
                blocked += 1
            else:
                starved += 1
        c0 = c1
    a.walk = max(a.walk, c0)
    a.ptr = ptr
    store_activity(a, state, (starved, blocked, 0), (n_gaps, last_busy), err,
                   gaps.shape[1])


# ---- at an instant ------------------------------------------------------------------------------


@njit(cache=True)
def layer_start(ring, streams, lr, h, j):
    """The cycle layer ``lr``'s MAC array starts output j (INF: its rows are not in)."""
    r = j // lr.ow
    out_rows = lr.y1 - lr.y0
    fr = r // out_rows
    need = fr * lr.n_in + (nna_last_input_row(lr.y0 + r - fr * out_rows, lr.half, h)
                           - lr.iy0 + 1) * lr.iw
    rows_in = event(ring, streams[lr.in_stream], need - 1)
    if rows_in == INF:
        return INF
    prev = event(ring, streams[lr.out_stream], j - 1) if j > 0 else -1
    return max(prev + 1, rows_in + 1)


@njit(cache=True)
def layer_status(ring, streams, cursors, prm, lr, c):
    """(activity, outputs before cycle c, one leaves at c) of layer ``lr``'s MAC array in its
    cycle c: busy working on an output or letting one leave, blocked holding a finished one,
    starved waiting for its rows, idle once through."""
    emitted, push_at = lt_at(ring, streams[lr.out_stream], cursors[lr.out_stream], c)
    if push_at:
        return A_BUSY, emitted, push_at
    if emitted >= prm.frames * lr.n_out:
        return A_IDLE, emitted, push_at
    s_j = layer_start(ring, streams, lr, prm.h, emitted)
    if c < s_j:
        return A_STARVED, emitted, push_at
    if c <= mac_done(s_j, lr.ii):
        return A_BUSY, emitted, push_at
    return A_BLOCKED, emitted, push_at


@njit(cache=True)
def status_nna(ring, streams, cursors, prm, tl, layers, c):
    received, pop_at = lt_at(ring, streams[tl.line_pop], cursors[tl.line_pop], c)
    moved = pop_at
    act = A_IDLE
    emitted = 0
    for li in range(tl.layer0, tl.layer0 + tl.n_layers):
        act, emitted, _ = layer_status(ring, streams, cursors, prm, layers[li], c)
        moved |= act == A_BUSY
    if moved:
        return A_BUSY, -1
    if act == A_BLOCKED:  # the last layer holds a finished descriptor
        return A_BLOCKED, tl.out_fifo
    if emitted < prm.frames * tl.n_out or received < prm.frames * tl.n_in:
        return A_STARVED, tl.src_fifo
    return A_IDLE, -1


@njit(cache=True)
def sample_nna(ring, streams, cursors, prm, tile, data, c, out):
    """The NNA's signals after its cycle c into ``out`` (per layer, its status with several
    layers, line_buffer.row_in, line_buffer.fill, mac.phase, mac.row, mac.col; then out.valid,
    out.descriptor); ``tile`` = (its record, the layers' records), ``data``: the traced frames'
    descriptors."""
    tl, layers = tile
    k = 0
    push_at = False
    emitted = 0
    for li in range(tl.layer0, tl.layer0 + tl.n_layers):
        lr = layers[li]
        act, emitted, push_at = layer_status(ring, streams, cursors, prm, lr, c)
        if tl.n_layers > 1:
            out[k] = (act + 1) % 4
            k += 1
        received = cursors[lr.in_stream]
        if push_at:
            emitted += 1
        in_rows, out_rows = lr.iy1 - lr.iy0, lr.y1 - lr.y0
        f_in, r_in = frame_row(received // lr.iw, in_rows, prm.frames)
        f_out, r_out = frame_row(emitted // lr.ow, out_rows, prm.frames)
        y_out = lr.y0 + r_out
        oldest = f_out * in_rows + max(0, y_out - lr.half - lr.iy0)
        phase = 0
        if not push_at and emitted < prm.frames * lr.n_out:
            s_j = layer_start(ring, streams, lr, prm.h, emitted)
            if c >= s_j:
                phase = c - s_j + 1 if c < mac_done(s_j, lr.ii) else lr.ii
        out[k] = lr.iy0 + r_in
        out[k + 1] = max(0, f_in * in_rows + r_in - oldest)
        out[k + 2] = phase
        out[k + 3] = y_out
        out[k + 4] = lr.x0 + emitted % lr.ow
        k += 5
    out[k] = 1 if push_at else 0
    value = np.uint64(0)  # (a plain 0 would make numba unify it with the uint64 descriptor as a
    # float64, losing the low bits of a descriptor above 2^53)
    if emitted > 0:
        j = emitted - 1
        fr = j // tl.n_out
        j -= fr * tl.n_out
        r = j // tl.ow
        value = data.desc[fr - data.frame0, tl.side, tl.y0 + r, tl.x0 + j - r * tl.ow]
    out[k + 1] = value
