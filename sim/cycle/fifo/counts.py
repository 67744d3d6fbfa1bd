"""A FIFO's statistics as every engine reports them: the readable
:class:`~sim.cycle.fifo.readable.Fifo` and the compiled engine's walk
(:mod:`sim.cycle.compiled.fifo`) hand their counts to :func:`fifo_counts`."""

from __future__ import annotations


def fifo_counts(*, pushes: int, pops: int, depth: int, width_bits: int, max_occupancy: int,
                max_producer_occupancy: int, histogram, cycles_full: int,
                cycles_empty: int) -> dict:
    """A FIFO's statistics, as every engine reports them (sorted keys; see
    :class:`sim.cycle.fifo.readable.Fifo`)."""
    return {
        "bits_transferred": int(pops) * width_bits,
        "cycles_empty": int(cycles_empty),
        "cycles_full": int(cycles_full),
        "depth": int(depth),
        "max_occupancy": int(max_occupancy),
        "max_producer_occupancy": int(max_producer_occupancy),
        "occupancy_histogram": [int(v) for v in histogram],
        "pops": int(pops),
        "pushes": int(pushes),
        "width_bits": int(width_bits),
    }
