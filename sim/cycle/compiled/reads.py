"""What the memory sources read: a camera's frame buffers and the DRAM channel, in the
compiled engine (the readable kernel's :class:`~sim.cycle.readable.blocks.sources.FrameBuffers` and
:class:`~sim.cycle.readable.blocks.sources.DramChannel`; the rules are :mod:`sim.cycle.rules`).

- which camera frame the stream's g-th frame is (:func:`decide_frame`: a frame is taken at its
  start when its pair's buffer is free, else dropped or the run stops);
- the first cycle a source may send a pixel (:func:`reader_first`: its previous push, the camera
  having written the pixel, its DRAM read burst in -- the R events, :func:`dram_ready`);
- when a run stops: the frames that start before the stop decided (:func:`decide_until`), the
  sources' token-bucket waits noted (:func:`note_source_wait`).
"""

from __future__ import annotations

from numba import njit

from stereosim.sim.cycle.compiled.layout import END_OVERFLOW, INF, K_MEMORY
from stereosim.sim.cycle.compiled.ring import busy, ratio
from stereosim.sim.cycle.rules import (
    burst_last,
    burst_of,
    camera_cycle,
    camera_frame_start,
    dram_read_ready_fs,
    dram_slot,
    first_edge_at,
    frame_buffer_admits,
    memory_first_cycle,
    seen_from_scaled,
)


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


@njit(cache=True)
def decide_frame(net, g, acc, until_fs):
    """The camera frame the g-th frame of the stream is, with frame buffers: the next camera
    frame whose pair's buffer is free when it starts (:func:`~sim.cycle.rules.frame_buffer_admits`:
    the reader finished the frame its pair took B frames before), the ones before it dropped -- or a stop (policy
    error: ``prm.end`` = END_OVERFLOW, the frame in ``acc``). Returns 1 taken, 0 undecided
    (its start is at or beyond ``until_fs``) or no camera frame left (then the stream has g
    frames: ``prm.target``), -1 stopped. A frame whose buffer is held by a frame the readers
    have not finished is not admitted."""
    prm = net.prm[0]
    while prm.fb_next < prm.frames:
        f = prm.fb_next
        start = camera_frame_start(f, prm.cam_frame, prm.pairs) * prm.per_cam
        if start >= until_fs:
            return 0
        g_pair, held = pair_frames_taken(net.frame_fs, g, f % prm.pairs, prm.pairs, prm.fb)
        busy_until = net.fbuf[1, held] if held >= 0 and net.fbuf[1, held] >= 0 else INF
        if frame_buffer_admits(g_pair, prm.fb, busy_until, start):
            net.frame_fs[0, g] = start
            net.frame_fs[2, g] = f
            prm.fb_taken = g + 1
            prm.fb_next = f + 1
            return 1
        if prm.fb_drop == 1:
            net.fbuf[0, f] = 1
            prm.fb_next = f + 1
            continue
        acc.over_cycle, acc.over_k, acc.over_tile = \
            camera_frame_start(f, prm.cam_frame, prm.pairs), f, net.frame_fs[2, held]
        prm.end = END_OVERFLOW
        return -1
    prm.target = g * prm.n
    return 0


@njit(cache=True, inline="always")
def fb_first_cycle(net, g, x, y, per_src, rat):
    """The first source cycle that may read pixel (x, y) of the g-th frame of the stream from
    its frame buffer: the first edge after the camera wrote it."""
    prm = net.prm[0]
    c = camera_cycle(net.frame_fs[2, g], x, y, prm.cam_line, prm.cam_frame, prm.pairs)
    return seen_from_scaled(c, prm.per_cam, per_src, rat, 1)


@njit(cache=True)
def dram_ready(net, k, own_side, own_count):
    """(cycle, ok, ring error): the first source cycle pixel k may leave through the DRAM
    channel -- its read burst's R event, computed here for the burst after the last known
    (:class:`~sim.cycle.readable.blocks.sources.DramChannel`: requested when both sources sent the last
    pixel of the burst ``prefetch`` before, and a camera wrote the burst's last pixel); not ok
    while a push it needs is not known (``own_count``: the pushes ``own_side`` knows)."""
    prm = net.prm[0]
    ring, streams = net.ring, net.streams
    st = streams[streams.shape[0] - 2]  # R
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
            a = streams[net.tiles[s * prm.parts].a]
            count = own_count if s == own_side else a.count
            if j >= count:
                return 0, False, False
            err |= j <= count - 1 - a.mask
            request = max(request, ring[a.off + (j & a.mask)] * a.period)
    slot = dram_slot(request, prm.d_rslot, prm.d_slot, prm.d_round, prm.d_rfirst, 1)
    prm.d_rslot = slot
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


@njit(cache=True)
def note_source_wait(net):
    """When a run stops with a memory source's next pixel not pushed: the source is busy while
    it waits for its token bucket (the readable's MemorySource: starved while the frame buffer
    or DRAM channel has not delivered the pixel, busy until its token, blocked after), so its
    busy instants run to the cycle before the token -- which the passes, noting a pixel's
    instants when it is pushed, have not noted."""
    prm = net.prm[0]
    ring, streams = net.ring, net.streams
    for blk in range(net.blocks.shape[0]):
        b = net.blocks[blk]
        if b.kind != K_MEMORY or b.side >= prm.sides:
            continue
        st = streams[b.stream]
        k = st.count
        if k >= (prm.fb_taken if prm.fb > 0 else prm.frames) * prm.n:
            continue
        per = b.period
        a_prev = ring[st.off + ((k - 1) & st.mask)] if k > 0 else -1
        first, _, ok, _ = reader_first(net, k, b.side, a_prev, per, ratio(prm.per_cam, per))
        if not ok:
            continue
        lo = max(first, memory_first_cycle(k, prm.mem_hz, prm.mem_bps))
        if lo > first:
            a = net.acc[blk]
            a.gaps, a.last_busy = busy(net.gaps, blk, a.gaps, a.last_busy, first * per,
                                       (lo - 1) * per, prm.watchdog_fs)


@njit(cache=True)
def decide_until(net, acc, until_fs):
    """When a run stops: the camera frames that start before ``until_fs`` are decided at their
    start whatever the readers do (a camera does not wait; the passes decide a frame when a
    reader reaches it), so a frame whose buffer is still held is dropped or stops the run as
    in the readable kernel."""
    prm = net.prm[0]
    while prm.fb > 0 and prm.end != END_OVERFLOW and prm.fb_next < prm.frames:
        if decide_frame(net, prm.fb_taken, acc, until_fs) != 1:
            return
