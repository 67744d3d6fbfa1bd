"""Reading the event rings: the few helpers every block's loops, walkers and samplers share
(each block's file writes its streams' rings and reads the others' through these).

They take arrays and integers, never the :class:`~sim.cycle.compiled.layout.Net`: unpacking it per
call costs more than the work (numba then keeps a stream's state in registers and emits no
reference counting in the loops).
"""

from __future__ import annotations

from typing import NamedTuple

from stereosim.core.kernel_cache import njit
from stereosim.sim.cycle.compiled.layout import ERR_GAPS, ERR_RING, INF, SVA_ISSUE

NEVER = -(1 << 40)  # the previous issue tick before the SVA's first word


class BusyWatch(NamedTuple):
    """A walker's watch over a block's busy instants (:func:`busy`, :func:`pops_in`): the
    block, the long gaps noted so far, its last busy instant (fs), its clock period (fs) and the
    watchdog's time (fs): a gap longer than it is noted."""

    block: int
    n_gaps: int
    last_busy_fs: int
    period_fs: int
    watchdog_fs: int


@njit(cache=True, inline="always")
def view(streams, s):
    """(ring offset, mask, known events, the highest index the ring no longer holds) of stream
    s."""
    st = streams[s]
    return st.off, st.mask, st.count, st.count - 1 - st.mask


@njit(cache=True, inline="always")
def rd(ring, off, mask, i):
    """Event i of the stream at ``off`` with ``mask`` (the caller knows the ring holds it)."""
    return ring[off + (i & mask)]


@njit(cache=True, inline="always")
def busy(gaps, blk, n_gaps, last_busy, u, v, g):
    """Block ``blk`` is busy over the instants u .. v (fs, in time order) after ``last_busy``: a
    gap longer than the watchdog's time ``g`` is kept in ``gaps[blk]`` (``n_gaps`` kept so far;
    counted on beyond its room, which the caller reports). Returns (n_gaps, last busy)."""
    if u - last_busy > g:
        if n_gaps < gaps.shape[1]:
            gaps[blk, n_gaps, 0] = last_busy
            gaps[blk, n_gaps, 1] = u
        n_gaps += 1
    return n_gaps, (v if v > last_busy else last_busy)


@njit(cache=True, inline="always")
def ratio(per_from, per_to):
    """Two clock periods' ratio (for :func:`~sim.cycle.fifo.rule.seen_from_scaled`)."""
    return per_from / per_to


@njit(cache=True, inline="always")
def first_at_least(ring, off, mask, lo, hi, v):
    """The first index in [lo, hi) whose (increasing) event is >= v (hi if none)."""
    while lo < hi:
        mid = (lo + hi) // 2
        if ring[off + (mid & mask)] >= v:
            hi = mid
        else:
            lo = mid + 1
    return lo


# ---- what the walkers share: pops inside a block's waits ----------------------------------------


@njit(cache=True, inline="always")
def skip(ring, off, mask, ptr, limit, c):
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
def catch_up(ring, off, mask, ptr, lowest, lo):
    """A pointer into a ring that has moved on: jump to the ``lowest`` event it still holds if
    everything before it is earlier than cycle ``lo`` (then nothing uncounted was lost).
    Returns (pointer, lost: the ring was too small)."""
    if ptr >= lowest:
        return ptr, False
    return lowest, ring[off + (lowest & mask)] > lo


@njit(cache=True)
def pops_in(ring, pops, ptr, lo, hi, long, gaps, watch):
    """Count the pops in cycles [lo, hi) (skipping those before lo); inside an interval longer
    than the watchdog's time (``long``) each is a busy instant to note. ``pops`` = (ring offset,
    mask, known events) of the pop stream; ``watch`` a :class:`BusyWatch` of :func:`busy`.
    Returns (pointer past them, count, n_gaps, last busy)."""
    off, mask, limit = pops
    blk, per, g = watch.block, watch.period_fs, watch.watchdog_fs
    n_gaps, last_busy = watch.n_gaps, watch.last_busy_fs
    ptr = skip(ring, off, mask, ptr, limit, lo)
    first = ptr
    if long:
        while ptr < limit:
            c = ring[off + (ptr & mask)]
            if c >= hi:
                break
            n_gaps, last_busy = busy(gaps, blk, n_gaps, last_busy, c * per, c * per, g)
            ptr += 1
    else:
        ptr = skip(ring, off, mask, ptr, limit, hi)
    return ptr, ptr - first, n_gaps, last_busy


@njit(cache=True, inline="always")
def note_wait(ring, pops, ptr, last, hi, gaps, watch):
    """A block's wait over its cycles last + 1 .. hi - 1, after its busy cycle ``last`` (for
    its input or for a free slot): a cycle of it with a pop is busy, the others are the wait's
    (starved or blocked). The pops are the block's busy instants; they are noted
    (:func:`pops_in`) only when the wait reaches further than the watchdog's time past the
    last busy instant -- else none of them can end a long gap, nor can the wait's end. ``pops``
    = (ring offset, mask, known events, the lowest index the ring holds) of the pop stream,
    ``ptr`` the first pop not counted, ``watch`` a :class:`BusyWatch`. Returns (pointer past
    the wait's pops, cycles waited, whether the ring lost pops, the watch after them)."""
    off, mask, limit, lowest = pops
    ptr, lost = catch_up(ring, off, mask, ptr, lowest, last + 1)
    per, g = watch.period_fs, watch.watchdog_fs
    long = hi >= INF or hi * per - watch.last_busy_fs > g
    ptr, cnt, n_gaps, last_busy = pops_in(ring, (off, mask, limit), ptr, last + 1, hi, long,
                                          gaps, watch)
    return ptr, hi - last - 1 - cnt, lost, BusyWatch(watch.block, n_gaps, last_busy, per, g)


@njit(cache=True, inline="always")
def store_activity(acc, state, waits, noted, err, room):
    """Add a pass of a block's walker to its statistics ``acc``: ``waits`` = (cycles starved,
    blocked, of those waiting for the DRAM channel), ``noted`` = (long gaps noted, last busy
    instant) (:func:`busy`); a ring that lost events (``err``) or more gaps than the ``room``
    kept is the run's error (``state``)."""
    starved, blocked, dram = waits
    n_gaps, last_busy = noted
    acc.starved += starved
    acc.blocked += blocked
    acc.dram += dram
    acc.last_busy, acc.gaps = last_busy, n_gaps
    if err:
        state.error = ERR_RING
    if n_gaps > room:
        state.error = ERR_GAPS


# ---- what the samplers share: the events up to an instant ---------------------------------------


@njit(cache=True, inline="always")
def at(ring, st, i):
    """Event i of the stream whose record is ``st`` (the ring holds it)."""
    return ring[st.off + (i & st.mask)]


@njit(cache=True, inline="always")
def event(ring, st, i):
    """Event i of the stream ``st``, or INF if the streams do not hold it (later than asked)."""
    if i < st.count:
        return ring[st.off + (i & st.mask)]
    return INF


@njit(cache=True, inline="always")
def lt_at(ring, st, le, c):
    """(events of stream ``st`` before cycle c, is there one at c), c being the cycle of the
    cursors' instant in the stream's domain and ``le`` the stream's cursor."""
    at_c = le > 0 and ring[st.off + ((le - 1) & st.mask)] == c
    return le - (1 if at_c else 0), at_c


@njit(cache=True)
def count_le(net, s, c):
    """Known events of stream s at cycles <= c (the ring holds the ones asked about)."""
    ring = net.ring
    st = net.streams[s]
    hi = st.count
    lo = max(0, hi - st.mask - 1)
    if hi == 0 or at(ring, st, hi - 1) <= c:
        return hi
    if at(ring, st, lo) > c:
        return lo
    # events lo .. hi - 1 increase; find the first > c
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if at(ring, st, mid) <= c:
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
        if st.kind == SVA_ISSUE:
            continue  # ticks, not cycles: the SVA's sampler reads them by tick
        c = t // st.period
        if init:
            cur[s] = count_le(net, s, c)
        else:
            i = cur[s]
            while i < st.count and ring[st.off + (i & st.mask)] <= c:
                i += 1
            cur[s] = i
