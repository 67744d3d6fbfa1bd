"""The chip's state at an instant, read off the event streams: what every block reported at its
last edge and every traced signal, each block's from its own file (``status_*``,
``sample_*``), in the plan's order. The stop message of a run that stops and the trace of a
window come from here (:mod:`.run`).

Everything at an instant t depends only on events at instants <= t: a block of a domain with
period P reports at its last edge c = t // P what the readable block's ``evaluate`` would, given
how many of its beats came before c (the cursors, :func:`.ring.cursors_at`), whether one comes
at c, and the few events its rule looks at (:mod:`sim.cycle.rules`); an event the streams do not
hold is later than any instant asked for (the caller computes them up to it). Activities are
``layout.A_*``; the traced status code is (activity + 1) % 4: 0 idle, 1 busy, 2 starved, 3
blocked.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from stereosim.core.kernel_cache import njit
from stereosim.sim.cycle.compiled.fifo import counts_at
from stereosim.sim.cycle.compiled.layout import (
    INF,
    K_CAMERA,
    K_MEMORY,
    K_MERGE,
    K_NNA,
    K_SINK,
    K_SVA,
    StatusTables,
)
from stereosim.sim.cycle.compiled.merge import sample_merge, status_merge
from stereosim.sim.cycle.compiled.nna import sample_nna, status_nna
from stereosim.sim.cycle.compiled.ring import cursors_at
from stereosim.sim.cycle.compiled.sink import sample_sink, status_sink
from stereosim.sim.cycle.compiled.source import sample_source, status_camera, status_memory
from stereosim.sim.cycle.compiled.sva import sample_sva, status_sva
from stereosim.sim.cycle.fifo.compiled import sample_fifo


@njit(cache=True, inline="always")
def _tables(net):
    """The :class:`.layout.StatusTables` of ``net``."""
    return StatusTables(net.tiles, net.fifos, net.frame_fs, net.ids[0], net.sink)


@njit(cache=True)
def _block_status(events, prm, state, tables, layers, b, c):
    """(activity, FIFO waited on or a code of :mod:`.source`, or -1) that block ``b`` (its
    record) reports in its cycle c; ``events`` = (ring, streams, cursors), ``tables`` a
    :class:`.layout.StatusTables`, ``layers`` the NNA tiles' layers."""
    ring, streams, cursors = events
    kind = b.kind
    if kind == K_MEMORY:
        return status_memory(ring, streams, cursors, prm, state, tables, b, c)
    if kind == K_CAMERA:
        return status_camera(prm, c)
    if kind == K_NNA:
        return status_nna(ring, streams, cursors, prm, tables.tiles[b.side * prm.parts + b.tile],
                          layers, c)
    if kind == K_MERGE:
        return status_merge(ring, streams, cursors, prm, tables, b, c)
    if kind == K_SVA:
        return status_sva(ring, streams, cursors, prm, tables, b, c)
    return status_sink(ring, streams, cursors, prm, tables, b, c)


@njit(cache=True)
def block_status(net, blk, c):
    """(activity, FIFO waited on or -1) that block ``blk`` reports in its cycle c (after
    :func:`.ring.cursors_at` for the instant)."""
    return _block_status((net.ring, net.streams, net.cursors), net.prm[0], net.state[0],
                         _tables(net), net.layers, net.blocks[blk], c)


@njit(cache=True, inline="always")
def _block_signals(kind, n_stages, n_layers):
    """How many signals a block of this kind traces (its activity first)."""
    if kind == K_MEMORY or kind == K_CAMERA:
        return 2
    if kind == K_NNA:  # per layer 5 (and its status with several), out.valid, out.descriptor
        return 3 + 5 * n_layers + (n_layers if n_layers > 1 else 0)
    if kind == K_SVA:
        return 12 + 2 * n_stages
    return 3


@njit(cache=True)
def sample(net, data, t, out, done):
    """Every traced signal's value after the step at instant t, in the plan's order (blocks,
    then FIFOs; :func:`sim.cycle.plan._signals`), after :func:`.ring.cursors_at` for the
    instant. A block's signals change only at its clock's edges, a FIFO's at its producer's or
    its consumer's: ``done`` (int64 (blocks + FIFOs, 2), -1 at first) holds the cycles ``out``
    already shows for each, which are not evaluated again."""
    ring, streams, cursors, tiles, fifos = net.ring, net.streams, net.cursors, net.tiles, net.fifos
    prm = net.prm[0]
    ids = net.ids[0]
    tables = _tables(net)
    blocks = net.blocks
    n_blocks = blocks.shape[0]
    n_layers = tiles[0].n_layers
    k = 0
    for blk in range(n_blocks):
        b = blocks[blk]
        c = t // b.period
        m = _block_signals(b.kind, prm.n_stages, n_layers) - 1
        if done[blk, 0] == c:
            k += m + 1
            continue
        done[blk, 0] = c
        st, _ = _block_status((ring, streams, cursors), prm, net.state[0], tables, net.layers,
                              b, c)
        out[k] = (st + 1) % 4  # idle 0, busy 1, starved 2, blocked 3
        k += 1
        if b.kind == K_MEMORY or b.kind == K_CAMERA:
            out[k] = sample_source(prm, cursors, b, c)
        elif b.kind == K_NNA:
            sample_nna(ring, streams, cursors, prm, (tiles[b.side * prm.parts + b.tile],
                                                     net.layers), data, c, out[k:k + m])
        elif b.kind == K_MERGE:
            sample_merge(ring, streams, cursors, fifos, b, c, out[k:k + m])
        elif b.kind == K_SVA:
            sample_sva(ring, streams, cursors, prm, (ids, net.stages), data, c, out[k:k + m])
        elif b.kind == K_SINK:
            sample_sink(ring, streams, cursors, ids, c, out[k:k + m])
        k += m
    for f in range(fifos.shape[0]):
        fi = fifos[f]
        c_src, c_dst = t // fi.per_src, t // fi.per_dst
        if done[n_blocks + f, 0] != c_src or done[n_blocks + f, 1] != c_dst:
            done[n_blocks + f, 0], done[n_blocks + f, 1] = c_src, c_dst
            sample_fifo(counts_at(ring, streams, cursors, prm, tiles, fi, t), fi.depth,
                        out[k:k + 5])
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


class WindowLog(NamedTuple):
    """What :func:`record_window` writes: ``ctl`` = [changes logged, the next instant], the
    signals' ``last`` values, the changes' ``times`` (fs), signal ``ids`` and ``values``, and
    :func:`sample`'s ``scratch`` (the signals) and ``done`` (the cycles it shows)."""

    ctl: np.ndarray  # int64 (2,)
    last: np.ndarray  # uint64 (signals,)
    times: np.ndarray  # int64
    ids: np.ndarray  # int32
    values: np.ndarray  # uint64
    scratch: np.ndarray  # uint64 (signals,)
    done: np.ndarray  # int64 (blocks + FIFOs, 2)


@njit(cache=True)
def record_window(net, data, periods, end, log):
    """Record the traced signals from the instant ``log.ctl[1]`` until ``end`` (exclusive):
    every change against ``log.last`` goes to (times, ids, values) from ``log.ctl[0]`` on
    (``log`` a :class:`WindowLog`). Returns False when the arrays are full (grow them and call
    again: ``ctl`` holds where)."""
    ctl, last, times, ids, values = log.ctl, log.last, log.times, log.ids, log.values
    scratch, done = log.scratch, log.done
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
