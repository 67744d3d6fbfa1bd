"""The statistics the readable kernel counts edge by edge, taken from the event streams behind
them (docs/compiled-engine.md, "statistics"):

- **activity** of the MAC arrays and the SVA: a descriptor's MAC array waits for its input rows
  in ``[e[j-1] + 1, s)`` (starved) and holds the finished descriptor in ``(s + cycles - 1,
  e[j])`` (blocked); the SVA's word waits for its row (starved), then for its latency and
  initiation interval (busy), then for a free slot (blocked). A pop in such a cycle makes it
  busy, so the walker counts the pops inside those intervals;
- **FIFO occupancy**: a walk over the merged push and pop events of the consumer's timeline
  (the histogram at every consumer edge, the largest occupancy) and, for a FIFO that crosses
  domains, of the producer's (the largest occupancy it sees, its cycles full);
- **busy instants** for the watchdog: each block's gaps between busy instants longer than the
  watchdog's time are kept (``Net.gaps``); the run's quiet stretches are where every block has
  one (:func:`sim.cycle.compiled.run.first_quiet`).

A walker settles a beat only once every event it needs is known (and no unknown event can come
before one it processes), so it runs behind the streams and finishes when they do. Like the
streams, the loops read rings through local offsets and masks only.
"""

from __future__ import annotations

from numba import njit

from stereosim.sim.cycle.compiled.layout import (
    ERR_GAPS,
    ERR_RING,
    F_MERGE,
    F_SRC,
    INF,
    K_CAMERA,
    K_SVA,
    S_T,
)
from stereosim.sim.cycle.compiled.pipeline import arrival, cycle_of, issued_before, words_between
from stereosim.sim.cycle.compiled.ring import busy, rd, view
from stereosim.sim.cycle.rules import (
    camera_frame_start,
    nna_last_input_row,
    seen_from,
    seen_from_scaled,
    sva_last_input_row,
)

NEVER = -(1 << 40)


@njit(cache=True, inline="always")
def _skip(ring, off, mask, ptr, limit, c):
    """The first of the known events ptr .. limit - 1 (increasing) at or after cycle c:
    galloping from ptr, then bisecting (cheap when the answer is near ptr)."""
    if ptr >= limit or ring[off + (ptr & mask)] >= c:
        return ptr
    step = 1
    hi = ptr + 1
    while hi < limit and ring[off + (hi & mask)] < c:
        ptr = hi
        step *= 2
        hi = ptr + step
    if hi > limit:
        hi = limit
    # event ptr < c; the answer is in (ptr, hi]
    while hi - ptr > 1:
        mid = (ptr + hi) // 2
        if ring[off + (mid & mask)] < c:
            ptr = mid
        else:
            hi = mid
    return hi


@njit(cache=True, inline="always")
def _catch_up(ring, off, mask, ptr, lowest, lo):
    """A pointer into a ring that has moved on: jump to the ``lowest`` event it still holds if
    everything before it is earlier than cycle ``lo`` (then nothing uncounted was lost).
    Returns (pointer, lost: the ring was too small)."""
    if ptr >= lowest:
        return ptr, False
    return lowest, ring[off + (lowest & mask)] > lo


@njit(cache=True, inline="always")
def _pops_in(ring, pops, ptr, lo, hi, long, gaps, state):
    """Count the pops in cycles [lo, hi) (skipping those before lo); inside an interval longer
    than the watchdog's time (``long``) each is a busy instant to note. ``pops`` = (ring offset,
    mask, known events) of the pop stream; ``state`` = (block, n_gaps, last busy, period,
    watchdog) of :func:`~sim.cycle.compiled.ring.busy`. Returns (pointer past them, count,
    n_gaps, last busy)."""
    off, mask, limit = pops
    blk, n_gaps, last_busy, per, g = state
    ptr = _skip(ring, off, mask, ptr, limit, lo)
    first = ptr
    if long:
        while ptr < limit:
            c = ring[off + (ptr & mask)]
            if c >= hi:
                break
            n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy, c * per, c * per, g)
            ptr += 1
    else:
        ptr = _skip(ring, off, mask, ptr, limit, hi)
    return ptr, ptr - first, n_gaps, last_busy


# ---- the MAC arrays -----------------------------------------------------------------------------


@njit(cache=True)
def walk_nna(net, ti, final):
    """Settle the activity of tile ``ti``'s descriptors whose every event is known (``final``:
    the streams have stopped; a descriptor still pending works, then waits for ever). A gap in
    the block's busy instants can only lie in a wait (for rows or for a slot), so those are the
    only places it is looked for."""
    prm = net.prm[0]
    ring = net.ring
    gaps = net.gaps
    tl = net.tiles[ti]
    blk = tl.block
    a = net.acc[blk]
    b_off, b_mask, nb, b_lo = view(net.streams, tl.b)
    b_pops = (b_off, b_mask, nb)
    e_off, e_mask, ne, e_lo = view(net.streams, tl.e)
    cpd, half, h, g = prm.cpd, prm.half, prm.h, prm.watchdog_fs
    per = net.blocks[blk].period
    ow, iw, y0, iy0, n_in = tl.ow, tl.iw, tl.y0, tl.iy0, tl.n_in
    out_rows = tl.y1 - tl.y0
    n_out, n_in_all = net.streams[tl.e].n, net.streams[tl.b].n  # over the stream
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
                ptr, lost = _catch_up(ring, b_off, b_mask, ptr, b_lo + 1, prev + 1)
                err |= lost
                long = s_j == INF or (s_j - prev) * per > g
                ptr, _, n_gaps, last_busy = _pops_in(ring, b_pops, ptr, prev + 1, s_j, long, gaps,
                                                     (blk, n_gaps, last_busy, per, g))
                if s_j < INF:
                    n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy, s_j * per,
                                              done * per, g)
                    _, _, n_gaps, last_busy = _pops_in(ring, b_pops, ptr, done + 1, INF, True, gaps,
                                                       (blk, n_gaps, last_busy, per, g))
            break
        e = rd(ring, e_off, e_mask, j)
        if e > known_until:
            break  # a pop before e may still come
        if s_j > prev + 1:  # waiting for the row's input (phase 0)
            ptr, lost = _catch_up(ring, b_off, b_mask, ptr, b_lo + 1, prev + 1)
            err |= lost
            long = (s_j - prev) * per > g
            ptr, cnt, n_gaps, last_busy = _pops_in(ring, b_pops, ptr, prev + 1, s_j, long, gaps,
                                                   (blk, n_gaps, last_busy, per, g))
            starved += s_j - prev - 1 - cnt
            n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy, s_j * per, done * per, g)
        if e > done + 1:  # the finished descriptor held for a free slot
            ptr, lost = _catch_up(ring, b_off, b_mask, ptr, b_lo + 1, done + 1)
            err |= lost
            long = (e - done) * per > g
            ptr, cnt, n_gaps, last_busy = _pops_in(ring, b_pops, ptr, done + 1, e, long, gaps,
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
        prm.error = ERR_RING
    if n_gaps > gaps.shape[1]:
        prm.error = ERR_GAPS


# ---- the SVA ------------------------------------------------------------------------------------


@njit(cache=True)
def walk_sva(net, blk, p_s, final):
    """Settle the SVA's activity for the words whose every event is known (``final``: the
    streams have stopped; a pending word waits for its row, the pipeline, then a slot). Word j,
    the next to leave, makes the block starved until its row is ready (unless a pair is popped),
    busy until it reaches the output register (:func:`~sim.cycle.compiled.pipeline.arrival`:
    the pipeline is working or waiting out the II), then blocked -- the pipeline stalled --
    until it is pushed. Gaps in its busy instants can only lie in a wait for a row or for a
    slot. The stages' counts follow (:func:`_walk_stages`)."""
    prm = net.prm[0]
    ring = net.ring
    gaps = net.gaps
    a = net.acc[blk]
    p_off, p_mask, npop, p_lo = view(net.streams, p_s)
    p_pops = (p_off, p_mask, npop)
    o_off, o_mask, no, o_lo = view(net.streams, p_s + 1)
    t_off, t_mask, kt, t_lo = view(net.streams, p_s + 3)
    o, t = (o_off, o_mask, o_lo), (t_off, t_mask, t_lo)
    n, w, h, la = net.streams[p_s].n, prm.w, prm.h, prm.lookahead
    lat, g = prm.pipe_latency, prm.watchdog_fs
    per = net.blocks[blk].period
    j, ptr, prev = a.walk, a.ptr, a.prev
    if j == 0:
        prev = NEVER
    last_busy, n_gaps = a.last_busy, a.gaps
    # after the last pop known no other comes (every pop is in, or the streams have stopped)
    known_until = INF if npop >= n or final else (rd(ring, p_off, p_mask, npop - 1) + 1
                                                  if npop > 0 else 0)
    # issues after the last one known come at ticks from t[kt - 1] + II on
    next_tick = INF if kt >= n or final else (rd(ring, t_off, t_mask, kt - 1) + prm.cpp
                                              if kt > 0 else 0)
    err = (j < no and j <= o_lo) or (j < kt and j - 1 <= t_lo and j > 0)
    starved = 0
    blocked = 0
    y = j // w
    x = j - y * w
    ready_row = -1
    ready = INF
    never = INF // per  # a cycle no run reaches (keeps instants in range)
    while j < n:
        if y != ready_row:
            fr = y // h
            need = (fr * h + sva_last_input_row(y - fr * h, la, h) + 1) * w
            ready = rd(ring, p_off, p_mask, need - 1) + 1 if need <= npop else INF
            ready_row = y
        lo = max(prev + 1, 0)
        arrive = arrival(ring, o, t, lat, j) if j < kt else never
        if j >= no:
            if final:
                ptr, lost = _catch_up(ring, p_off, p_mask, ptr, p_lo + 1, lo)
                err |= lost
                long = ready == INF or (ready - lo) * per > g
                ptr, _, n_gaps, last_busy = _pops_in(ring, p_pops, ptr, lo, ready, long, gaps,
                                                     (blk, n_gaps, last_busy, per, g))
                if ready < INF:
                    if arrive > max(lo, ready):
                        n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy,
                                                  max(lo, ready) * per, (arrive - 1) * per, g)
                    _, _, n_gaps, last_busy = _pops_in(ring, p_pops, ptr, arrive, INF, True,
                                                       gaps, (blk, n_gaps, last_busy, per, g))
            break
        out = rd(ring, o_off, o_mask, j)
        if out > known_until:
            break  # a pop before the push may still come
        if out > arrive and next_tick < rd(ring, t_off, t_mask, j) + lat:
            break  # a stall: the words in the stages then may not all be issued yet
        if ready > lo:  # waiting for the word's row
            ptr, lost = _catch_up(ring, p_off, p_mask, ptr, p_lo + 1, lo)
            err |= lost
            long = (ready - lo) * per > g
            ptr, cnt, n_gaps, last_busy = _pops_in(ring, p_pops, ptr, lo, ready, long, gaps,
                                                   (blk, n_gaps, last_busy, per, g))
            starved += ready - lo - cnt
            if arrive > ready:
                n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy, ready * per,
                                          (arrive - 1) * per, g)
        elif arrive > lo:  # the pipeline works (or waits out the II), lo .. arrive - 1
            if (arrive - lo) * per > g:
                n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy, lo * per,
                                          (arrive - 1) * per, g)
            elif (arrive - 1) * per > last_busy:  # too short to hide a gap: just move on
                last_busy = (arrive - 1) * per
        if out > arrive:  # the pipeline stalled: the word waits for a free slot
            ptr, lost = _catch_up(ring, p_off, p_mask, ptr, p_lo + 1, arrive)
            err |= lost
            long = (out - arrive) * per > g
            ptr, cnt, n_gaps, last_busy = _pops_in(ring, p_pops, ptr, arrive, out, long, gaps,
                                                   (blk, n_gaps, last_busy, per, g))
            blocked += out - arrive - cnt
            n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy, out * per, out * per, g)
        err |= _walk_stages(prm, net.stages, ring, t, kt, j, out - arrive)
        last_busy = out * per
        prev = out
        j += 1
        x += 1
        if x == w:
            x = 0
            y += 1
    if j == prm.target and a.walk < j:  # every word settled: when the last left each stage
        for s in range(net.stages.shape[0]):
            st = net.stages[s]
            st.busy += prm.sva_regular * min(st.lat, prm.cpp) + st.lat
            tick = rd(ring, t_off, t_mask, j - 1) + st.off + st.lat
            st.done, _, bad = cycle_of(ring, o, t, lat, no, kt, tick)
            err |= bad
    a.walk, a.ptr, a.prev = j, ptr, prev
    a.starved += starved
    a.blocked += blocked
    a.last_busy, a.gaps = last_busy, n_gaps
    if err:
        prm.error = ERR_RING
    if n_gaps > gaps.shape[1]:
        prm.error = ERR_GAPS


@njit(cache=True, inline="always")
def _walk_stages(prm, stages, ring, t, kt, j, stall):
    """Count word j into every stage: the ticks it adds to the stage's busy ones (up to the
    next word's entry), the words the stage holds when j enters it (the most: its peak), and,
    when the pipeline stalled ``stall`` cycles with j in the output register, those cycles as
    blocked for every stage holding a word then. A word issued II ticks after the previous one
    without a stall (most of them) is only counted (``prm.sva_regular``: it adds min(l, II)
    busy ticks to a stage of latency l, which holds at most ceil(l / II) words then); the
    peaks are searched until a stage holds that many. Returns a ring error."""
    err = False
    t_off, t_mask, t_lo = t
    tj = rd(ring, t_off, t_mask, j)
    lat, ii = prm.pipe_latency, prm.cpp
    gap = tj - rd(ring, t_off, t_mask, j - 1) if j > 0 else -1
    if j > 0 and j - 1 <= t_lo:
        err = True
    regular = gap == ii and stall == 0
    if regular:
        prm.sva_regular += 1
        if prm.sva_peaks_full == 1:
            return err
    full = 1
    for s in range(stages.shape[0]):
        st = stages[s]
        if st.lat == 0:
            continue
        if not regular and j > 0:
            st.busy += min(st.lat, gap)
        most = (st.lat + ii - 1) // ii
        if st.peak < most or not regular:
            held = j + 1 - issued_before(ring, t, kt, tj - st.lat + 1)
            if held > st.peak:
                st.peak = held
        if st.peak < most:
            full = 0
        if stall > 0:
            x = tj + lat
            if words_between(ring, t, kt, x - st.off - st.lat, x - st.off) > 0:
                st.blocked += stall
    prm.sva_peaks_full = full
    return err


# ---- the FIFOs ----------------------------------------------------------------------------------


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
    """The stream index of FIFO item i: the same, or for a tile's FIFO (``kind`` F_SRC: its
    pushes, F_MERGE: its pops) the raster index over the stream (``n`` pixels a frame) of the
    i-th pixel of its regions; ``region`` = (x0, y0, row width, rows) of one frame's."""
    if kind == F_SRC or kind == F_MERGE:
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
    if fi.kind == F_SRC:
        npush = tile_input_before(tiles[fi.side * parts + fi.tile], w, n, npush)
    elif fi.kind == F_MERGE:
        npop = tile_output_before(tiles[fi.side * parts + fi.tile], w, n, npop)
    return npush, npop


@njit(cache=True, inline="always")
def fifo_region(fifos, tiles, parts, f):
    """(x0, y0, row width, rows) of the tile region FIFO f's items map from in each frame (0,
    0, 1, 1 for whole-frame FIFOs)."""
    fi = fifos[f]
    if fi.kind == F_SRC:
        tl = tiles[fi.side * parts + fi.tile]
        return tl.ix0, tl.iy0, tl.iw, tl.iy1 - tl.iy0
    if fi.kind == F_MERGE:
        tl = tiles[fi.side * parts + fi.tile]
        return tl.x0, tl.y0, tl.ow, tl.y1 - tl.y0
    return 0, 0, 1, 1


@njit(cache=True)
def pop_cycle(net, f, i):
    """The consumer cycle of item i's pop."""
    fi = net.fifos[f]
    region = fifo_region(net.fifos, net.tiles, net.prm[0].parts, f)
    idx = item_index(fi.kind if fi.kind == F_MERGE else -1, region, net.prm[0].w,
                     net.prm[0].n, i)
    off, mask, _, _ = view(net.streams, fi.pop)
    return rd(net.ring, off, mask, idx)


@njit(cache=True)
def walk_fifo(net, f, producer, c_end):
    """Advance FIFO f's occupancy walk: the consumer's timeline (``producer`` False: a push
    counts from the first consumer edge after it, a pop from the next consumer cycle; the
    histogram) or the producer's (a push from its next cycle, a pop once its free slot is
    seen). Events at equal times: pushes first. ``c_end``: the walk's last edge + 1 once the
    run is over (then everything is settled), else -1 (only what no unknown event can
    precede)."""
    prm = net.prm[0]
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
    push_kind = F_SRC if kind == F_SRC and not whole else -1
    pop_kind = F_MERGE if kind == F_MERGE and not whole else -1
    u_off, u_mask, _, u_lo = view(net.streams, fi.push)
    o_off, o_mask, _, o_lo = view(net.streams, fi.pop)
    per_p, per_c, se, depth = fi.per_src, fi.per_dst, fi.space_edges, fi.depth
    final = c_end >= 0
    limit = c_end if final else INF
    if producer and not final:
        limit = prm.horizon_fs // per_p + 1  # no free slot counts beyond the run's end
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
        td = seen_from_scaled(cc, per_c, per_p, rat_c, se) if producer else cc + 1
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
                td = seen_from_scaled(cc, per_c, per_p, rat_c, se) if producer else cc + 1
    if final and c_end > cycle and 0 <= level <= depth:
        if keep:
            hist[hoff + level] += c_end - cycle
        if level >= depth:
            at_depth += c_end - cycle
        cycle = c_end
    wk.inc, wk.dec, wk.cycle, wk.level, wk.top, wk.at_depth = inc, dec, cycle, level, top, \
        at_depth
    if err:
        prm.error = ERR_RING


# ---- the row windows ---------------------------------------------------------------------------


@njit(cache=True)
def walk_windows(net, final):
    """Settle the row windows' peaks (:func:`sim.cycle.buffers.window_peaks`, the same
    arithmetic) for the input rows whose instant is known and before which every output row
    done is known: when input row r starts to enter, with y output rows done before that cycle
    -- the next is row y % out_rows of frame y // out_rows -- the window holds r - oldest + 1
    rows, oldest = min(frame in_rows + max(0, row + offset), r). The row instants live in the
    rings of ``Net.occ``; a walk that fell a ring behind sets the ring error."""
    prm = net.prm[0]
    occ = net.occ
    mask = occ.shape[1] - 1
    for i in range(net.win.shape[0]):
        wn = net.win[i]
        n_in = (net.streams[wn.in_stream].count + wn.in_width - 1) // wn.in_width
        n_out = net.streams[wn.out_stream].count // wn.out_width
        out_total = prm.frames * wn.out_rows
        slot, offset, in_rows, out_rows = wn.slot, wn.offset, wn.in_rows, wn.out_rows
        r, y, peak, at = wn.row, wn.done, wn.peak, wn.at
        if n_in - r > mask or n_out - y > mask:
            prm.error = ERR_RING
        while r < n_in:
            t = occ[slot, r & mask]
            while y < n_out and occ[slot + 1, y & mask] < t:
                y += 1
            if y == n_out and n_out < out_total and not final:
                break  # an output row not yet known may be done before t
            fr = y // out_rows
            oldest = min(fr * in_rows + max(0, y - fr * out_rows + offset), r)
            if r - oldest + 1 > peak:
                peak, at = r - oldest + 1, t
            r += 1
        wn.row, wn.done, wn.peak, wn.at = r, y, peak, at


# ---- all of them --------------------------------------------------------------------------------


@njit(cache=True)
def walk_all(net, final):
    """Run every walker as far as it can (``final``: the streams are done or stopped; the FIFO
    walks are finished by :func:`finish_fifos` once the run's length is known)."""
    prm = net.prm[0]
    horizon = 0
    streams, ring = net.streams, net.ring
    for s in range(streams.shape[0]):
        off, mask, count, _ = view(streams, s)
        if count > 0 and streams[s].kind != S_T:  # T holds ticks, not cycles
            t = rd(ring, off, mask, count - 1) * streams[s].period
            if t > horizon:
                horizon = t
    prm.horizon_fs = horizon
    for ti in range(prm.sides * prm.parts):
        walk_nna(net, ti, final)
    for blk in range(net.blocks.shape[0]):
        if net.blocks[blk].kind == K_SVA:
            walk_sva(net, blk, net.fifos[net.blocks[blk].fifo_in].pop, final)
    walk_windows(net, final)
    if not final:
        for f in range(net.fifos.shape[0]):
            if net.fifos[f].side < prm.sides:
                walk_fifo(net, f, False, -1)
                if net.fifos[f].crossing == 1:
                    walk_fifo(net, f, True, -1)


@njit(cache=True)
def finish_fifos(net, cycles):
    """Settle every FIFO walk up to the end of a completed run: ``cycles[f]`` = (edges of its
    consumer's domain, edges of its producer's)."""
    for f in range(net.fifos.shape[0]):
        if net.fifos[f].side < net.prm[0].sides:
            walk_fifo(net, f, False, cycles[f, 0])
            if net.fifos[f].crossing == 1:
                walk_fifo(net, f, True, cycles[f, 1])


@njit(cache=True)
def note_camera(net, blk, lines, line_clocks, frame_clocks):
    """A camera is busy from each frame's first to its last line's end (frames of pairs
    sharing the chip overlap; their starts come in order)."""
    if net.blocks[blk].kind == K_CAMERA:
        a = net.acc[blk]
        per = net.blocks[blk].period
        for f in range(net.prm[0].frames):
            start = camera_frame_start(f, frame_clocks, net.prm[0].pairs)
            a.gaps, a.last_busy = busy(net.gaps, blk, a.gaps, a.last_busy, start * per,
                                        (start + lines * line_clocks - 1) * per,
                                        net.prm[0].watchdog_fs)
