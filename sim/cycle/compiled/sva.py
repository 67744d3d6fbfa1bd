"""The SVA on the compiled engine: its joint pops, its lock-step pipeline in closed form and its
pushes (twin of the readable kernel's :class:`~sim.cycle.readable.blocks.sva.SvaBlock`, in
:mod:`sim.cycle.readable.blocks.sva`; the rules are :mod:`sim.cycle.rules`).

Streams:

- ``SVA_POP``: the SVA pops pair j (input row y) ``p[j] = max(p[j-1] + 1, vis(left[j]),
  vis(right[j]), e[last word of output row sva_rows_done_before_input(y) - 1] + 1)``, e the
  cycle a word is issued;
- ``SVA_ISSUE``: the *tick* t_j at which word j is issued; ``SVA_PUSH``: the cycle o_j it is
  pushed.

The pipeline's tick counts the cycles in which it advanced; it stalls only while the word in
its output register waits for a free slot. So between one push and the next word's arrival it
advances every cycle, and everything follows from the issue ticks, the pushes and the exit
ticks x_j = t_i + e + L (``sva_exit_item`` gives (i, e): i = j, e = 0 without the median; the
word S = m W + m later, or a flush tick, with it; :func:`exit_tick`):

- the tick at the start of cycle c, with k words pushed before c:
  ``T(c) = min(x_{k-1} + c - o_{k-1}, x_k)`` (``sva_tick_at``; before any push o = x = 0);
- word j reaches the output register in cycle ``a_j = o_{j-1} + x_j - x_{j-1}``
  (``sva_cycle_of_tick`` of its exit tick) and is pushed at ``o_j = max(a_j, q[j - depth] +
  1)``, q the sink's pops;
- word j is issued at tick ``t_j = t_{j-1} + II`` inside a row (``sva_issue_tick``), the first
  word of a row at ``sva_row_issue_tick(T(ready_j), t_{j-1}, II, r, a)`` (its r look-ahead
  slots, a the slot II) and a frame's first word at ``sva_first_word_tick`` after the frame's
  k - 1 passes (each ``sva_pass_start(T(its row complete), the previous end) + W a`` from
  ``sva_frame_start``): in the first advancing cycle with that tick: ``o_k`` if it is word
  k's exit tick (the pipeline resumes with that push), else ``sva_cycle_of_tick(t_j, o_{k-1},
  x_{k-1})`` with k the first word whose exit tick is above it. The slots that issue no word
  never wait for anything but their row and the slot II, so these closed forms are the
  readable kernel's sequencer (``sva_slot``) slot by slot.

Each of these needs only pushes that come before it in time; a value that needs a push not yet
known waits (the helpers return ok = False) and the loop moves on to the pushes. The helpers
read the rings through ``(offset, mask, lowest held index)`` triples; reading below the lowest
held index sets the ring error (the caller reruns with larger rings).

Here also: the SVA's statistics and its stages' (:func:`walk_sva`), and what it reports at an
instant (status, traced signals, its stages').
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from stereosim.core.kernel_cache import njit, njit_borrowing
from stereosim.sim.cycle.compiled.fifo import visible_by
from stereosim.sim.cycle.compiled.layout import (
    A_BLOCKED,
    A_BUSY,
    A_IDLE,
    A_STARVED,
    ERR_RING,
    INF,
)
from stereosim.sim.cycle.compiled.ring import (
    NEVER,
    BusyWatch,
    busy,
    event,
    first_at_least,
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
    rows_ready_in_frame,
    sva_cycle_of_tick,
    sva_exit_item,
    sva_first_word_tick,
    sva_frame_start,
    sva_issue_tick,
    sva_last_input_row,
    sva_pass_start,
    sva_rows_done_before_input,
    sva_slot,
    sva_tick_at,
)

# ---- the pipeline in closed form ----------------------------------------------------------------


class SvaExits(NamedTuple):
    """What a word's exit tick follows from (``sva_exit_item``): the pipeline's latency L, the
    median's skew S, a frame's words N and the ticks between its flush slots F."""

    latency: int
    skew: int
    words: int
    flush_ii: int


@njit(cache=True, inline="always")
def sva_exits(prm):
    """The SVA's :class:`SvaExits` from the run's constants ``prm``."""
    return SvaExits(latency=prm.pipe_latency, skew=prm.skew, words=prm.n, flush_ii=prm.flush_ii)


@njit(cache=True, inline="always")
def exit_tick(ring, t, ex, j):
    """Word j's exit tick (``ex`` a :class:`SvaExits`), from the issue ring ``t``; the word it
    leaves with must be issued."""
    nf = ex.words
    f = j // nf
    item, extra = sva_exit_item(j - f * nf, ex.skew, nf, ex.flush_ii)
    return rd(ring, t[0], t[1], f * nf + item) + extra + ex.latency


@njit(cache=True, inline="always")
def exits_known(kt, ex):
    """Words whose exit tick is known when ``kt`` words are issued: every word of the frames
    issued whole, and of the frame being issued those S behind the last issued."""
    skew, nf = ex.skew, ex.words
    f = kt // nf
    return f * nf + max(0, kt - f * nf - skew)


@njit(cache=True, inline="always")
def arrival(ring, o, t, ex, j):
    """The cycle word j reaches the output register (its push o_{j-1} and both exit ticks
    known)."""
    x = exit_tick(ring, t, ex, j)
    if j == 0:
        return sva_cycle_of_tick(x, 0, 0)
    return sva_cycle_of_tick(x, rd(ring, o[0], o[1], j - 1), exit_tick(ring, t, ex, j - 1))


@njit(cache=True, inline="always")
def tick_at(ring, o, t, ex, ko, kt, c):
    """(T(c), ok, ring error): the pipeline's tick at the start of cycle c from the ``ko``
    pushes and ``kt`` issue ticks known; not ok while a push not yet known may come before c.
    ``o``, ``t``: (offset, mask, lowest held index) of the push and issue rings."""
    kx = exits_known(kt, ex)
    if ko > 0 and rd(ring, o[0], o[1], ko - 1) >= c:
        lo = max(0, o[2] + 1)
        k = first_at_least(ring, o[0], o[1], lo, ko, c)
        err = k == lo and lo > 0  # the answer may lie in what the ring no longer holds
    else:
        k = ko
        err = False
        if ko < kx and c > arrival(ring, o, t, ex, ko):
            return 0, False, err  # word ko waits in the output register: its push decides
    if k == 0:
        last_push, last_exit = 0, 0
    else:
        last_push, last_exit = rd(ring, o[0], o[1], k - 1), exit_tick(ring, t, ex, k - 1)
    nxt = exit_tick(ring, t, ex, k) if k < kx else INF
    err = err or (k > 0 and (k - 1 <= o[2] or k - 1 <= t[2]))
    return sva_tick_at(c, last_push, last_exit, nxt), True, err


@njit(cache=True, inline="always")
def exiting_from(ring, t, ex, kt, tick):
    """The first of the words whose exit tick is known (of ``kt`` issued) with exit tick >=
    ``tick`` (all those known if none), and a ring error."""
    kx = exits_known(kt, ex)
    if kx == 0 or exit_tick(ring, t, ex, kx - 1) < tick:
        return kx, False
    lo = max(0, t[2] + 1)
    a, b = lo, kx - 1  # exit ticks rise with j: a binary search
    while a < b:
        mid = (a + b) // 2
        if exit_tick(ring, t, ex, mid) >= tick:
            b = mid
        else:
            a = mid + 1
    return a, a == lo and lo > 0  # the answer may lie in what the ring no longer holds


@njit(cache=True, inline="always")
def cycle_of_after(ring, o, t, ex, ko, kt, tick, k):
    """(cycle, ok): the first advancing cycle whose tick is ``tick``, k being the first word
    whose exit tick is >= ``tick`` (:func:`exiting_from`), from the ``ko`` pushes and ``kt``
    issue ticks known; not ok while it depends on a push not yet known."""
    kx = exits_known(kt, ex)
    if k < kx and exit_tick(ring, t, ex, k) == tick:
        if k < ko:
            return rd(ring, o[0], o[1], k), True  # the pipeline resumes with k's push
        return 0, False
    if k == 0:
        return sva_cycle_of_tick(tick, 0, 0), True
    if k - 1 < ko:
        return sva_cycle_of_tick(tick, rd(ring, o[0], o[1], k - 1),
                                 exit_tick(ring, t, ex, k - 1)), True
    return 0, False


@njit(cache=True, inline="always")
def cycle_of(ring, o, t, ex, ko, kt, tick):
    """(cycle, ok, ring error): :func:`cycle_of_after` with the word found by search."""
    k, err = exiting_from(ring, t, ex, kt, tick)
    e, ok = cycle_of_after(ring, o, t, ex, ko, kt, tick, k)
    return e, ok, err or (k > 0 and (k - 1 <= o[2] or k - 1 <= t[2]))


@njit(cache=True, inline="always")
def issued_before(ring, t, kt, tick):
    """Words (of the ``kt`` whose issue ticks are known) issued at ticks below ``tick``."""
    return first_at_least(ring, t[0], t[1], max(0, t[2] + 1), kt, tick)


@njit(cache=True, inline="always")
def words_between(ring, t, kt, lo_tick, hi_tick):
    """Issued words (of the ``kt`` known) with issue tick in [lo_tick, hi_tick)."""
    first = max(0, t[2] + 1)
    a = first_at_least(ring, t[0], t[1], first, kt, lo_tick)
    b = first_at_least(ring, t[0], t[1], a, kt, hi_tick)
    return b - a


# ---- the pops -----------------------------------------------------------------------------------


@njit_borrowing(cache=True)
def advance_sva_pops(net):
    """The SVA's joint pops (the readable ``SvaBlock.evaluate``'s input), as far as both
    descriptor streams and its row window (released as output rows are issued) allow."""
    prm = net.prm[0]
    ids = net.ids[0]
    p_s, f_left, f_right = ids.sva_pop, ids.fifo_sva_left, ids.fifo_sva_right
    state = net.state[0]
    ring, streams = net.ring, net.streams
    fl, fr = net.fifos[f_left], net.fifos[f_right]
    l_off, l_mask, nl, l_lo = view(streams, fl.push)
    r_off, r_mask, nr, r_lo = view(streams, fr.push)
    p_off, p_mask, j, _ = view(streams, p_s)
    n_issued = streams[ids.sva_issue].count
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
    occ_in, occ_out = ids.occ_sva_in, ids.occ_sva_out
    known = min(n, nl, nr)
    # one camera's events stand for both (prm.sides 1): the right pair is the left's
    same = fl.push == fr.push and (l_src, l_dst, l_de) == (r_src, r_dst, r_de)
    y = j // w
    x = j - y * w
    while j < known:
        if y != window_row:
            done = sva_rows_done_before_input(y, la, prm.h)
            if done > 0:
                if done * w > n_issued:
                    break
                # the cycle after its last issue
                window = occ[occ_out, (done - 1) & (occ.shape[1] - 1)] + 1
            else:
                window = 0
            window_row = y
        err |= j <= l_lo or j <= r_lo
        vl = visible_from(rd(ring, l_off, l_mask, j), l_src, l_dst, l_rat, l_de)
        vr = vl if same else visible_from(rd(ring, r_off, r_mask, j), r_src, r_dst, r_rat,
                                          r_de)
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
        state.error = ERR_RING
    return j > start


# ---- the issues and the pushes (taken in turn with the sink's pops) ------------------------------


class IssueLoop(NamedTuple):
    """The constants of :func:`issues`' loop: the view of the SVA's pops (:func:`~.ring.view`),
    the rings of its pushes and its issue ticks, the words of the stream, the clock period
    (fs), a frame's columns and box rows, the cap, the sequencer's look-ahead rows, its cycles
    a pixel, passes and slot II, the first row of a frame's first slot, and the
    :class:`SvaExits`; with the arrays it writes (taken from the Net once, not per turn): the
    ring and the issue row ends' occupancy row."""

    pops: tuple  # (offset, mask, known, highest index lost) of the SVA's pops
    push_off: int
    push_mask: int
    issue_off: int
    issue_mask: int
    n: int
    period: int
    w: int
    h: int
    cap_fs: int
    lookahead: int
    ii: int
    passes: int
    slot_ii: int
    first_row: int
    exits: SvaExits
    ring: np.ndarray
    issue_rows: np.ndarray


class IssueCursor(NamedTuple):
    """Where :func:`issues` stands: the issue ticks known, the last one, the next word's box
    row and column, the first issued word exiting at or after the next issue's tick (-1:
    search), the row whose readiness is known, its ready cycle and tick, the end of its
    frame's passes (a frame's first row; else never), whether they are known, a ring
    error."""

    issued: int
    last_tick: int
    row: int
    x: int
    exiting: int
    ready_row: int
    ready: int
    ready_tick: int
    passes_end: int
    ready_known: bool
    ring_error: bool


@njit(cache=True, inline="always")
def issues_begin(net):
    """What :func:`issues` reads: the constants of its loop and the arrays it writes (an
    :class:`IssueLoop`) and its cursor (an :class:`IssueCursor`)."""
    prm = net.prm[0]
    ids = net.ids[0]
    streams = net.streams
    o_off, o_mask, _, _ = view(streams, ids.sva_push)
    t_off, t_mask, kt, _ = view(streams, ids.sva_issue)
    st = streams[ids.sva_issue]
    k = IssueLoop(
        pops=view(streams, ids.sva_pop), push_off=o_off, push_mask=o_mask, issue_off=t_off,
        issue_mask=t_mask, n=st.n, period=st.period, w=prm.w, h=prm.h, cap_fs=prm.cap_fs,
        lookahead=prm.lookahead, ii=prm.sva_ii, passes=prm.passes, slot_ii=prm.slot_ii,
        first_row=prm.first_row, exits=sva_exits(prm), ring=net.ring,
        issue_rows=net.occ[ids.occ_sva_out])
    t_prev = rd(net.ring, t_off, t_mask, kt - 1) if kt > 0 else NEVER
    yt = kt // prm.w
    return k, IssueCursor(issued=kt, last_tick=t_prev, row=yt, x=kt - yt * prm.w, exiting=-1,
                          ready_row=-1, ready=0, ready_tick=0, passes_end=NEVER,
                          ready_known=False, ring_error=False)


@njit(cache=True, inline="always")
def issues(k, cur, ko):
    """The next words issued, each once its row is ready (a frame's first, its passes too)
    and the pipeline reaches its tick (``ko``: the pushes known), from the
    :class:`IssueCursor` ``cur`` with the constants ``k`` (an :class:`IssueLoop`). Returns
    (cursor, moved)."""
    ring, issue_rows = k.ring, k.issue_rows
    p_off, p_mask, npop, p_lo = k.pops
    o_off, o_mask, t_off, t_mask = k.push_off, k.push_mask, k.issue_off, k.issue_mask
    n, per, ex = k.n, k.period, k.exits
    w, h, cap, r, ii = k.w, k.h, k.cap_fs, k.lookahead, k.ii
    passes, a, first_row = k.passes, k.slot_ii, k.first_row
    kt, t_prev, yt, xt, kx = cur.issued, cur.last_tick, cur.row, cur.x, cur.exiting
    ready_row, ready, ready_tick = cur.ready_row, cur.ready, cur.ready_tick
    pend, ready_known, err = cur.passes_end, cur.ready_known, cur.ring_error
    o = (o_off, o_mask, ko - 1 - o_mask)
    t = (t_off, t_mask, kt - 1 - t_mask)
    moved = False
    while kt < n:
        if yt != ready_row:
            ft = yt // h  # the frame of box row yt: its rows up to the look-ahead's
            row = sva_last_input_row(yt - ft * h, r, h)
            if yt == ft * h:  # a frame's box row 0: its first slot's row (sva_slot)
                row = sva_slot(passes * w, w, h, r, passes, first_row)[0]
            need = (ft * h + row + 1) * w
            if need > npop:
                break
            err |= need - 1 <= p_lo
            ready = rd(ring, p_off, p_mask, need - 1) + 1
            ready_row = yt
            ready_known = False
        if xt == 0:
            if not ready_known:
                ready_tick, ok, bad = tick_at(ring, o, t, ex, ko, kt, ready)
                err |= bad
                if not ok:
                    break
                pend = NEVER
                ft = yt // h
                if yt == ft * h:  # a frame's first row: its passes first
                    pend = sva_frame_start(t_prev, a, ex.skew, ex.flush_ii)
                    for q in range(passes):
                        row = ft * h + sva_slot(q * w, w, h, r, passes, first_row)[0]
                        if (row + 1) * w > npop:  # its row is not in yet
                            ok = False
                            break
                        err |= (row + 1) * w - 1 <= p_lo
                        row_tick, ok, bad = tick_at(ring, o, t, ex, ko, kt,
                                                    rd(ring, p_off, p_mask, (row + 1) * w - 1)
                                                    + 1)
                        err |= bad
                        if not ok:
                            break
                        pend = sva_pass_start(row_tick, pend) + w * a
                    if not ok:
                        break
                ready_known = True
            tick = sva_first_word_tick(ready_tick, t_prev, ii, r, a, pend)
        else:  # the row was ready when its first word was issued: T(ready) <= t_prev
            tick = sva_issue_tick(NEVER, t_prev, ii)
        # the first issued word exiting at or after the tick: it only moves forward
        if kx < 0:
            kx, bad = exiting_from(ring, t, ex, kt, tick)
            err |= bad
        known = exits_known(kt, ex)
        while kx < known and exit_tick(ring, t, ex, kx) < tick:
            kx += 1
        err |= kx > 0 and (kx - 1 <= o[2] or kx - 1 <= t[2])
        e, ok = cycle_of_after(ring, o, t, ex, ko, kt, tick, kx)
        if not ok or e * per >= cap:
            break
        ring[t_off + (kt & t_mask)] = tick
        t_prev = tick
        kt += 1
        t = (t_off, t_mask, kt - 1 - t_mask)
        moved = True
        xt += 1
        if xt == w:
            issue_rows[yt & (issue_rows.shape[0] - 1)] = e
            xt = 0
            yt += 1
    return IssueCursor(issued=kt, last_tick=t_prev, row=yt, x=xt, exiting=kx,
                       ready_row=ready_row, ready=ready, ready_tick=ready_tick,
                       passes_end=pend, ready_known=ready_known, ring_error=err), moved


@njit(cache=True, inline="always")
def issues_end(net, cur):
    """Store what :func:`issues` did: the issue ticks known."""
    net.streams[net.ids[0].sva_issue].count = cur.issued
    if cur.ring_error:
        net.state[0].error = ERR_RING


class PushLoop(NamedTuple):
    """The constants of :func:`pushes`' loop: the rings of the SVA's pushes, of the sink's
    pops and of the SVA's issue ticks, the sink FIFO's depth and space edges, the clock period
    (fs), the cap and the :class:`SvaExits`."""

    push_off: int
    push_mask: int
    pop_off: int
    pop_mask: int
    issue_off: int
    issue_mask: int
    depth: int
    space_edges: int
    period: int
    cap_fs: int
    exits: SvaExits


@njit(cache=True, inline="always")
def pushes_begin(net):
    """What :func:`pushes` reads (a :class:`PushLoop`)."""
    ids = net.ids[0]
    streams = net.streams
    o_off, o_mask, _, _ = view(streams, ids.sva_push)
    q_off, q_mask, _, _ = view(streams, ids.sink_pop)
    t_off, t_mask, _, _ = view(streams, ids.sva_issue)
    prm = net.prm[0]
    fi = net.fifos[ids.fifo_sink]
    return PushLoop(push_off=o_off, push_mask=o_mask, pop_off=q_off, pop_mask=q_mask,
                    issue_off=t_off, issue_mask=t_mask, depth=fi.depth,
                    space_edges=fi.space_edges, period=streams[ids.sva_push].period,
                    cap_fs=prm.cap_fs, exits=sva_exits(prm))


@njit(cache=True, inline="always")
def pushes(k, ring, ko, kt, kq):
    """The next words pushed, each a word whose exit is known (``kt`` issued) at its arrival,
    once the slot a FIFO depth back is free (``kq``: the sink's pops known), with the
    constants ``k`` (a :class:`PushLoop`). Returns (pushes known, moved)."""
    o_off, o_mask, q_off, q_mask = k.push_off, k.push_mask, k.pop_off, k.pop_mask
    t_off, t_mask, depth, se = k.issue_off, k.issue_mask, k.depth, k.space_edges
    per, cap, ex = k.period, k.cap_fs, k.exits
    o = (o_off, o_mask, ko - 1 - o_mask)
    t = (t_off, t_mask, kt - 1 - t_mask)
    moved = False
    kx = exits_known(kt, ex)
    while ko < kx and ko - depth < kq:
        # (the sink's FIFO is in the SVA's domain)
        free = room_from(rd(ring, q_off, q_mask, ko - depth), per, per, 1.0, se) \
            if ko >= depth else 0
        out = max(arrival(ring, o, t, ex, ko), free)
        if out * per >= cap:
            break
        ring[o_off + (ko & o_mask)] = out
        ko += 1
        o = (o_off, o_mask, ko - 1 - o_mask)
        moved = True
    return ko, moved


# ---- statistics ---------------------------------------------------------------------------------


@njit_borrowing(cache=True)
def walk_sva(net, final):
    """Settle the SVA's activity for the words whose every event is known (``final``: the
    streams have stopped; a pending word waits for its row, the pipeline, then a slot). Word j,
    the next to leave, makes the block starved until its row is ready (unless a pair is popped),
    busy until it reaches the output register (:func:`arrival`:
    the pipeline is working or waiting out the II), then blocked -- the pipeline stalled --
    until it is pushed. Gaps in its busy instants can only lie in a wait for a row or for a
    slot. The stages' counts follow (:func:`_walk_stages`)."""
    prm = net.prm[0]
    state = net.state[0]
    ring = net.ring
    gaps = net.gaps
    ids = net.ids[0]
    blk, p_s = ids.block_sva, ids.sva_pop
    a = net.acc[blk]
    p_off, p_mask, npop, p_lo = view(net.streams, p_s)
    p_pops = (p_off, p_mask, npop, p_lo + 1)
    o_off, o_mask, no, o_lo = view(net.streams, ids.sva_push)
    t_off, t_mask, kt, t_lo = view(net.streams, ids.sva_issue)
    o, t = (o_off, o_mask, o_lo), (t_off, t_mask, t_lo)
    n, w, h, la = net.streams[p_s].n, prm.w, prm.h, prm.lookahead
    g = prm.watchdog_fs
    ex = sva_exits(prm)
    kx = exits_known(kt, ex)
    per = net.blocks[blk].period
    j, ptr, prev = a.walk, a.ptr, a.prev
    if j == 0:
        prev = NEVER
    last_busy, n_gaps = a.last_busy, a.gaps
    # after the last pop known no other comes (every pop is in, or the streams have stopped)
    known_until = INF if npop >= n or final else (rd(ring, p_off, p_mask, npop - 1) + 1
                                                  if npop > 0 else 0)
    # issues after the last one known come at ticks from t[kt - 1] + II on
    next_tick = INF if kt >= n or final else (rd(ring, t_off, t_mask, kt - 1) + prm.sva_ii
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
        arrive = arrival(ring, o, t, ex, j) if j < kx else never
        if j >= no:
            if final:
                ptr, _, lost, watch = note_wait(ring, p_pops, ptr, lo - 1, ready, gaps,
                                                BusyWatch(blk, n_gaps, last_busy, per, g))
                err |= lost
                n_gaps, last_busy = watch.n_gaps, watch.last_busy_fs
                if ready < INF:
                    if arrive > max(lo, ready):
                        n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy,
                                                  max(lo, ready) * per, (arrive - 1) * per, g)
                    _, _, n_gaps, last_busy = pops_in(ring, (p_off, p_mask, npop), ptr, arrive,
                                                       INF, np.bool_(True), gaps,
                                                       BusyWatch(blk, n_gaps, last_busy, per, g))
            break
        out = rd(ring, o_off, o_mask, j)
        if out > known_until:
            break  # a pop before the push may still come
        if out > arrive and next_tick < exit_tick(ring, t, ex, j):
            break  # a stall: the words in the stages then may not all be issued yet
        if ready > lo:  # waiting for the word's row
            ptr, waited, lost, watch = note_wait(ring, p_pops, ptr, lo - 1, ready, gaps,
                                                 BusyWatch(blk, n_gaps, last_busy, per, g))
            err |= lost
            starved += waited
            n_gaps, last_busy = watch.n_gaps, watch.last_busy_fs
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
            ptr, waited, lost, watch = note_wait(ring, p_pops, ptr, arrive - 1, out, gaps,
                                                 BusyWatch(blk, n_gaps, last_busy, per, g))
            err |= lost
            blocked += waited
            n_gaps, last_busy = busy(gaps, blk, watch.n_gaps, watch.last_busy_fs, out * per,
                                     out * per, g)
        err |= _walk_stages(prm, state, net.stages, ring, t, kt, j, out - arrive)
        last_busy = out * per
        prev = out
        j += 1
        x += 1
        if x == w:
            x = 0
            y += 1
    if j == state.target and a.walk < j:  # every word settled: when the last left each stage
        for s in range(net.stages.shape[0]):
            st = net.stages[s]
            st.busy += state.sva_regular * min(st.lat, prm.sva_ii) + st.lat
            tick = rd(ring, t_off, t_mask, j - 1) + st.off + st.lat
            st.done, _, bad = cycle_of(ring, o, t, ex, no, kt, tick)
            err |= bad
    a.walk, a.ptr, a.prev = j, ptr, prev
    store_activity(a, state, (starved, blocked, 0), (n_gaps, last_busy), err,
                   gaps.shape[1])


@njit(cache=True, inline="always")
def _walk_stages(prm, state, stages, ring, t, kt, j, stall):
    """Count word j into every stage: the ticks it adds to the stage's busy ones (up to the
    next word's entry), the words the stage holds when j enters it (the most: its peak), and,
    when the pipeline stalled ``stall`` cycles with j in the output register, those cycles as
    blocked for every stage holding a word then. A word issued II ticks after the previous one
    without a stall (most of them) is only counted (``state.sva_regular``: it adds min(l, II)
    busy ticks to a stage of latency l, which holds at most ceil(l / II) words then); the
    peaks are searched until a stage holds that many. Returns a ring error."""
    err = False
    t_off, t_mask, t_lo = t
    tj = rd(ring, t_off, t_mask, j)
    ii = prm.sva_ii
    gap = tj - rd(ring, t_off, t_mask, j - 1) if j > 0 else -1
    if j > 0 and j - 1 <= t_lo:
        err = True
    regular = gap == ii and stall == 0
    if regular:
        state.sva_regular += 1
        if state.sva_peaks_full == 1:
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
            x = exit_tick(ring, t, sva_exits(prm), j)
            if words_between(ring, t, kt, x - st.off - st.lat, x - st.off) > 0:
                st.blocked += stall
    state.sva_peaks_full = full
    return err


# ---- at an instant ------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _pipeline(streams, ids):
    """(push ring, issue ring, issue ticks known) of the SVA: (offset, mask, lowest held
    index) of its ``SVA_PUSH`` and ``SVA_ISSUE`` streams."""
    so, st = streams[ids.sva_push], streams[ids.sva_issue]
    return ((so.off, so.mask, so.count - 1 - so.mask), (st.off, st.mask, st.count - 1 - st.mask),
            st.count)


@njit(cache=True, inline="always")
def _tick(ring, o, t, kt, ex, k, c):
    """The SVA pipeline's tick at the start of cycle c, k words pushed before it."""
    if k == 0:
        last_push, last_exit = 0, 0
    else:
        last_push, last_exit = rd(ring, o[0], o[1], k - 1), exit_tick(ring, t, ex, k - 1)
    nxt = exit_tick(ring, t, ex, k) if k < exits_known(kt, ex) else INF
    return sva_tick_at(c, last_push, last_exit, nxt)


@njit(cache=True)
def status_sva(ring, streams, cursors, prm, tables, b, c):
    """(activity, FIFO waited on or -1) the SVA ``b`` (its record) reports in its cycle c."""
    fifos, ids = tables.fifos, tables.ids
    p_s, o_s = ids.sva_pop, ids.sva_push
    n, w, h = prm.frames * prm.n, prm.w, prm.h
    o, t, kt = _pipeline(streams, ids)
    received, pop_at = lt_at(ring, streams[p_s], cursors[p_s], c)
    emitted, push_at = lt_at(ring, streams[o_s], cursors[o_s], c)
    ex = sva_exits(prm)
    issued = issued_before(ring, t, kt, _tick(ring, o, t, kt, ex, emitted, c))
    wait = -1
    if received < n and not pop_at and issued // w >= sva_rows_done_before_input(
            received // w, prm.lookahead, h):
        for f in (b.fifo_in, b.fifo_in2):
            if not visible_by(ring, streams, fifos[f], received, c):
                wait = f
                break
    if pop_at or push_at:
        return A_BUSY, -1
    if emitted < n:
        if emitted < exits_known(kt, ex) and c >= arrival(ring, o, t, ex, emitted):
            return A_BLOCKED, b.fifo_out  # the pipeline stalls
        y = emitted // w
        fr = y // h
        ready = event(ring, streams[p_s],
                       (fr * h + sva_last_input_row(y - fr * h, prm.lookahead, h) + 1) * w - 1)
        if ready != INF and ready + 1 <= c:
            return A_BUSY, -1  # words in the pipeline, or a ready row waiting out the II
        return A_STARVED, wait if wait >= 0 else b.fifo_in
    return A_IDLE, -1


@njit(cache=True)
def sample_sva(ring, streams, cursors, prm, sva, data, c, out):
    """The SVA's signals after its cycle c into out[0:11 + 2 S]; ``sva`` = (its ids, its
    stages)."""
    ids, stages = sva
    w, h, n = prm.w, prm.h, prm.frames * prm.n
    ex = sva_exits(prm)
    o, t, kt = _pipeline(streams, ids)
    received = cursors[ids.sva_pop]
    emitted, push_at = lt_at(ring, streams[ids.sva_push], cursors[ids.sva_push], c)
    tick = _tick(ring, o, t, kt, ex, emitted, c)  # during cycle c
    stall = (not push_at and emitted < n and emitted < exits_known(kt, ex)
             and c >= arrival(ring, o, t, ex, emitted))
    if push_at:
        emitted += 1
    after = _tick(ring, o, t, kt, ex, emitted, c + 1)  # after it
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

