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

from stereosim.sim.cycle.compiled.layout import (
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
    S_T,
)
from stereosim.sim.cycle.compiled.pipeline import arrival, issued_before, words_between
from stereosim.sim.cycle.compiled.ring import rd
from stereosim.sim.cycle.compiled.walkers import tile_input_before, tile_output_before
from stereosim.sim.cycle.rules import (
    burst_of,
    camera_cycle,
    camera_frame_start,
    camera_in_lines,
    camera_pixels_streamed,
    memory_first_cycle,
    nna_last_input_row,
    seen_from,
    sink_may_pop,
    sva_last_input_row,
    frame_row,
    rows_ready_in_frame,
    sva_rows_done_before_input,
    sva_tick_at,
)

NEVER = -(1 << 40)


@njit(cache=True, inline="always")
def _at(ring, st, i):
    """Event i of the stream whose record is ``st`` (the ring holds it)."""
    return ring[st.off + (i & st.mask)]


@njit(cache=True, inline="always")
def _event(ring, st, i):
    """Event i of the stream ``st``, or INF if the streams do not hold it (later than asked)."""
    if i < st.count:
        return ring[st.off + (i & st.mask)]
    return INF


@njit(cache=True, inline="always")
def _lt_at(ring, st, le, c):
    """(events of stream ``st`` before cycle c, is there one at c), c being the cycle of the
    cursors' instant in the stream's domain and ``le`` the stream's cursor."""
    at = le > 0 and ring[st.off + ((le - 1) & st.mask)] == c
    return le - (1 if at else 0), at


@njit(cache=True)
def count_le(net, s, c):
    """Known events of stream s at cycles <= c (the ring holds the ones asked about)."""
    ring = net.ring
    st = net.streams[s]
    hi = st.count
    lo = max(0, hi - st.mask - 1)
    if hi == 0 or _at(ring, st, hi - 1) <= c:
        return hi
    if _at(ring, st, lo) > c:
        return lo
    # events lo .. hi - 1 increase; find the first > c
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if _at(ring, st, mid) <= c:
            lo = mid
        else:
            hi = mid
    return hi


@njit(cache=True)
def cursors_at(net, t, init):
    """Set ``net.cursors[s]`` to the number of events of stream s at cycles <= t // P_s (its
    domain's last edge at or before the instant t) -- searched (``init``) or moved forward from
    their values at an earlier instant."""
    cur = net.cursors
    ring = net.ring
    streams = net.streams
    for s in range(streams.shape[0]):
        st = streams[s]
        if st.kind == S_T:
            continue  # ticks, not cycles: the SVA's replay reads them by tick
        c = t // st.period
        if init:
            cur[s] = count_le(net, s, c)
        else:
            i = cur[s]
            while i < st.count and ring[st.off + (i & st.mask)] <= c:
                i += 1
            cur[s] = i


# ---- blocks -------------------------------------------------------------------------------------
# The helpers take the arrays they read (ring, stream records, cursors, the run's constants,
# tile and FIFO records), not the Net: unpacking it per call would cost more than the rule.


@njit(cache=True)
def _tile_full(ring, streams, shape, tl, f, k, c):
    """Is tile ``tl``'s source FIFO ``f`` full for pixel k (raster over the stream) at
    producer cycle c?"""
    h, w = shape
    n = w * h
    fr = k // n
    y = (k - fr * n) // w
    x = k - fr * n - y * w
    if not (tl.ix0 <= x < tl.ix1 and tl.iy0 <= y < tl.iy1):
        return False
    i = fr * tl.n_in + (y - tl.iy0) * tl.iw + x - tl.ix0
    if i < f.depth:
        return False
    b = _event(ring, streams[tl.b], i - f.depth)
    return b == INF or seen_from(b, f.per_dst, f.per_src, f.space_edges) > c


FRAME_BUFFERS = -2  # what a memory source reading a camera's frame buffers waits on
DRAM = -3  # what a memory source (its read burst) or the sink (its write buffer) waits on


@njit(cache=True)
def _status_memory(ring, streams, cursors, prm, tables, b, c):
    tiles, fifos, frame_fs = tables
    k, at = _lt_at(ring, streams[b.stream], cursors[b.stream], c)
    if prm.fb > 0:  # reading a camera's frame buffers: frames are decided at their start
        instant = c * b.period
        last_start = camera_frame_start(prm.frames - 1, prm.cam_frame, prm.pairs) * prm.per_cam
        if prm.fb_next == prm.frames and last_start < instant and k >= prm.fb_taken * prm.n:
            return A_IDLE, -1
        if at:
            return A_BUSY, -1
        g = k // prm.n
        if g >= prm.fb_taken or frame_fs[0, g] >= instant:
            return A_STARVED, FRAME_BUFFERS  # the frame is not decided yet
        y = (k - g * prm.n) // prm.w
        x = k - g * prm.n - y * prm.w
        cam = camera_cycle(frame_fs[2, g], x, y, prm.cam_line, prm.cam_frame, prm.pairs)
        if c < seen_from(cam, prm.per_cam, b.period, 1):
            return A_STARVED, FRAME_BUFFERS  # the camera has not written the pixel
    elif k >= prm.frames * prm.n:
        return A_IDLE, -1
    if at:
        return A_BUSY, -1
    if prm.dram == 1:  # its read burst is in from the R event on
        r = _event(ring, streams[streams.shape[0] - 2], burst_of(k, prm.n, prm.d_rpx)[0])
        if r == INF or c < r:
            return A_STARVED, DRAM
    elif c < memory_first_cycle(k, prm.mem_hz, prm.mem_bps):
        return A_BUSY, -1
    for t in range(prm.parts):
        tl = tiles[b.side * prm.parts + t]
        if _tile_full(ring, streams, (prm.h, prm.w), tl, fifos[tl.src_fifo], k, c):
            return A_BLOCKED, tl.src_fifo
    return A_BUSY, -1  # (not reached: it would have pushed)


@njit(cache=True)
def _mac_start(ring, streams, prm, tl, j):
    """The cycle the MAC array starts descriptor j of tile ``tl`` (INF: its rows are not in)."""
    r = j // tl.ow
    out_rows = tl.y1 - tl.y0
    fr = r // out_rows
    need = fr * tl.n_in + (nna_last_input_row(tl.y0 + r - fr * out_rows, prm.half, prm.h)
                           - tl.iy0 + 1) * tl.iw
    rows_in = _event(ring, streams[tl.b], need - 1)
    if rows_in == INF:
        return INF
    prev = _event(ring, streams[tl.e], j - 1) if j > 0 else -1
    return max(prev + 1, rows_in + 1)


@njit(cache=True)
def _status_nna(ring, streams, cursors, prm, tl, c):
    received, pop_at = _lt_at(ring, streams[tl.b], cursors[tl.b], c)
    emitted, push_at = _lt_at(ring, streams[tl.e], cursors[tl.e], c)
    moved = pop_at
    mac_blocked = False
    n_out, n_in = prm.frames * tl.n_out, prm.frames * tl.n_in
    if emitted < n_out:
        s_j = _mac_start(ring, streams, prm, tl, emitted)
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
def _status_merge(ring, streams, cursors, prm, tables, b, c):
    tiles, fifos, _ = tables
    m_s = fifos[b.fifo_out].push
    m, at = _lt_at(ring, streams[m_s], cursors[m_s], c)
    if m >= prm.frames * prm.n:
        return A_IDLE, -1
    if at:
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
    e = _event(ring, streams[tl.e], fr * tl.n_out + (y - tl.y0) * tl.ow + x - tl.x0)
    fin = fifos[tl.out_fifo]
    if e == INF or seen_from(e, fin.per_src, fin.per_dst, fin.data_edges) > c:
        return A_STARVED, tl.out_fifo
    return A_BLOCKED, b.fifo_out


@njit(cache=True, inline="always")
def _pipeline(ring, streams, p_s):
    """(O ring, T ring, issue ticks known) of the SVA whose pop stream is ``p_s``."""
    so, st = streams[p_s + 1], streams[p_s + 3]
    return ((so.off, so.mask, so.count - 1 - so.mask), (st.off, st.mask, st.count - 1 - st.mask),
            st.count)


@njit(cache=True, inline="always")
def _tick(ring, o, t, kt, lat, k, c):
    """The SVA pipeline's tick at the start of cycle c, k words pushed before it."""
    if k == 0:
        last_push, last_exit = 0, 0
    else:
        last_push, last_exit = rd(ring, o[0], o[1], k - 1), rd(ring, t[0], t[1], k - 1) + lat
    nxt = rd(ring, t[0], t[1], k) + lat if k < kt else INF
    return sva_tick_at(c, last_push, last_exit, nxt)


@njit(cache=True)
def _status_sva(ring, streams, cursors, prm, fifos, b, c):
    p_s = fifos[b.fifo_in].pop
    o_s = p_s + 1
    n, w, h = prm.frames * prm.n, prm.w, prm.h
    o, t, kt = _pipeline(ring, streams, p_s)
    received, pop_at = _lt_at(ring, streams[p_s], cursors[p_s], c)
    emitted, push_at = _lt_at(ring, streams[o_s], cursors[o_s], c)
    issued = issued_before(ring, t, kt, _tick(ring, o, t, kt, prm.pipe_latency, emitted, c))
    wait = -1
    if received < n and not pop_at and issued // w >= sva_rows_done_before_input(
            received // w, prm.lookahead):
        for f in (b.fifo_in, b.fifo_in2):
            fi = fifos[f]
            e = _event(ring, streams[fi.push], received)
            if e == INF or seen_from(e, fi.per_src, fi.per_dst, fi.data_edges) > c:
                wait = f
                break
    if pop_at or push_at:
        return A_BUSY, -1
    if emitted < n:
        if emitted < kt and c >= arrival(ring, o, t, prm.pipe_latency, emitted):
            return A_BLOCKED, b.fifo_out  # the pipeline stalls
        y = emitted // w
        fr = y // h
        ready = _event(ring, streams[p_s],
                       (fr * h + sva_last_input_row(y - fr * h, prm.lookahead, h) + 1) * w - 1)
        if ready != INF and ready + 1 <= c:
            return A_BUSY, -1  # words in the pipeline, or a ready row waiting out the II
        return A_STARVED, wait if wait >= 0 else b.fifo_in
    return A_IDLE, -1


@njit(cache=True)
def _status_sink(ring, streams, cursors, prm, fifos, b, c):
    q_s = fifos[b.fifo_in].pop
    received, at = _lt_at(ring, streams[q_s], cursors[q_s], c)
    if received >= prm.frames * prm.n:
        return A_IDLE, -1
    if not sink_may_pop(c, prm.stall_period, prm.stall_phase):
        return A_IDLE, -1
    if at:
        return A_BUSY, -1
    if prm.dram == 1 and received < streams[q_s - 1].count:  # its word is visible: the write
        fi = fifos[b.fifo_in]  # buffer is full
        if seen_from(_event(ring, streams[q_s - 1], received), fi.per_src, fi.per_dst,
                     fi.data_edges) <= c:
            return A_BLOCKED, DRAM
    return A_STARVED, b.fifo_in


@njit(cache=True)
def _block_status(ring, streams, cursors, prm, tables, b, c):
    """(activity, FIFO waited on or -1) that block ``b`` (its record) reports in its cycle c."""
    kind = b.kind
    if kind == K_MEMORY:
        return _status_memory(ring, streams, cursors, prm, tables, b, c)
    if kind == K_CAMERA:  # busy in the lines of its frames
        busy = camera_in_lines(c, prm.frames, prm.h, prm.line_clocks, prm.frame_clocks,
                               prm.pairs)
        return (A_BUSY if busy else A_IDLE), -1
    if kind == K_NNA:
        return _status_nna(ring, streams, cursors, prm, tables[0][b.side * prm.parts + b.tile],
                           c)
    if kind == K_MERGE:
        return _status_merge(ring, streams, cursors, prm, tables, b, c)
    if kind == K_SVA:
        return _status_sva(ring, streams, cursors, prm, tables[1], b, c)
    return _status_sink(ring, streams, cursors, prm, tables[1], b, c)


@njit(cache=True)
def block_status(net, blk, c):
    """(activity, FIFO waited on or -1) that block ``blk`` reports in its cycle c (after
    :func:`cursors_at` for the instant)."""
    return _block_status(net.ring, net.streams, net.cursors, net.prm[0],
                         (net.tiles, net.fifos, net.frame_fs),
                         net.blocks[blk], c)


# ---- FIFOs --------------------------------------------------------------------------------------


@njit(cache=True)
def _fifo_counts(ring, streams, cursors, prm, tiles, fi, t):
    """(pushes, pops, frees the producer has seen, pushed at the producer's last edge, popped
    at the consumer's last edge) of the FIFO ``fi`` (its record) after the step at instant t."""
    c_src = t // fi.per_src
    c_dst = t // fi.per_dst
    # the last pop whose free slot the producer sees at c_src
    if fi.crossing == 1:
        x = (c_src - fi.space_edges + 1) * fi.per_src
        p_seen = (x - 1) // fi.per_dst if x > 0 else -1
    else:
        p_seen = c_src - 1
    push = streams[fi.push]
    pop = streams[fi.pop]
    le_push = cursors[fi.push]
    le_pop = cursors[fi.pop]
    # the frees seen are the pops up to p_seen <= c_dst: counted back from the pop cursor
    le_seen = le_pop
    while le_seen > 0 and _at(ring, pop, le_seen - 1) > p_seen:
        le_seen -= 1
    pushed = le_push > 0 and _at(ring, push, le_push - 1) == c_src
    popped = le_pop > 0 and _at(ring, pop, le_pop - 1) == c_dst
    if fi.kind == F_SRC:
        tl = tiles[fi.side * prm.parts + fi.tile]
        pushes = tile_input_before(tl, prm.w, prm.n, le_push)
        pushed = pushed and tile_input_before(tl, prm.w, prm.n, le_push - 1) < pushes
        return pushes, le_pop, le_seen, pushed, popped
    if fi.kind == F_MERGE:
        tl = tiles[fi.side * prm.parts + fi.tile]
        pops = tile_output_before(tl, prm.w, prm.n, le_pop)
        popped = popped and tile_output_before(tl, prm.w, prm.n, le_pop - 1) < pops
        return le_push, pops, tile_output_before(tl, prm.w, prm.n, le_seen), pushed, popped
    return le_push, le_pop, le_seen, pushed, popped


@njit(cache=True)
def fifo_counts(net, f, t):
    """:func:`_fifo_counts` of FIFO f (after :func:`cursors_at` for the instant t)."""
    return _fifo_counts(net.ring, net.streams, net.cursors, net.prm[0], net.tiles, net.fifos[f],
                        t)


# ---- traced signals -----------------------------------------------------------------------------


@njit(cache=True)
def _sample_nna(ring, streams, cursors, prm, tl, data, c, out):
    """The NNA's signals after its cycle c into out[0:7]; ``data``: the traced frames'
    descriptors."""
    received = cursors[tl.b]
    emitted, push_at = _lt_at(ring, streams[tl.e], cursors[tl.e], c)
    if push_at:
        emitted += 1
    in_rows, out_rows = tl.iy1 - tl.iy0, tl.y1 - tl.y0
    f_in, r_in = frame_row(received // tl.iw, in_rows, prm.frames)
    f_out, r_out = frame_row(emitted // tl.ow, out_rows, prm.frames)
    y_out = tl.y0 + r_out
    oldest = f_out * in_rows + max(0, y_out - prm.half - tl.iy0)
    phase = 0
    if not push_at and emitted < prm.frames * tl.n_out:
        s_j = _mac_start(ring, streams, prm, tl, emitted)
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


@njit(cache=True)
def _sample_sva(ring, streams, cursors, prm, sva, data, c, out):
    """The SVA's signals after its cycle c into out[0:11 + 2 S]; ``sva`` = (its pop stream,
    its stages)."""
    p_s, stages = sva
    w, h, n, lat = prm.w, prm.h, prm.frames * prm.n, prm.pipe_latency
    o, t, kt = _pipeline(ring, streams, p_s)
    received = cursors[p_s]
    emitted, push_at = _lt_at(ring, streams[p_s + 1], cursors[p_s + 1], c)
    tick = _tick(ring, o, t, kt, lat, emitted, c)  # during cycle c
    stall = (not push_at and emitted < n and emitted < kt
             and c >= arrival(ring, o, t, lat, emitted))
    if push_at:
        emitted += 1
    after = _tick(ring, o, t, kt, lat, emitted, c + 1)  # after it
    issued = issued_before(ring, t, kt, tick)
    rows = received // w
    out[0] = frame_row(rows, h, prm.frames)[1]
    out[1] = received - rows * w
    out[2] = rows_ready_in_frame(rows, h, prm.lookahead, prm.frames)
    out[3] = frame_row(emitted // w, h, prm.frames)[1]
    out[4] = emitted % w
    out[5] = 1 if push_at else 0
    word = 0
    if emitted > 0:
        fr = (emitted - 1) // prm.n
        j = emitted - 1 - fr * prm.n
        word = data.words[fr - data.frame0, j // w, j % w]
    out[6] = word & data.word_mask
    out[7] = 1 if push_at and word < 0 else 0
    out[8] = 1 if not stall and issued < kt and rd(ring, t[0], t[1], issued) == tick else 0
    out[9] = 1 if stall else 0
    out[10] = issued_before(ring, t, kt, after) - emitted
    last = rd(ring, t[0], t[1], n - 1) if issued == n else 0
    for s in range(stages.shape[0]):
        st = stages[s]
        held = words_between(ring, t, kt, tick - st.off - st.lat, tick - st.off)
        if held > 0:
            code = 3 if stall else 1  # blocked, busy
        elif issued == n and tick - last > st.off + st.lat:
            code = 0  # idle
        else:
            code = 2  # starved
        out[11 + 2 * s] = code
        out[12 + 2 * s] = words_between(ring, t, kt, after - st.off - st.lat, after - st.off)


@njit(cache=True, inline="always")
def _block_signals(kind, n_stages):
    """How many signals a block of this kind traces (its activity first)."""
    if kind == K_MEMORY or kind == K_CAMERA:
        return 2
    if kind == K_NNA:
        return 8
    if kind == K_SVA:
        return 12 + 2 * n_stages
    return 3


@njit(cache=True)
def sample(net, data, t, out, done):
    """Every traced signal's value after the step at instant t, in the plan's order (blocks,
    then FIFOs; :func:`sim.cycle.plan._signals`), after :func:`cursors_at` for the instant.
    A block's signals change only at its clock's edges, a FIFO's at its producer's or its
    consumer's: ``done`` (int64 (blocks + FIFOs, 2), -1 at first) holds the cycles ``out``
    already shows for each, which are not evaluated again."""
    ring, streams, cursors, tiles, fifos = net.ring, net.streams, net.cursors, net.tiles, net.fifos
    prm = net.prm[0]
    blocks = net.blocks
    n_blocks = blocks.shape[0]
    k = 0
    for blk in range(n_blocks):
        b = blocks[blk]
        c = t // b.period
        if done[blk, 0] == c:
            k += _block_signals(b.kind, prm.n_stages)
            continue
        done[blk, 0] = c
        st, _ = _block_status(ring, streams, cursors, prm, (tiles, fifos, net.frame_fs), b, c)
        out[k] = (st + 1) % 4  # idle 0, busy 1, starved 2, blocked 3
        k += 1
        if b.kind == K_MEMORY or (b.kind == K_CAMERA and prm.fb == 0):
            out[k] = cursors[b.stream]
            k += 1
        elif b.kind == K_CAMERA:  # writing frame buffers: the pixels it has streamed
            out[k] = camera_pixels_streamed(c, prm.frames, prm.h, prm.w, prm.line_clocks,
                                            prm.frame_clocks, prm.pairs)
            k += 1
        elif b.kind == K_NNA:
            _sample_nna(ring, streams, cursors, prm, tiles[b.side * prm.parts + b.tile],
                        data, c, out[k:k + 7])
            k += 7
        elif b.kind == K_MERGE:
            m_s = fifos[b.fifo_out].push
            m, at = _lt_at(ring, streams[m_s], cursors[m_s], c)
            out[k] = m + (1 if at else 0)
            out[k + 1] = 1 if at else 0
            k += 2
        elif b.kind == K_SVA:
            m = _block_signals(b.kind, prm.n_stages) - 1
            _sample_sva(ring, streams, cursors, prm, (fifos[b.fifo_in].pop, net.stages), data,
                        c, out[k:k + m])
            k += m
        elif b.kind == K_SINK:
            q_s = fifos[b.fifo_in].pop
            got, at = _lt_at(ring, streams[q_s], cursors[q_s], c)
            out[k] = got + (1 if at else 0)
            out[k + 1] = 1 if at else 0
            k += 2
    for f in range(fifos.shape[0]):
        fi = fifos[f]
        c_src, c_dst = t // fi.per_src, t // fi.per_dst
        if done[n_blocks + f, 0] == c_src and done[n_blocks + f, 1] == c_dst:
            k += 5
            continue
        done[n_blocks + f, 0], done[n_blocks + f, 1] = c_src, c_dst
        pushes, pops, seen, pushed, popped = _fifo_counts(ring, streams, cursors, prm, tiles, fi,
                                                          t)
        occ = pushes - pops
        out[k] = occ
        out[k + 1] = 1 if pushed else 0
        out[k + 2] = 1 if popped else 0
        out[k + 3] = 1 if pushes - seen >= fi.depth else 0
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
    ctl, last, times, ids, values, scratch, done = log
    n_sig = last.shape[0]
    n_log = ctl[0]
    t = ctl[1]
    first = True
    while t < end:
        if n_log + n_sig > times.shape[0]:
            ctl[0], ctl[1] = n_log, t
            return False
        cursors_at(net, t, first)
        first = False
        sample(net, data, t, scratch, done)
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
