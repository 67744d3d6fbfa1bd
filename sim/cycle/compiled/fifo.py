"""The FIFOs on the compiled engine: their occupancy from the push and pop streams of their
producer and consumer (its readable twin is the FIFO block's own,
:class:`~sim.cycle.fifo.readable.Fifo`, beside the rule -- edges, visibility, room --
:mod:`sim.cycle.fifo.rule`, and what a FIFO traces, :mod:`sim.cycle.fifo.compiled`).

A FIFO has no stream of its own: its items are its producer's pushes and its consumer's pops
(a tile's FIFO: the pixels of the tile's input region among the source's pushes, or the
descriptors of its output region among the merge's moves -- :func:`item_index`). Here: its
statistics, a walk over the merged push and pop events of the consumer's timeline (a push
counts from the first consumer edge after its instant, a pop from the next consumer cycle; at
one instant pushes count first: the histogram, the largest occupancy) and, for a FIFO that
crosses domains, of the producer's (frees counted from ``free(c)``: the largest occupancy the
producer sees, its cycles full); and its counts at an instant (occupancy, traced signals).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from stereosim.core.kernel_cache import njit, njit_borrowing
from stereosim.sim.cycle.compiled.layout import ERR_RING, FIFO_TO_MERGE, FIFO_TO_NNA, INF
from stereosim.sim.cycle.compiled.ring import at, event, ratio, rd, view
from stereosim.sim.cycle.fifo.rule import (
    room_from,
    room_seen_until,
    seen_from,
    seen_from_scaled,
    visible_from,
)

# ---- items and streams --------------------------------------------------------------------------


@njit(cache=True, inline="always")
def tile_input_before(tl, w, n, k):
    """Pixels of a tile's input regions whose raster index over the stream (``n`` pixels a
    frame) is below k."""
    f = k // n
    k -= f * n
    y = k // w
    x = k - y * w
    if y < tl.iy0:
        return f * tl.n_in
    if y >= tl.iy1:
        return (f + 1) * tl.n_in
    return f * tl.n_in + (y - tl.iy0) * tl.iw + min(max(x - tl.ix0, 0), tl.iw)



@njit(cache=True, inline="always")
def tile_output_before(tl, w, n, k):
    """Pixels of a tile's output regions whose raster index over the stream is below k."""
    f = k // n
    k -= f * n
    y = k // w
    x = k - y * w
    if y < tl.y0:
        return f * tl.n_out
    if y >= tl.y1:
        return (f + 1) * tl.n_out
    return f * tl.n_out + (y - tl.y0) * tl.ow + min(max(x - tl.x0, 0), tl.ow)



@njit(cache=True, inline="always")
def item_index(kind, region, w, n, i):
    """The stream index of FIFO item i: the same, or for a tile's FIFO (``kind`` FIFO_TO_NNA: its
    pushes, FIFO_TO_MERGE: its pops) the raster index over the stream (``n`` pixels a frame) of the
    i-th pixel of its regions; ``region`` = (x0, y0, row width, rows) of one frame's."""
    if kind == FIFO_TO_NNA or kind == FIFO_TO_MERGE:
        x0, y0, row_w, rows = region
        per = row_w * rows
        f = i // per
        i -= f * per
        if row_w == w:
            return f * n + y0 * w + i
        r = i // row_w
        return f * n + (y0 + r) * w + x0 + i - r * row_w
    return i



@njit(cache=True, inline="always")
def fifo_known(fifos, tiles, streams, parts, w, n, f):
    """(items pushed, items popped) of FIFO f whose events are known."""
    fi = fifos[f]
    npush = streams[fi.push].count
    npop = streams[fi.pop].count
    if fi.kind == FIFO_TO_NNA:
        npush = tile_input_before(tiles[fi.side * parts + fi.tile], w, n, npush)
    elif fi.kind == FIFO_TO_MERGE:
        npop = tile_output_before(tiles[fi.side * parts + fi.tile], w, n, npop)
    return npush, npop



@njit(cache=True, inline="always")
def fifo_region(fifos, tiles, parts, f):
    """(x0, y0, row width, rows) of the tile region FIFO f's items map from in each frame (0,
    0, 1, 1 for whole-frame FIFOs)."""
    fi = fifos[f]
    if fi.kind == FIFO_TO_NNA:
        tl = tiles[fi.side * parts + fi.tile]
        return tl.ix0, tl.iy0, tl.iw, tl.iy1 - tl.iy0
    if fi.kind == FIFO_TO_MERGE:
        tl = tiles[fi.side * parts + fi.tile]
        return tl.x0, tl.y0, tl.ow, tl.y1 - tl.y0
    return 0, 0, 1, 1



@njit(cache=True)
def pop_cycle(net, f, i):
    """The consumer cycle of item i's pop."""
    fi = net.fifos[f]
    region = fifo_region(net.fifos, net.tiles, net.prm[0].parts, f)
    idx = item_index(fi.kind if fi.kind == FIFO_TO_MERGE else -1, region, net.prm[0].w,
                     net.prm[0].n, i)
    off, mask, _, _ = view(net.streams, fi.pop)
    return rd(net.ring, off, mask, idx)



# ---- statistics ---------------------------------------------------------------------------------


@njit_borrowing(cache=True)
def walk_fifo(net, f, producer, c_end):
    """Advance FIFO f's occupancy walk: the consumer's timeline (``producer`` False: a push
    counts from the first consumer edge after it, a pop from the next consumer cycle; the
    histogram) or the producer's (a push from its next cycle, a pop once its free slot is
    seen). Events at equal times: pushes first. ``c_end``: the walk's last edge + 1 once the
    run is over (then everything is settled), else -1 (only what no unknown event can
    precede)."""
    prm = net.prm[0]
    state = net.state[0]
    ring = net.ring
    hist = net.hist
    fi = net.fifos[f]
    nf = net.fifos.shape[0]
    wk = net.walks[nf + f if producer else f]
    n = fi.items
    w = prm.w
    npush, npop = fifo_known(net.fifos, net.tiles, net.streams, prm.parts, w, prm.n, f)
    region = fifo_region(net.fifos, net.tiles, prm.parts, f)
    kind = fi.kind
    # the region is the frame: item i is stream event i
    whole = region[2] == w and region[1] == 0 and region[3] == prm.h
    push_kind = FIFO_TO_NNA if kind == FIFO_TO_NNA and not whole else -1
    pop_kind = FIFO_TO_MERGE if kind == FIFO_TO_MERGE and not whole else -1
    u_off, u_mask, _, u_lo = view(net.streams, fi.push)
    o_off, o_mask, _, o_lo = view(net.streams, fi.pop)
    per_p, per_c, se, depth = fi.per_src, fi.per_dst, fi.space_edges, fi.depth
    final = c_end >= 0
    limit = c_end if final else INF
    if producer and not final:
        limit = state.horizon_fs // per_p + 1  # no free slot counts beyond the run's end
    keep = not producer
    hoff = wk.hoff
    inc, dec, cycle, level, top, at_depth = wk.inc, wk.dec, wk.cycle, wk.level, wk.top, \
        wk.at_depth
    # the latest known push's time: no unknown push comes before it
    last_inc = INF
    if npush > 0 and npush < n:
        pc = rd(ring, u_off, u_mask, item_index(push_kind, region, w, prm.n, npush - 1))
        last_inc = pc + 1 if producer else seen_from(pc, per_p, per_c, 1)
    # no unknown pop counts before an unknown push (a pop follows its push), so a push is
    # settled once as many pops as pushes before it are known; a pop once no unknown push can
    # come at or before it
    inc_limit = npush if final or npop == n else min(npush, npop + 1)
    dec_before = INF if final or npush == n else last_inc
    rat_p = per_p / per_c
    rat_c = per_c / per_p
    err = False
    ti = INF
    if inc < npush:
        idx = item_index(push_kind, region, w, prm.n, inc)
        err |= idx <= u_lo
        pc = rd(ring, u_off, u_mask, idx)
        ti = pc + 1 if producer else seen_from_scaled(pc, per_p, per_c, rat_p, 1)
    td = INF
    if dec < npop:
        idx = item_index(pop_kind, region, w, prm.n, dec)
        err |= idx <= o_lo
        cc = rd(ring, o_off, o_mask, idx)
        td = room_from(cc, per_p, per_c, rat_c, se) if producer else cc + 1
    while True:
        if ti <= td:
            if ti == INF or inc >= inc_limit:
                break
            t = ti
        else:
            if td >= dec_before:
                break
            t = td
        if t >= limit:
            break
        if t > cycle:
            if level < 0 or level > depth:
                # (cannot happen -- a pop follows its push, a push waits for a slot -- unless
                # the ring lost an event; the level held between events at one instant may
                # pass the depth: pushes count first)
                err = True
                break
            if keep:
                hist[hoff + level] += t - cycle
            if level >= depth:
                at_depth += t - cycle
            cycle = t
        if ti <= td:
            level += 1
            if level > top:
                top = level
            inc += 1
            ti = INF
            if inc < npush:
                idx = item_index(push_kind, region, w, prm.n, inc)
                pc = rd(ring, u_off, u_mask, idx)
                ti = pc + 1 if producer else seen_from_scaled(pc, per_p, per_c, rat_p, 1)
        else:
            level -= 1
            dec += 1
            td = INF
            if dec < npop:
                idx = item_index(pop_kind, region, w, prm.n, dec)
                cc = rd(ring, o_off, o_mask, idx)
                td = room_from(cc, per_p, per_c, rat_c, se) if producer else cc + 1
    if final and c_end > cycle and 0 <= level <= depth:
        if keep:
            hist[hoff + level] += c_end - cycle
        if level >= depth:
            at_depth += c_end - cycle
        cycle = c_end
    wk.inc, wk.dec, wk.cycle, wk.level, wk.top, wk.at_depth = inc, dec, cycle, level, top, \
        at_depth
    if err:
        state.error = ERR_RING



@njit_borrowing(cache=True)
def walk_fifos(net):
    """Advance every FIFO's walks as far as the events known settle them."""
    for f in range(net.fifos.shape[0]):
        if net.fifos[f].side < net.prm[0].sides:
            walk_fifo(net, f, np.bool_(False), np.int64(-1))
            if net.fifos[f].crossing == 1:
                walk_fifo(net, f, np.bool_(True), np.int64(-1))


@njit_borrowing(cache=True)
def finish_fifos(net, cycles):
    """Settle every FIFO walk up to the end of a completed run: ``cycles[f]`` = (edges of its
    consumer's domain, edges of its producer's)."""
    for f in range(net.fifos.shape[0]):
        if net.fifos[f].side < net.prm[0].sides:
            walk_fifo(net, f, np.bool_(False), cycles[f, 0])
            if net.fifos[f].crossing == 1:
                walk_fifo(net, f, np.bool_(True), cycles[f, 1])



# ---- at an instant ------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def visible_by(ring, streams, fi, i, c):
    """Can the consumer of FIFO ``fi`` (its record) pop its item i (the index of its push on
    the push stream) in its cycle c? False while the push is not known (later than asked)."""
    e = event(ring, streams[fi.push], i)
    return e != INF and visible_from(e, fi.per_src, fi.per_dst, ratio(fi.per_src, fi.per_dst),
                                     fi.data_edges) <= c


@njit(cache=True, inline="always")
def seen_free_by(ring, streams, fi, j, c):
    """Does the producer of FIFO ``fi`` (its record) see the slot its pop j (the index on the
    pop stream) frees in its cycle c? False while the pop is not known."""
    b = event(ring, streams[fi.pop], j)
    return b != INF and room_from(b, fi.per_src, fi.per_dst, ratio(fi.per_dst, fi.per_src),
                                  fi.space_edges) <= c


class FifoCounts(NamedTuple):
    """A FIFO's counts at an instant (:func:`counts_at`): its pushes, its pops, the frees its
    producer has seen, whether it was pushed at the producer's last edge and popped at the
    consumer's last edge."""

    pushes: int
    pops: int
    seen: int
    pushed: bool
    popped: bool


@njit(cache=True)
def counts_at(ring, streams, cursors, prm, tiles, fi, t):
    """The :class:`FifoCounts` of the FIFO ``fi`` (its record) after the step at instant t."""
    c_src = t // fi.per_src
    c_dst = t // fi.per_dst
    # the last pop whose free slot the producer sees at c_src
    p_seen = room_seen_until(c_src, fi.per_src, fi.per_dst, fi.space_edges)
    push = streams[fi.push]
    pop = streams[fi.pop]
    le_push = cursors[fi.push]
    le_pop = cursors[fi.pop]
    # the frees seen are the pops up to p_seen <= c_dst: counted back from the pop cursor
    le_seen = le_pop
    while le_seen > 0 and at(ring, pop, le_seen - 1) > p_seen:
        le_seen -= 1
    pushed = le_push > 0 and at(ring, push, le_push - 1) == c_src
    popped = le_pop > 0 and at(ring, pop, le_pop - 1) == c_dst
    if fi.kind == FIFO_TO_NNA:
        tl = tiles[fi.side * prm.parts + fi.tile]
        pushes = tile_input_before(tl, prm.w, prm.n, le_push)
        pushed = pushed and tile_input_before(tl, prm.w, prm.n, le_push - 1) < pushes
        return FifoCounts(pushes=pushes, pops=le_pop, seen=le_seen, pushed=pushed, popped=popped)
    if fi.kind == FIFO_TO_MERGE:
        tl = tiles[fi.side * prm.parts + fi.tile]
        pops = tile_output_before(tl, prm.w, prm.n, le_pop)
        popped = popped and tile_output_before(tl, prm.w, prm.n, le_pop - 1) < pops
        return FifoCounts(pushes=le_push, pops=pops,
                          seen=tile_output_before(tl, prm.w, prm.n, le_seen), pushed=pushed,
                          popped=popped)
    return FifoCounts(pushes=le_push, pops=le_pop, seen=le_seen, pushed=pushed, popped=popped)



@njit(cache=True)
def fifo_counts(net, f, t):
    """:func:`counts_at` of FIFO f (after :func:`cursors_at` for the instant t)."""
    return counts_at(net.ring, net.streams, net.cursors, net.prm[0], net.tiles, net.fifos[f],
                        t)


