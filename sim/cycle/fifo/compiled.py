"""The FIFO's helpers on the compiled engine that are FIFO rules rather than a walk over
streams (the walk of every FIFO's occupancy is :mod:`sim.cycle.compiled.fifo`): what a FIFO
traces at an instant, as the readable :meth:`~sim.cycle.fifo.readable.Fifo.signal_values`."""

from __future__ import annotations

from stereosim.core.kernel_cache import njit


@njit(cache=True, inline="always")
def sample_fifo(counts, depth, out):
    """A FIFO's traced values from its ``counts`` (a
    :class:`~sim.cycle.compiled.fifo.FifoCounts`) into out[0:5]: occupancy, pushed and popped
    in the last edges, full as its producer sees it, empty."""
    occ = counts.pushes - counts.pops
    out[0] = occ
    out[1] = 1 if counts.pushed else 0
    out[2] = 1 if counts.popped else 0
    out[3] = 1 if counts.pushes - counts.seen >= depth else 0
    out[4] = 1 if occ == 0 else 0
