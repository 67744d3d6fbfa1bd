"""The frame sources on the compiled engine: memory sources, cameras, a camera's frame buffers
and the DRAM channel's reads (twin of the readable kernel's
:mod:`sim.cycle.readable.blocks.sources`: :class:`~sim.cycle.readable.blocks.sources.MemorySource`,
:class:`~sim.cycle.readable.blocks.sources.CameraSource`,
:class:`~sim.cycle.readable.blocks.sources.FrameBuffers`,
:class:`~sim.cycle.readable.blocks.sources.DramChannel`; the rules are :mod:`sim.cycle.rules`).

Stream: ``SOURCE_PUSH`` per side, the cycle the source pushes pixel k (raster order over the
stream of frames) to every tile that takes it, in one joint push:

- memory: ``a[k] = max(a[k-1] + 1, the camera wrote it (frame buffers), its DRAM read burst in,
  memory_first_cycle(k), free(b_t[i - depth]) per tile t)``;
- camera: ``a[k] = camera_cycle(x, y)``, an overflow if a tile's slot is not free by then.

Two loops push: :func:`advance_source` (every tile of a side) and :func:`whole_pushes` (a camera
served by one submodule, in turn with its line buffer's pops); a memory source's pixel is the
same step in both (:func:`memory_pixel`, then :func:`store_push`).

Here also: which camera frame the stream's g-th frame is (:func:`decide_frame`), the DRAM
channel's read bursts (``DRAM_READ``, :func:`dram_ready`), the sources' statistics (blocked
while a FIFO is full, starved waiting for a camera or the channel, busy otherwise), a camera's
busy lines, what a stopped run still owes (frames that started, token waits), and what a source
reports at an instant (status, traced signals).
"""

from __future__ import annotations

from typing import NamedTuple

from stereosim.core.kernel_cache import njit, njit_borrowing
from stereosim.sim.cycle.compiled.fifo import seen_free_by
from stereosim.sim.cycle.compiled.layout import (
    A_BLOCKED,
    A_BUSY,
    A_IDLE,
    A_STARVED,
    END_OVERFLOW,
    INF,
    K_CAMERA,
    K_MEMORY,
)
from stereosim.sim.cycle.compiled.ring import (
    busy,
    event,
    lt_at,
    ratio,
    rd,
    store_activity,
    view,
)
from stereosim.sim.cycle.fifo.rule import room_from, seen_from, seen_from_scaled
from stereosim.sim.cycle.rules import (
    burst_last,
    burst_of,
    camera_cycle,
    camera_frame_start,
    camera_in_lines,
    camera_pixels_streamed,
    dram_read_ready_fs,
    dram_slot,
    first_edge_at,
    frame_buffer_admits,
    memory_first_cycle,
)

FRAME_BUFFERS = -2  # what a memory source reading a camera's frame buffers waits on
DRAM = -3  # what a memory source (its read burst) or the sink (its write buffer) waits on

# ---- frame buffers and the DRAM channel's reads -------------------------------------------------


@njit(cache=True)
def pair_frames_taken(frame_fs, g, pair, pairs, buffers):
    """(frames pair ``pair`` took among the stream's first g, the stream index of the one that
    holds the buffer its next frame needs -- its ``buffers``-th last taken -- or -1 while it has
    taken fewer)."""
    if pairs == 1:
        return g, g - buffers if g >= buffers else -1
    count, held = 0, -1
    for j in range(g - 1, -1, -1):
        if frame_fs[2, j] % pairs == pair:
            count += 1
            if count == buffers:
                held = j
    return count, held


@njit_borrowing(cache=True)
def decide_frame(net, g, acc, until_fs):
    """The camera frame the g-th frame of the stream is, with frame buffers (the readable
    ``CameraSource._decide``): the next camera frame whose pair's buffer is free when it starts
    (:func:`~sim.cycle.rules.frame_buffer_admits`: the reader finished the frame its pair took
    B frames before), the ones before it dropped -- or a stop (policy error: ``state.end`` =
    END_OVERFLOW, the frame in ``acc``). Returns 1 taken, 0 undecided (its start is at or
    beyond ``until_fs``) or no camera frame left (then the stream has g frames:
    ``state.target``), -1 stopped. A frame whose buffer is held by a frame the readers have not
    finished is not admitted."""
    prm = net.prm[0]
    state = net.state[0]
    while state.fb_next < prm.frames:
        f = state.fb_next
        start = camera_frame_start(f, prm.cam_frame, prm.pairs) * prm.per_cam
        if start >= until_fs:
            return 0
        g_pair, held = pair_frames_taken(net.frame_fs, g, f % prm.pairs, prm.pairs, prm.fb)
        busy_until = net.fbuf[1, held] if held >= 0 and net.fbuf[1, held] >= 0 else INF
        if frame_buffer_admits(g_pair, prm.fb, busy_until, start):
            net.frame_fs[0, g] = start
            net.frame_fs[2, g] = f
            state.fb_taken = g + 1
            state.fb_next = f + 1
            return 1
        if prm.fb_drop == 1:
            net.fbuf[0, f] = 1
            state.fb_next = f + 1
            continue
        acc.over_cycle, acc.over_k, acc.over_tile = \
            camera_frame_start(f, prm.cam_frame, prm.pairs), f, net.frame_fs[2, held]
        state.end = END_OVERFLOW
        return -1
    state.target = g * prm.n
    return 0


@njit(cache=True, inline="always")
def fb_first_cycle(net, g, x, y, per_src, rat):
    """The first source cycle that may read pixel (x, y) of the g-th frame of the stream from
    its frame buffer: the first edge after the camera wrote it."""
    prm = net.prm[0]
    c = camera_cycle(net.frame_fs[2, g], x, y, prm.cam_line, prm.cam_frame, prm.pairs)
    return seen_from_scaled(c, prm.per_cam, per_src, rat, 1)


@njit_borrowing(cache=True)
def dram_ready(net, k, own_side, own_count):
    """(cycle, ok, ring error): the first source cycle pixel k may leave through the DRAM
    channel -- its read burst's ``DRAM_READ`` event, computed here for the burst after the last
    known (the readable ``DramChannel.read_ready_cycle``: requested when both sources sent the
    last pixel of the burst ``prefetch`` before, and a camera wrote the burst's last pixel); not
    ok while a push it needs is not known (``own_count``: the pushes ``own_side`` knows)."""
    prm = net.prm[0]
    state = net.state[0]
    ring, streams = net.ring, net.streams
    st = streams[net.ids[0].dram_read]
    b, last = burst_of(k, prm.n, prm.d_rpx)
    if b < st.count:
        return ring[st.off + (b & st.mask)], True, b <= st.count - 1 - st.mask
    request = 0
    err = False
    if prm.fb > 0:  # the camera has written the burst
        g = last // prm.n
        y = (last - g * prm.n) // prm.w
        c = camera_cycle(net.frame_fs[2, g], last - g * prm.n - y * prm.w, y, prm.cam_line,
                         prm.cam_frame, prm.pairs)
        request = c * prm.per_cam
    if b >= prm.d_pref:  # a prefetch buffer frees when the burst before leaves
        j = burst_last(b - prm.d_pref, prm.n, prm.d_rpx)
        for s in range(prm.sides):
            a = streams[net.tiles[s * prm.parts].source_push]
            count = own_count if s == own_side else a.count
            if j >= count:
                return 0, False, False
            err |= j <= count - 1 - a.mask
            request = max(request, ring[a.off + (j & a.mask)] * a.period)
    slot = dram_slot(request, state.d_rslot, prm.d_slot, prm.d_round, prm.d_rfirst, 1)
    state.d_rslot = slot
    ready = first_edge_at(dram_read_ready_fs(slot, prm.d_slot, prm.d_lat), st.period)
    ring[st.off + (b & st.mask)] = ready
    st.count = b + 1
    return ready, True, err


@njit(cache=True, inline="always")
def reader_first(net, k, side, a_prev, per, rat_cam):
    """(first, DRAM wait, ok, ring error): the first cycle a memory source may send pixel k of
    the stream: after its previous push ``a_prev``, once the camera wrote it (frame buffers)
    and once its read burst is in (:func:`dram_ready`; the wait: the cycles that added); not ok
    while a push the burst needs is not known."""
    prm = net.prm[0]
    first = a_prev + 1
    if prm.fb > 0:
        g = k // prm.n
        y = (k - g * prm.n) // prm.w
        first = max(first, fb_first_cycle(net, g, k - g * prm.n - y * prm.w, y, per, rat_cam))
    if prm.dram == 0:
        return first, 0, True, False
    rdy, ok, bad = dram_ready(net, k, side, k)
    if ok and rdy > first:
        return rdy, rdy - first, ok, bad
    return first, 0, ok, bad


# ---- the pushes ---------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def memory_push(k, first, free, bucket):
    """(lo, a): the cycle ``a`` a memory source pushes pixel k (the readable
    ``MemorySource.evaluate``): from ``first`` (:func:`reader_first`) and its token bucket's
    cycle (``bucket`` = (memory clock Hz, bytes/s)), ``lo``, once every slot it needs is free
    (``free``). (Scalars only: it runs per pixel, and an array or the Net handed to an inlined
    function in a loop costs a reference count per call.)"""
    lo = max(first, memory_first_cycle(k, bucket[0], bucket[1]))
    return lo, max(lo, free)


@njit(cache=True, inline="always")
def note_memory_push(gaps, blk, acct, a_prev, first, lo, a, clock):
    """A memory source's statistics at its push in cycle ``a``: starved from ``a_prev`` + 1
    waiting for the camera or the channel (until ``first``), busy in every cycle but the
    blocked ones, ``lo`` .. a - 1 (a FIFO full). ``acct`` = (n_gaps, last busy), ``clock`` =
    (period, watchdog). Returns (starved, blocked, n_gaps, last busy)."""
    n_gaps, last_busy = acct
    per, g = clock
    starved = 0
    blocked = 0
    if first > a_prev + 1:
        starved = first - a_prev - 1
        n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy, first * per, first * per, g)
    if a > lo:
        blocked = a - lo
        n_gaps, last_busy = busy(gaps, blk, n_gaps, (lo - 1) * per if lo > 0 else last_busy,
                                 a * per, a * per, g)
    return starved, blocked, n_gaps, a * per


@njit(cache=True)
def _source_tables(tiles, fifos, streams, side, parts, tab):
    """Per tile of ``side`` into ``tab`` (TABLE): input region, ring of its pops, its source
    FIFO, its input pixels per frame."""
    for t in range(parts):
        tl = tiles[side * parts + t]
        f = fifos[tl.src_fifo]
        b = streams[tl.line_pop]
        r = tab[t]
        r.x0, r.x1, r.y0, r.y1, r.width, r.items = tl.ix0, tl.ix1, tl.iy0, tl.iy1, tl.iw, tl.n_in
        r.off, r.mask, r.count, r.lost = b.off, b.mask, b.count, b.count - 1 - b.mask
        r.depth, r.per_dst, r.per_src, r.edges = f.depth, f.per_dst, f.per_src, f.space_edges


@njit(cache=True, inline="always")
def _tiles_free(ring, tab, fno, x, y, rat, camera, c):
    """(the first cycle every tile (of ``tab``, :func:`_source_tables`) that takes pixel (x, y)
    of frame ``fno`` has a free slot, known, ring error, the first tile whose slot a camera's
    pixel of cycle c finds full or -1)."""
    free = 0
    err = False
    full_tile = -1
    for t in range(tab.shape[0]):
        r = tab[t]
        if not (r.x0 <= x < r.x1 and r.y0 <= y < r.y1):
            continue
        j = fno * r.items + (y - r.y0) * r.width + x - r.x0 - r.depth
        if j >= 0:
            if j >= r.count:
                return free, False, err, full_tile
            err |= j <= r.lost
            fr = room_from(ring[r.off + (j & r.mask)], r.per_src, r.per_dst, rat, r.edges)
            if fr > free:
                free = fr
            if camera == 1 and full_tile < 0 and fr > c:
                full_tile = t
    return free, True, err, full_tile


class SourcePush(NamedTuple):
    """The constants of a source's pushes (:func:`memory_pixel`, :func:`store_push`): its ring
    (offset, mask), side, block and clock period (fs), the camera's clock over it (frame
    buffers), whether it reads a camera's frame buffers or through the DRAM channel, its token
    bucket (memory clock Hz, bytes/s), the cap and the watchdog's time (fs), whether statistics
    are kept, a frame's columns and rows, and the frame buffers."""

    ring_off: int
    ring_mask: int
    side: int
    block: int
    period: int
    rat_cam: float
    reads: bool
    mem_hz: float
    mem_bps: float
    cap_fs: int
    watchdog_fs: int
    stats: int
    w: int
    h: int
    fb: int


class SourceTally(NamedTuple):
    """A source's statistics over a pass: cycles blocked (a FIFO full), starved (waiting for a
    camera or the DRAM channel), the DRAM channel's share of the waits, the long gaps noted
    (:func:`~.ring.busy`), its last busy instant (fs), a ring error."""

    blocked: int
    starved: int
    dram_wait: int
    n_gaps: int
    last_busy_fs: int
    ring_error: bool


@njit(cache=True, inline="always")
def source_push(net, side):
    """The :class:`SourcePush` of camera ``side``'s source and its :class:`SourceTally` so
    far."""
    prm = net.prm[0]
    st = net.streams[net.tiles[side * prm.parts].source_push]
    acc = net.acc[st.block]
    sp = SourcePush(
        ring_off=st.off, ring_mask=st.mask, side=side, block=st.block, period=st.period,
        rat_cam=ratio(prm.per_cam, st.period) if prm.fb > 0 else 1.0,
        reads=prm.fb > 0 or prm.dram == 1, mem_hz=prm.mem_hz, mem_bps=prm.mem_bps,
        cap_fs=prm.cap_fs, watchdog_fs=prm.watchdog_fs, stats=prm.stats, w=prm.w, h=prm.h,
        fb=prm.fb)
    return sp, SourceTally(blocked=0, starved=0, dram_wait=0, n_gaps=acc.gaps,
                           last_busy_fs=acc.last_busy, ring_error=False)


@njit(cache=True, inline="always")
def frame_taken(net, sp, pixel):
    """False when pixel = (column, row, frame of the stream) starts a frame that a memory source
    reading a camera's frame buffers cannot take yet: which camera frame it is is not decided
    (:func:`decide_frame`; or the run stops there)."""
    x, y, f = pixel
    if sp.fb > 0 and x == 0 and y == 0 and f >= net.state[0].fb_taken:
        return decide_frame(net, f, net.acc[sp.block], sp.cap_fs) == 1
    return True


@njit(cache=True, inline="always")
def memory_pixel(net, sp, k, a_prev, free, tally):
    """(a, tally): the cycle ``a`` memory source ``sp`` (a :class:`SourcePush`) pushes pixel k
    after its push ``a_prev`` once every slot it needs is free (``free``), the readable
    ``MemorySource.evaluate`` (:func:`reader_first`, :func:`memory_push`), and its
    :class:`SourceTally` with that push (:func:`note_memory_push`); a = -1: not now (a push its
    read burst needs is not known, or the push is beyond the cap)."""
    first = a_prev + 1
    d_wait, err = tally.dram_wait, tally.ring_error
    if sp.reads:  # frame buffers or the DRAM channel (the Net only on that path)
        first, wait, ok, bad = reader_first(net, k, sp.side, a_prev, sp.period, sp.rat_cam)
        err |= bad
        d_wait += wait
        if not ok:
            return -1, SourceTally(tally.blocked, tally.starved, d_wait, tally.n_gaps,
                                   tally.last_busy_fs, err)
    lo, a = memory_push(k, first, free, (sp.mem_hz, sp.mem_bps))
    if a * sp.period >= sp.cap_fs:
        return -1, SourceTally(tally.blocked, tally.starved, d_wait, tally.n_gaps,
                               tally.last_busy_fs, err)
    if sp.stats != 1:
        return a, SourceTally(tally.blocked, tally.starved, d_wait, tally.n_gaps,
                              tally.last_busy_fs, err)
    starved, blocked, n_gaps, last_busy = note_memory_push(
        net.gaps, sp.block, (tally.n_gaps, tally.last_busy_fs), a_prev, first, lo, a,
        (sp.period, sp.watchdog_fs))
    return a, SourceTally(tally.blocked + blocked, tally.starved + starved, d_wait, n_gaps,
                          last_busy, err)


@njit(cache=True, inline="always")
def store_push(net, sp, k, a, pixel):
    """Source ``sp`` pushes pixel k, at pixel = (column, row, frame of the stream), in cycle a:
    its ring, the frame's first push (frames from memory or a camera; side 0 stands for the
    stream) or, reading a camera's frame buffers, its last (the reader is done with the
    frame's buffer)."""
    net.ring[sp.ring_off + (k & sp.ring_mask)] = a
    x, y, f = pixel
    if sp.fb == 0:
        if sp.side == 0 and x == 0 and y == 0:
            net.frame_fs[0, f] = a * sp.period
    elif x == sp.w - 1 and y == sp.h - 1:
        net.fbuf[1, f] = a * sp.period


@njit_borrowing(cache=True)
def advance_source(net, side):
    """Source pushes of camera ``side`` to its tiles (a joint push to every tile that takes the
    pixel), as far as their line buffers' pops allow."""
    prm = net.prm[0]
    state = net.state[0]
    ring, streams = net.ring, net.streams
    sp, tally = source_push(net, side)
    st = streams[net.tiles[side * prm.parts].source_push]
    k = st.count
    n, w, h, per, cap = st.n, prm.w, prm.h, st.period, prm.cap_fs
    parts, camera = prm.parts, prm.camera
    line_clocks, frame_clocks = prm.line_clocks, prm.frame_clocks
    tab = net.scratch
    _source_tables(net.tiles, net.fifos, streams, side, parts, tab)
    rat = ratio(tab[0].per_dst, tab[0].per_src)
    err = False
    start = k
    a_prev = rd(ring, sp.ring_off, sp.ring_mask, k - 1) if k > 0 else -1
    full_tile = -1
    y = k // w  # row of frame fno
    x = k - y * w
    fno = y // h
    y -= fno * h
    while k < n:
        if not frame_taken(net, sp, (x, y, fno)):
            break
        c = camera_cycle(fno, x, y, line_clocks, frame_clocks, prm.pairs)
        free, ok, bad, full = _tiles_free(ring, tab, fno, x, y, rat, camera, c)
        err |= bad
        if full_tile < 0:
            full_tile = full
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
            a, tally = memory_pixel(net, sp, k, a_prev, free, tally)
            if a < 0:
                break
        store_push(net, sp, k, a, (x, y, fno))
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
    store_activity(net.acc[sp.block], state, (tally.starved, tally.blocked, tally.dram_wait),
                   (tally.n_gaps, tally.last_busy_fs), tally.ring_error or err,
                   net.gaps.shape[1])
    if full_tile >= 0:
        acc = net.acc[sp.block]
        acc.over_cycle, acc.over_k, acc.over_tile = (
            camera_cycle(fno, x, y, line_clocks, frame_clocks, prm.pairs), k,
            side * parts + full_tile)
        state.end = END_OVERFLOW
    return k > start


# ---- the pushes of a whole-frame side (taken in turn with its line buffer's pops) ----------------


class WholeSource(NamedTuple):
    """The constants of :func:`whole_pushes`' loop (a camera served by one submodule): the
    source's pushes (a :class:`SourcePush`), the ring of its line buffer's pops, its FIFO
    (depth, space edges), the NNA's clock period (fs) and its ratio to the source's, the
    stream's pushes."""

    push: SourcePush
    pop_off: int
    pop_mask: int
    depth: int
    space_edges: int
    per_nna: int
    rat_back: float  # per_nna / per_src (room_from's ratio)
    n: int


class SourceCursor(NamedTuple):
    """Where :func:`whole_pushes` stands: the pushes known, the last push (cycle), the next
    pixel's column, row of its frame and frame of the stream, the statistics so far (a
    :class:`SourceTally`) and an overflow."""

    pushes: int
    last_push: int
    x: int
    row: int
    frame: int
    tally: SourceTally
    overflow: bool


@njit(cache=True, inline="always")
def whole_pushes_begin(net, side):
    """What :func:`whole_pushes` reads of a camera served by one submodule: the constants of
    its loop (a :class:`WholeSource`) and its cursor (a :class:`SourceCursor`)."""
    prm = net.prm[0]
    tl = net.tiles[side]
    sp, tally = source_push(net, side)
    b_off, b_mask, _, _ = view(net.streams, tl.line_pop)
    sa = net.streams[tl.source_push]
    f = net.fifos[tl.src_fifo]
    k = WholeSource(
        push=sp, pop_off=b_off, pop_mask=b_mask, depth=f.depth, space_edges=f.space_edges,
        per_nna=f.per_dst, rat_back=ratio(f.per_dst, f.per_src), n=sa.n)
    ka = sa.count
    a_prev = rd(net.ring, sp.ring_off, sp.ring_mask, ka - 1) if ka > 0 else -1
    ya = ka // prm.w  # rows over the stream
    fa = ya // prm.h
    cur = SourceCursor(pushes=ka, last_push=a_prev, x=ka % prm.w, row=ya - fa * prm.h, frame=fa,
                       tally=tally, overflow=False)
    return k, cur


@njit(cache=True, inline="always")
def whole_pushes(net, k, cur, kb):
    """The source's pushes while the slot a FIFO depth back has been freed (``kb``: the line
    buffer's pops known), from the :class:`SourceCursor` ``cur`` with the constants ``k`` (a
    :class:`WholeSource`). Returns (cursor, moved)."""
    prm = net.prm[0]
    ring = net.ring
    sp = k.push
    b_off, b_mask, depth, se, n = k.pop_off, k.pop_mask, k.depth, k.space_edges, k.n
    p_src, p_nna, rat_back = sp.period, k.per_nna, k.rat_back
    ka, a_prev, xa, ya, fa = cur.pushes, cur.last_push, cur.x, cur.row, cur.frame
    tally, over = cur.tally, cur.overflow
    w, h, cap, camera = prm.w, prm.h, prm.cap_fs, prm.camera
    line_clocks, frame_clocks, pairs = prm.line_clocks, prm.frame_clocks, prm.pairs
    moved = False
    while ka < n and ka - depth < kb:
        free = 0
        if ka >= depth:
            free = room_from(rd(ring, b_off, b_mask, ka - depth), p_src, p_nna, rat_back, se)
        if camera == 1:
            c = camera_cycle(fa, xa, ya, line_clocks, frame_clocks, pairs)
            if c * p_src >= cap:
                break
            if free > c:
                over = True
                break
            a = c
        else:
            if not frame_taken(net, sp, (xa, ya, fa)):  # from a camera's frame buffer
                break
            a, tally = memory_pixel(net, sp, ka, a_prev, free, tally)
            if a < 0:
                break
        store_push(net, sp, ka, a, (xa, ya, fa))
        a_prev = a
        ka += 1
        moved = True
        xa += 1
        if xa == w:
            xa = 0
            ya += 1
            if ya == h:
                ya = 0
                fa += 1
    return SourceCursor(pushes=ka, last_push=a_prev, x=xa, row=ya, frame=fa, tally=tally,
                        overflow=over), moved


@njit(cache=True, inline="always")
def whole_pushes_end(net, k, cur):
    """Store what :func:`whole_pushes` did: the pushes known, the statistics, an overflow."""
    prm = net.prm[0]
    sp = k.push
    net.streams[net.tiles[sp.side].source_push].count = cur.pushes
    tally = cur.tally
    store_activity(net.acc[sp.block], net.state[0], (tally.starved, tally.blocked,
                                                     tally.dram_wait),
                   (tally.n_gaps, tally.last_busy_fs), tally.ring_error, net.gaps.shape[1])
    if cur.overflow:
        acc = net.acc[sp.block]
        acc.over_cycle, acc.over_k, acc.over_tile = (
            camera_cycle(cur.frame, cur.x, cur.row, prm.line_clocks, prm.frame_clocks,
                         prm.pairs), cur.pushes, sp.side)
        net.state[0].end = END_OVERFLOW


@njit_borrowing(cache=True)
def pending_overflow(net, side):
    """After a pass in which nothing moves: a camera whose next pixel's slot never frees (or
    frees only beyond the cap) overflows when that pixel arrives, if before the cap."""
    prm = net.prm[0]
    ring, streams = net.ring, net.streams
    st = streams[net.tiles[side * prm.parts].source_push]
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
        if j >= 0 and not seen_free_by(ring, streams, f, j, a):
            acc = net.acc[st.block]
            acc.over_cycle, acc.over_k, acc.over_tile = a, k, ti
            net.state[0].end = END_OVERFLOW
            return


# ---- statistics and a stopped run ---------------------------------------------------------------


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


@njit(cache=True)
def note_source_wait(net):
    """When a run stops with a memory source's next pixel not pushed: the source is busy while
    it waits for its token bucket (the readable's MemorySource: starved while the frame buffer
    or DRAM channel has not delivered the pixel, busy until its token, blocked after), so its
    busy instants run to the cycle before the token -- which the passes, noting a pixel's
    instants when it is pushed, have not noted."""
    prm = net.prm[0]
    state = net.state[0]
    ring, streams = net.ring, net.streams
    for blk in range(net.blocks.shape[0]):
        b = net.blocks[blk]
        if b.kind != K_MEMORY or b.side >= prm.sides:
            continue
        st = streams[b.stream]
        k = st.count
        if k >= (state.fb_taken if prm.fb > 0 else prm.frames) * prm.n:
            continue
        per = b.period
        a_prev = ring[st.off + ((k - 1) & st.mask)] if k > 0 else -1
        first, _, ok, _ = reader_first(net, k, b.side, a_prev, per, ratio(prm.per_cam, per))
        if not ok:
            continue
        lo, _ = memory_push(k, first, 0, (prm.mem_hz, prm.mem_bps))
        if lo > first:
            a = net.acc[blk]
            a.gaps, a.last_busy = busy(net.gaps, blk, a.gaps, a.last_busy, first * per,
                                       (lo - 1) * per, prm.watchdog_fs)


@njit_borrowing(cache=True)
def decide_until(net, acc, until_fs):
    """When a run stops: the camera frames that start before ``until_fs`` are decided at their
    start whatever the readers do (a camera does not wait; the passes decide a frame when a
    reader reaches it), so a frame whose buffer is still held is dropped or stops the run as
    in the readable kernel."""
    prm = net.prm[0]
    state = net.state[0]
    while prm.fb > 0 and state.end != END_OVERFLOW and state.fb_next < prm.frames:
        if decide_frame(net, state.fb_taken, acc, until_fs) != 1:
            return


# ---- at an instant ------------------------------------------------------------------------------


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
    return i >= f.depth and not seen_free_by(ring, streams, f, i - f.depth, c)


@njit(cache=True)
def status_memory(ring, streams, cursors, prm, state, tables, b, c):
    """(activity, FIFO waited on, or FRAME_BUFFERS or DRAM, or -1) that memory source ``b``
    (its record) reports in its cycle c (the readable ``MemorySource.evaluate``)."""
    tiles, fifos, frame_fs, ids = tables.tiles, tables.fifos, tables.frame_fs, tables.ids
    k, at_c = lt_at(ring, streams[b.stream], cursors[b.stream], c)
    if prm.fb > 0:  # reading a camera's frame buffers: frames are decided at their start
        instant = c * b.period
        last_start = camera_frame_start(prm.frames - 1, prm.cam_frame, prm.pairs) * prm.per_cam
        if state.fb_next == prm.frames and last_start < instant and k >= state.fb_taken * prm.n:
            return A_IDLE, -1
        if at_c:
            return A_BUSY, -1
        g = k // prm.n
        if g >= state.fb_taken or frame_fs[0, g] >= instant:
            return A_STARVED, FRAME_BUFFERS  # the frame is not decided yet
        y = (k - g * prm.n) // prm.w
        x = k - g * prm.n - y * prm.w
        cam = camera_cycle(frame_fs[2, g], x, y, prm.cam_line, prm.cam_frame, prm.pairs)
        if c < seen_from(cam, prm.per_cam, b.period, 1):
            return A_STARVED, FRAME_BUFFERS  # the camera has not written the pixel
    elif k >= prm.frames * prm.n:
        return A_IDLE, -1
    if at_c:
        return A_BUSY, -1
    if prm.dram == 1:  # its read burst is in from the DRAM_READ event on
        r = event(ring, streams[ids.dram_read], burst_of(k, prm.n, prm.d_rpx)[0])
        if r == INF or c < r:
            return A_STARVED, DRAM
    elif c < memory_first_cycle(k, prm.mem_hz, prm.mem_bps):
        return A_BUSY, -1
    for t in range(prm.parts):
        tl = tiles[b.side * prm.parts + t]
        if _tile_full(ring, streams, (prm.h, prm.w), tl, fifos[tl.src_fifo], k, c):
            return A_BLOCKED, tl.src_fifo
    return A_BUSY, -1  # (not reached: it would have pushed)


@njit(cache=True, inline="always")
def status_camera(prm, c):
    """A camera's activity in its cycle c: busy in the lines of its frames."""
    busy_c = camera_in_lines(c, prm.frames, prm.h, prm.line_clocks, prm.frame_clocks, prm.pairs)
    return (A_BUSY if busy_c else A_IDLE), -1


@njit(cache=True, inline="always")
def sample_source(prm, cursors, b, c):
    """A source's traced value besides its status, after its cycle c: ``sent``, the pixels
    pushed (a camera writing frame buffers: the pixels it has streamed)."""
    if b.kind == K_MEMORY or prm.fb == 0:
        return cursors[b.stream]
    return camera_pixels_streamed(c, prm.frames, prm.h, prm.w, prm.line_clocks,
                                  prm.frame_clocks, prm.pairs)
