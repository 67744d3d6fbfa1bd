"""The pass: every block's event stream advanced in turn, each as far as what it needs is known
(the readable kernel's :class:`~sim.cycle.readable.chip.Chip` steps every block every edge;
docs/compiled-engine.md lists the recurrences, each block's file its own).

Each event depends on earlier events of its own stream and on events of other streams that are
strictly earlier in time, so :func:`run_pass` advances the streams in turn -- the sources and
line buffers (:mod:`.source`, :mod:`.nna`), the MAC arrays (:mod:`.nna`), the merges
(:mod:`.merge`), the SVA's pops (:mod:`.sva`), its issues and pushes with the sink's pops
(:mod:`.sva`, :mod:`.sink`) -- until the sink has the frame or no stream can move (a deadlock,
or the cap: events at instants from ``prm.cap_fs`` on are not computed). Events live in rings
(:mod:`.layout`); a read of an event its ring no longer holds sets ``state.error`` and the
caller reruns with larger rings. The statistics the loops do not take on the way are walked
behind the streams (:func:`walk_all`).

Two pairs of streams that wait on each other item by item are taken in turn in one loop, each
as far as the other allows, without a call per turn: a whole-frame side's source pushes and
line-buffer pops (:func:`advance_whole_side`), and the SVA's issues and pushes with the sink's
pops (:func:`advance_sva_and_sink`); each block's part of the loop is in its own file.

Flags handed from one kernel to another are runtime values (``np.bool_(True)``, not ``True``):
numba compiles a kernel once per literal argument value it is called with (a walker called with
``final=True`` and ``final=False`` compiled twice; tests/test_architecture.py keeps literal flags
out).
"""

from __future__ import annotations

import numpy as np

from stereosim.core.kernel_cache import njit_borrowing
from stereosim.sim.cycle.compiled import fifo, merge, nna, sink, source, sva
from stereosim.sim.cycle.compiled.layout import (
    END_CAP,
    END_DONE,
    END_OVERFLOW,
    END_STUCK,
    INF,
    SVA_ISSUE,
)
from stereosim.sim.cycle.compiled.ring import rd, view
from stereosim.sim.cycle.compiled.windows import walk_windows


@njit_borrowing(cache=True)
def advance_whole_side(net, side):
    """A camera served by one submodule: its source's pushes (:func:`.source.whole_pushes`) and
    its line buffer's pops (:func:`.nna.whole_pops`) taken in turn (a push needs the pop of
    the item a FIFO depth before, a pop the push of its item) -- the same events as
    :func:`.source.advance_source` and :func:`.nna.advance_line_pops`."""
    kp, push = source.whole_pushes_begin(net, side)
    kl, pop = nna.whole_pops_begin(net, side)
    start_a, start_b = push.pushes, pop.pops
    while True:
        pop, popped = nna.whole_pops(net, kl, pop, push.pushes)
        push, pushed = source.whole_pushes(net, kp, push, pop.pops)
        if push.overflow or not (popped or pushed):  # a camera overflowed, or nothing moved
            break
    nna.whole_pops_end(net, kl, pop)
    source.whole_pushes_end(net, kp, push)
    return push.pushes > start_a or pop.pops > start_b


@njit_borrowing(cache=True)
def advance_sva_and_sink(net):
    """The SVA's issues (:func:`.sva.issues`), its pushes (:func:`.sva.pushes`) and the sink's
    pops (:func:`.sink.pops`) taken in turn (an issue needs the rows' pops and the pushes
    before it, a push its issue and the pop of the word a FIFO depth before, a pop the push of
    its word)."""
    ki, issue = sva.issues_begin(net)
    kp = sva.pushes_begin(net)
    ks, pop = sink.pops_begin(net)
    ring = net.ring
    ko = net.streams[net.ids[0].sva_push].count
    start_i, start_o, start_q = issue.issued, ko, pop.pops
    while True:
        issue, issued = sva.issues(ki, issue, ko)
        ko, pushed = sva.pushes(kp, ring, ko, issue.issued, pop.pops)
        pop, popped = sink.pops(ks, pop, ko)
        if not (issued or pushed or popped):
            break
    sva.issues_end(net, issue)
    net.streams[net.ids[0].sva_push].count = ko
    sink.pops_end(net, ks, pop)
    return issue.issued > start_i or ko > start_o or pop.pops > start_q


@njit_borrowing(cache=True)
def note_horizon(net):
    """``state.horizon_fs``: the latest instant of any event computed so far."""
    horizon = 0
    streams, ring = net.streams, net.ring
    for s in range(streams.shape[0]):
        off, mask, count, _ = view(streams, s)
        if count > 0 and streams[s].kind != SVA_ISSUE:  # issues are ticks, not cycles
            t = rd(ring, off, mask, count - 1) * streams[s].period
            if t > horizon:
                horizon = t
    net.state[0].horizon_fs = horizon


def walk_all(net, final: bool) -> None:
    """Run every walker as far as it can (``final``: the streams are done or stopped; the FIFO
    walks are finished by :func:`.fifo.finish_fifos` once the run's length is known).

    Each walker is a kernel called from here, a handful of calls per walk. Linked into one
    kernel they compiled once more inside it, and the NNA's walker for several layers ran
    2.5 times slower there (0.15 against 0.06 s per 720p frame of mccnn4-slim)."""
    note_horizon(net)
    prm = net.prm[0]
    for ti in range(int(prm["sides"] * prm["parts"])):
        nna.walk_nna(net, ti, final)
    sva.walk_sva(net, final)
    walk_windows(net, final)
    if not final:
        fifo.walk_fifos(net)


def run_pass(net, progress=None):
    """Advance every stream in turn until the sink has the frame, nothing can move, a camera
    overflows or a ring error stops the pass (:func:`advance_streams`); the walkers follow
    whenever a stream has gone a quarter of its ring ahead of them, and at the end. Sets
    ``state.end``. ``progress(words)``, if given, hears the sink's pops so far at each of those
    returns.

    The walkers are called from here, not from the compiled loop: numba re-optimises every
    kernel a kernel calls inside the caller's own code, and the walkers inside the loop were a
    third of the engine's cold compile. A 720p frame returns here about 28 times."""
    walked = np.zeros(net.streams.shape[0], np.int64)
    q_s = int(net.ids[0]["sink_pop"])
    while advance_streams(net, walked):
        walk_all(net, False)
        walked[:] = net.streams["count"]
        if progress is not None:
            progress(int(net.streams[q_s]["count"]))
    if net.state[0]["error"] == 0 and net.prm[0]["stats"] == 1:
        walk_all(net, True)


@njit_borrowing(cache=True)
def advance_streams(net, walked):
    """Advance every stream in turn until the pass ends (False; ``state.end`` or
    ``state.error`` says how) or, with statistics, a stream has gone a quarter of its ring past
    ``walked`` (its count when the walkers last ran): True, the walkers are due."""
    prm = net.prm[0]
    state = net.state[0]
    streams = net.streams
    q_s = net.ids[0].sink_pop
    sides = prm.sides  # 1: the right side's events are the left's
    n_tiles = sides * prm.parts
    n_streams = streams.shape[0]
    while True:
        state.iterations += 1
        moved = False
        if prm.parts == 1:
            for side in range(sides):
                moved |= advance_whole_side(net, side)
        else:
            for side in range(sides):
                moved |= source.advance_source(net, side)
            for ti in range(n_tiles):
                moved |= nna.advance_line_pops(net, ti)
        for ti in range(n_tiles):
            moved |= nna.advance_mac_pushes(net, ti)
        if prm.merge == 1:
            for side in range(sides):
                moved |= merge.advance_merge(net, side)
        moved |= sva.advance_sva_pops(net)
        moved |= advance_sva_and_sink(net)
        if state.error != 0:
            return False
        if streams[q_s].count >= state.target:  # every frame taken is out
            state.end = END_DONE
            return False
        if not moved:
            if state.end != END_OVERFLOW:
                for side in range(sides):
                    source.pending_overflow(net, side)
            if state.end != END_OVERFLOW:
                state.end = END_STUCK if prm.cap_fs >= INF else END_CAP
            return False
        if prm.stats == 1:
            for s in range(n_streams):
                if streams[s].count - walked[s] > (streams[s].mask + 1) // 4:
                    return True
