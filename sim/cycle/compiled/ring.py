"""Reading the event rings and noting busy instants: the few helpers every loop of the compiled
engine shares (:mod:`.streams` writes the rings, :mod:`.walkers` follows them).

They take arrays and integers, never the :class:`~sim.cycle.compiled.layout.Net`: unpacking it per
call costs more than the work (numba then keeps a stream's state in registers and emits no
reference counting in the loops).
"""

from __future__ import annotations

from numba import njit


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
    """Two clock periods' ratio (for :func:`~sim.cycle.rules.seen_from_scaled`)."""
    return per_from / per_to
