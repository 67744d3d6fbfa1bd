"""The compiled engine's driver: one frame from the plan, with the readable kernel's results
(its twin is the readable kernel's :mod:`sim.cycle.readable.chip`).

:func:`run_compiled` computes the event streams of the frame with the statistics behind them
(:func:`.schedule.run_pass`), decides how the run ends -- the sink has the frame, a camera
overflows, the cycle budget runs out, or the watchdog fires in a stretch in which no block is
busy (the intersection of every block's long gaps) -- and returns the words, the report and the
statistics the readable kernel gives, or raises the exception it raises with the same one-line
message and the same state of every FIFO and block (recomputed by a second pass that stops at
that instant; :mod:`.sampler` reads the state off the events). A traced window is recorded the
same way: a pass that stops at the window's end keeps every event of the window and
:func:`.sampler.record_window` samples every signal at every clock edge in it.
"""

from __future__ import annotations

import time

import numpy as np

from stereosim.core.kernel_cache import njit
from stereosim.nna.descriptor import compute_descriptor
from stereosim.sim.cycle.buffers import buffer_report
from stereosim.sim.cycle.compiled.fifo import fifo_counts as fifo_state
from stereosim.sim.cycle.compiled.fifo import finish_fifos, pop_cycle
from stereosim.sim.cycle.compiled.layout import (
    END_DONE,
    END_OVERFLOW,
    ERR_GAPS,
    ERR_NONE,
    INF,
    Net,
    TraceData,
    ring_capacity,
    serialise,
)
from stereosim.sim.cycle.compiled.ring import count_le, cursors_at
from stereosim.sim.cycle.compiled.sampler import (
    WindowLog,
    block_status,
    next_instant,
    record_window,
    sample,
)
from stereosim.sim.cycle.compiled.schedule import run_pass
from stereosim.sim.cycle.compiled.source import (
    DRAM,
    FRAME_BUFFERS,
    decide_until,
    note_camera,
    note_source_wait,
)
from stereosim.sim.cycle.contract import (
    ACTIVITIES,
    BudgetExceeded,
    CameraOverflow,
    DeadlockError,
    FrameBufferFull,
    FrameResult,
    RunStopped,
    activity_counts,
    budget_message,
    count_instants,
    frame_buffer_message,
    overflow_message,
    stop_message,
    trace_clocks,
    trace_signals,
    watchdog_message,
)
from stereosim.sim.cycle.fifo.counts import fifo_counts
from stereosim.sim.cycle.fifo.rule import seen_from
from stereosim.sim.cycle.frames import FrameSupply, camera_frames
from stereosim.sim.cycle.plan import ChipPlan
from stereosim.sim.cycle.report import cycle_report
from stereosim.sim.cycle.rules import (
    camera_busy_cycles,
    camera_frame_start,
    edges_through,
    sink_allowed_between,
)
from stereosim.sva.pipeline.pipeline import sva_stream
from stereosim.traces.log import TraceLog


@njit(cache=True)
def first_quiet(net, periods, end_fs):
    """The first instant before ``end_fs`` at which the watchdog fires: a clock edge at least
    the watchdog's time after the last busy instant of every block, before the next one.
    Returns (that instant, the last busy instant before it) or (INF, 0)."""
    g = net.prm[0].watchdog_fs
    nb = net.gaps.shape[0]
    ptr = np.zeros(nb, np.int64)
    while True:
        lo = -(1 << 62)
        hi = INF
        arg = -1
        for b in range(nb):
            if ptr[b] < net.acc[b].gaps:
                u, v = net.gaps[b, ptr[b], 0], net.gaps[b, ptr[b], 1]
            else:
                u, v = net.acc[b].last_busy, INF
            if u > lo:
                lo = u
            if v < hi or arg < 0:
                if v < hi:
                    hi = v
                arg = b if v <= hi else arg
        if hi - lo > g:
            t = INF
            x = max(0, lo + g)  # (edges start at t = 0)
            for per in periods:
                e = -(-x // per) * per
                if e < t:
                    t = e
            if t < hi and t < end_fs:
                return t, lo
        if hi >= INF:
            return INF, 0
        # the gap that ends first cannot meet any later one
        for b in range(nb):
            v = net.gaps[b, ptr[b], 1] if ptr[b] < net.acc[b].gaps else INF
            if v == hi:
                ptr[b] += 1
                break


def _pass(plan: ChipPlan, sink_stall, cap_fs: int, stats: bool, capacity: int | None = None,
          progress=None):
    """One pass over the streams; reruns with larger rings (or room for more long gaps) if one
    was too small."""
    cap = capacity or ring_capacity(plan)
    gap_cap = 64
    while True:
        net, names = serialise(plan, sink_stall=sink_stall, cap_fs=cap_fs, stats=stats,
                               capacity=cap, gap_capacity=gap_cap)
        if stats:
            for i, b in enumerate(plan.blocks):
                if b.kind == "camera":
                    note_camera(net, i, plan.shape[0], b.line_clocks, b.frame_clocks)
        run_pass(net, progress)
        error = net.state[0]["error"]
        if error == ERR_NONE:
            return net, names
        if error == ERR_GAPS:
            gap_cap *= 16
        elif cap > plan.frames * plan.shape[0] * plan.shape[1]:
            # every ring already holds its whole stream: nothing was overwritten
            raise RuntimeError("compiled engine: an event stream lost an event it still "
                               "needed although its ring holds the whole frame (a bug)")
        else:
            cap *= 4


def _last(net: Net, s: int) -> int:
    st = net.streams[s]
    return int(net.ring[st["off"] + ((st["count"] - 1) & st["mask"])])


def _left(name: str) -> str:
    """The left side's counterpart of a right-side block or FIFO."""
    return name.replace("right", "left")


def _budget_instant(plan: ChipPlan) -> int:
    """The instant of the budget's stop: at most the plan's :data:`~sim.cycle.plan.MAX_RUN_FS`,
    below :data:`.layout.INF` (the plan caps every domain's budget)."""
    d = plan.budget_domain
    return plan.budget[d] * plan.domains[d].period_fs


def _periods(plan: ChipPlan) -> np.ndarray:
    return np.array([d.period_fs for d in plan.domains.values()], np.int64)


# ---- a run that completes -----------------------------------------------------------------------


def _stats(plan: ChipPlan, net: Net, names: dict, t_end: int) -> dict:
    h, w = plan.shape
    prm = net.prm[0]
    # the frames the chip took: all of them, but for a camera's dropped ones -- whose beats the
    # blocks after the source wait for in vain (starved, not idle, to the end of the run)
    taken = int(net.state[0]["fb_taken"]) if plan.frame_buffered else plan.frames
    short = taken < plan.frames
    n = taken * h * w
    per = {name: d.period_fs for name, d in plan.domains.items()}
    cycles = {name: edges_through(t_end, p) for name, p in per.items()}
    nf = len(plan.fifos)
    fcyc = np.array([[cycles[f.dst], cycles[f.src]] for f in plan.fifos], np.int64)
    finish_fifos(net, fcyc)
    mirrored = int(prm["sides"]) == 1  # the right side's events are the left side's
    blocks = {}
    for i, b in enumerate(plan.blocks):
        acc = net.acc[i]
        c_d = cycles[b.domain]
        if mirrored and b.side == 1:
            blocks[b.name] = blocks[_left(b.name)]
        elif b.kind == "memory":
            active = _last(net, names["source_push"][b.side]) + 1 if n else 0
            starved = int(acc["starved"])
            if plan.frame_buffered:  # it waits for the camera until the last frame's decision
                last = camera_frame_start(plan.frames - 1, b.frame_clocks, plan.pairs)
                seen = seen_from(last, per["camera"], per[b.domain], 1)
                starved += max(0, min(c_d, seen) - active)
                active = max(active, min(c_d, seen))
            blocks[b.name] = activity_counts(active - starved - acc["blocked"], starved,
                                             acc["blocked"], c_d - active)
        elif b.kind == "camera":  # busy in the lines of its frames
            busy = camera_busy_cycles(c_d, plan.frames, h, b.line_clocks, b.frame_clocks,
                                      plan.pairs)
            blocks[b.name] = activity_counts(busy, 0, 0, c_d - busy)
        elif b.kind in ("nna", "sva"):
            s = net.blocks[i]
            stream = (names["mac_push"][b.side, max(0, int(s["tile"]))] if b.kind == "nna"
                      else int(net.ids[0]["sva_push"]))
            active = _last(net, stream) + 1
            tail = c_d - active
            blocks[b.name] = activity_counts(active - acc["starved"] - acc["blocked"],
                                             acc["starved"] + (tail if short else 0),
                                             acc["blocked"], 0 if short else tail)
        elif b.kind == "merge":
            active = _last(net, names["merge_move"][b.side]) + 1
            tail = c_d - active
            blocks[b.name] = activity_counts(n, acc["starved"] + (tail if short else 0),
                                             acc["blocked"], 0 if short else tail)
        else:
            q_last = _last(net, int(net.ids[0]["sink_pop"]))
            pattern = net.sink  # the sink's pattern (every cycle: [1, 0])
            allowed = c_d if pattern[0] == len(pattern) - 1 else \
                int(sink_allowed_between(0, q_last + 1, pattern))
            blocked = int(acc["blocked"])  # waiting on the DRAM write buffer
            blocks[b.name] = activity_counts(n, allowed - n - blocked, blocked, c_d - allowed)
    fifos = {}
    for k, f in enumerate(plan.fifos):
        if mirrored and plan.block(f.producer).side == 1:
            fifos[f.name] = fifos[_left(f.name)]
            continue
        wk = net.walks[nf + k] if f.crossing else net.walks[k]
        hist = net.hist[net.walks[k]["hoff"]:net.walks[k]["hoff"] + f.depth + 1]
        beats = taken * f.beats
        last_pop = int(pop_cycle(net, k, beats - 1))
        fifos[f.name] = fifo_counts(
            pushes=beats, pops=beats, depth=f.depth, width_bits=f.width_bits,
            max_occupancy=int(np.flatnonzero(hist).max()), max_producer_occupancy=wk["top"],
            histogram=hist, cycles_full=wk["at_depth"],
            cycles_empty=net.acc[len(plan.blocks) + k]["empty"] + cycles[f.dst] - 1 - last_pop)
    c_sva = cycles["sva"]
    stages = {}
    for st, rec in zip(plan.block("sva").stages, net.stages):
        idle = 0 if short else c_sva - int(rec["done"]) - 1
        stages[st.name] = {**activity_counts(int(rec["busy"]),
                                             c_sva - int(rec["busy"]) - int(rec["blocked"]) - idle,
                                             int(rec["blocked"]), idle),
                           "peak_words": int(rec["peak"])}
    out = _layer_stats(plan, net, cycles["nna"], short)
    if plan.dram is not None:
        bi = names["block_index"]
        reads = [int(net.acc[bi[f"memory_{side}"] if not mirrored else bi["memory_left"]]["dram"])
                 if not plan.camera_direct else 0 for side in ("left", "right")]
        out["dram"] = {"read_stall_cycles": reads,
                       "write_stall_cycles": int(net.acc[bi["sink"]]["dram"])}
    return {
        **out,
        "blocks": {b: blocks[b] for b in sorted(blocks)},
        "cycles": {name: int(cycles[name]) for name in sorted(cycles)},
        "end_time_fs": int(t_end),
        "fifos": {name: fifos[name] for name in sorted(fifos)},
        "stages": {"sva": stages},
        "steps": count_instants([(0, per[name], cycles[name]) for name in per]),
    }


def _layer_stats(plan: ChipPlan, net: Net, c_nna: int, short: bool) -> dict:
    """``{"nna_layers": {submodule: [per layer: busy, starved, blocked, idle, first and last
    output cycle]}}`` with a network of several layers (the readable ``layer_stats``): busy and
    blocked as its loop counted them, idle after its last output (starved, with frames
    dropped), starved the rest; {} with one layer."""
    subs = plan.blocks_of("nna")
    n_layers = len(subs[0].layers)
    if n_layers == 1:
        return {}
    mirrored = int(net.prm[0]["sides"]) == 1
    out = {}
    for b in subs:
        t = plan.tiles.index(b.tile) if plan.parts > 1 else 0
        ti = (0 if mirrored else b.side) * plan.parts + t
        first = int(net.tiles[ti]["layer0"])
        counts = []
        for lr in net.layers[first:first + n_layers]:
            active = _last(net, int(lr["out_stream"])) + 1
            busy, blocked = int(lr["busy"]), int(lr["blocked"])
            tail = c_nna - active
            counts.append({**activity_counts(busy, active - busy - blocked
                                             + (tail if short else 0), blocked,
                                             0 if short else tail),
                           "first_output_cycle": int(lr["first"]),
                           "last_output_cycle": active - 1})
        out[b.name] = counts
    return {"nna_layers": out}


def _stage_peaks(plan: ChipPlan, net: Net) -> dict[str, int]:
    """The most words each SVA stage held (as far as the walker got)."""
    return {st.name: int(rec["peak"]) for st, rec in zip(plan.block("sva").stages, net.stages)}


# ---- a run that stops ---------------------------------------------------------------------------


def _stop(plan: ChipPlan, sink_stall, cls, now_fs: int, executed: int, tail: str = "",
          message: str | None = None) -> RunStopped:
    """The exception the readable kernel raises at ``now_fs`` (the last executed step;
    ``executed``: steps before this instant are executed, and this one too if ``executed`` is
    ``now_fs + 1``), with the state of every FIFO and block: the kernel's message with
    ``tail``, or the chip's ``message`` (a camera's overflow)."""
    net, _ = _pass(plan, sink_stall, executed, False)
    _settle(plan, net, executed)
    cycles = {name: (executed - 1) // d.period_fs + 1 for name, d in plan.domains.items()}
    cursors_at(net, now_fs, True)
    fifos = {}
    for k, f in enumerate(plan.fifos):
        counts = fifo_state(net, k, now_fs)
        fifos[f.name] = {"occupancy": int(counts.pushes - counts.pops), "depth": f.depth}
    blocks = {}
    for i, b in enumerate(plan.blocks):
        act, wait = block_status(net, i, now_fs // plan.domains[b.domain].period_fs)
        status = ACTIVITIES[act]
        waiting = None
        if wait >= 0:
            waiting = (plan.fifos[wait].name, "full" if status == "blocked" else "empty")
        elif wait == FRAME_BUFFERS:
            waiting = ("frame buffers", "empty")
        elif wait == DRAM:
            waiting = ("dram", "full" if status == "blocked" else "empty")
        blocks[b.name] = {"status": status, "waiting_on": waiting}
    if message is None:
        message = stop_message("deadlock" if cls is DeadlockError else plan.budget_head,
                               now_fs, cycles, fifos, blocks, tail)
    return cls(message, time_fs=now_fs, cycles=dict(sorted(cycles.items())), fifos=fifos,
               blocks=blocks)


def _settle(plan: ChipPlan, net: Net, until_fs: int) -> None:
    """What a pass that stopped leaves undone, as the readable kernel would have done it by
    ``until_fs``: the camera frames that started decided, the sources' next read bursts and
    token waits noted."""
    note_source_wait(net)
    if plan.frame_buffered:
        decide_until(net, net.acc[[b.name for b in plan.blocks].index("memory_left")],
                     until_fs)
        note_source_wait(net)  # (a frame it took)


def _raise_stop(plan: ChipPlan, net: Net, names: dict, sink_stall, t_end: int) -> None:
    """Raise the exception of the earliest stop before ``t_end`` (INF: the run did not end),
    if any: the budget (checked before a step), a camera overflow (in a step), the watchdog
    (after a step)."""
    t_budget = _budget_instant(plan)
    t_over = INF
    over = []
    fb_message = None
    note_source_wait(net)
    if plan.frame_buffered:  # the frames that start before the run would stop
        t_dog, _ = first_quiet(net, _periods(plan), min(t_end, t_budget))
        _settle(plan, net, min(t_end, t_budget, t_dog))
    if net.state[0]["end"] == END_OVERFLOW and plan.frame_buffered:  # no free frame buffer
        acc = net.acc[[b.name for b in plan.blocks].index("memory_left")]
        cycle = int(acc["over_cycle"])
        t_over = cycle * plan.domains["camera"].period_fs
        fb_message = frame_buffer_message("camera_left", int(acc["over_k"]),
                                          int(acc["over_tile"]), cycle, plan.cfg)
    elif net.state[0]["end"] == END_OVERFLOW:
        index = {b.name: i for i, b in enumerate(plan.blocks)}
        mirrored = int(net.prm[0]["sides"]) == 1
        for b in plan.blocks:
            if b.kind != "camera":
                continue
            acc = net.acc[index[_left(b.name)] if mirrored else index[b.name]]
            if acc["over_cycle"] < INF:
                tile = int(acc["over_tile"]) + (plan.parts if mirrored and b.side == 1 else 0)
                t = int(acc["over_cycle"]) * plan.domains[b.domain].period_fs
                k = int(acc["over_k"])
                over.append((t, b.name, plan.fifos[int(net.tiles[tile]["src_fifo"])].name,
                             k % plan.shape[1], k // plan.shape[1], int(acc["over_cycle"])))
        t_over = min(e[0] for e in over)
    limit = min(t_end, t_budget, t_over)
    t_dog, quiet_from = first_quiet(net, _periods(plan), limit)
    if t_budget <= min(t_end, t_over, t_dog):
        now = max(((t_budget - 1) // d.period_fs) * d.period_fs for d in plan.domains.values())
        limit_d = plan.budget_domain
        raise _stop(plan, sink_stall, BudgetExceeded, now, t_budget,
                    budget_message(limit_d, plan.budget[limit_d], plan.budget_remedy))
    if t_over <= t_dog and t_over < INF:
        if fb_message is not None:
            raise _stop(plan, sink_stall, FrameBufferFull, t_over, t_over + 1,
                        message=fb_message)
        raise _stop(plan, sink_stall, CameraOverflow, t_over, t_over + 1,
                    message=overflow_message([e[1:] for e in over if e[0] == t_over],
                                             plan.shape[0], plan.frames))
    if t_dog < INF:
        raise _stop(plan, sink_stall, DeadlockError, t_dog, t_dog + 1,
                    watchdog_message(t_dog - quiet_from, plan.p_max_fs, plan.watchdog_remedy))


# ---- traces -------------------------------------------------------------------------------------


def _trace(plan: ChipPlan, sink_stall, window: tuple[int, int], t_end: int, data) -> tuple:
    start, end = window
    end = min(end, t_end + 1)
    if start > t_end:
        return None, 0
    periods = _periods(plan)
    span = (end - start) // int(periods.min()) + 16
    cap = ring_capacity(plan) + span
    net, names = _pass(plan, sink_stall, end, False, capacity=1 << int(cap - 1).bit_length())
    if plan.dram is not None:
        # a source held past the window's end has asked the channel for its next read burst
        # (the readable MemorySource does so whenever it evaluates): its DRAM_READ event
        note_source_wait(net)
    n_sig = len(plan.signals)
    initial = np.zeros(n_sig, np.uint64)
    done = np.full((len(plan.blocks) + len(plan.fifos), 2), -1)
    if start > 0:
        t0 = max(((start - 1) // int(p)) * int(p) for p in periods)
        cursors_at(net, t0, True)
        sample(net, data, t0, initial, done)
    size = max(1 << 16, 4 * n_sig)
    ctl = np.array([0, next_instant(periods, start - 1)], np.int64)
    last = initial.copy()
    scratch = initial.copy()  # the signals as ``done`` says they were sampled
    times = np.zeros(size, np.int64)
    ids = np.zeros(size, np.int32)
    values = np.zeros(size, np.uint64)
    while not record_window(net, data, periods, end,
                            WindowLog(ctl, last, times, ids, values, scratch, done)):
        times = np.concatenate([times, np.zeros_like(times)])
        ids = np.concatenate([ids, np.zeros_like(ids)])
        values = np.concatenate([values, np.zeros_like(values)])
    k = int(ctl[0])
    log = TraceLog(signals=trace_signals(plan), clocks=trace_clocks(plan), start_fs=start,
                   end_fs=end, initial=initial, times_fs=times[:k].copy(), ids=ids[:k].copy(),
                   values=values[:k].copy())
    per_sva = plan.domains["sva"].period_fs
    o_s = int(net.ids[0]["sva_push"])
    first = -(-start // per_sva)
    outputs = count_le(net, o_s, (end - 1) // per_sva) - (count_le(net, o_s, first - 1)
                                                          if first > 0 else 0)
    return log, int(outputs)


# ---- the frame ----------------------------------------------------------------------------------


def _windows(plan: ChipPlan, net: Net) -> list[tuple[int, int]]:
    """(peak, cycle) of every row window, in ``buffers.tracked`` order, from the window walks
    (a mirrored right side's are the left side's)."""
    walks = [(int(w["peak"]), int(w["at"])) for w in net.win]
    nna = plan.blocks_of("nna")[0]
    per_side = plan.parts * (len(nna.layers) + any(b.name == "nna.census_rows"
                                                    for b in nna.buffers))
    tiles = walks[:-1]
    if int(net.prm[0]["sides"]) == 1:
        tiles = tiles + tiles
    return tiles[:2 * per_side] + walks[-1:]


def _window_frames(plan: ChipPlan, frame_fs: np.ndarray, window: tuple[int, int]) -> range:
    """The frames whose data a trace of ``window`` may show: from the one before the first
    frame still in the chip at its start (the last word a block pushed may be that frame's) to
    the last one whose first pixel entered before its end."""
    start, end = window
    out = frame_fs[1]
    f_lo = max(0, int(((out >= 0) & (out < start)).sum()) - 1)
    f_hi = max(f_lo, min(plan.frames - 1, int(((frame_fs[0] >= 0)
                                                & (frame_fs[0] < end)).sum()) - 1))
    return range(f_lo, f_hi + 1)


def _trace_data(plan: ChipPlan, descs: list, words: list, first: int) -> TraceData:
    """What the trace sampler reads the data signals from: the descriptors and words of the
    traced frames, the first of which is frame ``first`` of the stream."""
    return TraceData(np.stack(descs), np.stack(words), np.int64((1 << plan.word_bits) - 1),
                     np.int64(first))


def _stop_trace(plan: ChipPlan, sink_stall, window: tuple[int, int], supply, net: Net,
                stop: RunStopped) -> tuple:
    """The trace of ``window`` up to a stop (its last executed step), with the words pushed in
    it, as the readable kernel records it; ``net`` is the first pass (the frames' instants)."""
    h, w = plan.shape
    traced = _window_frames(plan, net.frame_fs, (window[0], min(window[1], stop.time_fs + 1)))
    descs, words = [], []
    for f in traced:
        src = int(net.frame_fs[2, f])
        if src < 0:  # no frame taken yet: none of its data is in the chip
            descs.append(np.zeros((2, h, w), np.uint64))
            words.append(np.zeros((h, w), np.int32))
            continue
        left_f, right_f = supply.pair(src)
        desc = (compute_descriptor(left_f, plan.spec.nna),
                compute_descriptor(right_f, plan.spec.nna))
        descs.append(np.stack(desc).astype(np.uint64))
        words.append(sva_stream(desc[0], desc[1], left_f, plan.spec.sva, plan.part_bits))
    data = _trace_data(plan, descs, words, traced.start)
    return _trace(plan, sink_stall, window, stop.time_fs, data)


def run_compiled(plan: ChipPlan, left, right=None, *, sink_stall=None,
                 window: tuple[int, int] | None = None, timings: dict | None = None,
                 on_frame=None, words: bool = True, progress=None) -> FrameResult:
    """One frame or a stream of frames (the plan's: (N, H, W) stacks or a
    :class:`~sim.cycle.frames.FrameSupply`) on the compiled engine: the readable kernel's
    words, report and statistics, or its exception; ``window`` = (start_fs, end_fs) records
    the trace of that window. ``sink_stall``: the sink's pattern
    (:func:`~sim.cycle.rules.sink_pattern`: ``(period, allowed_phase)`` or a script of 0/1).
    ``on_frame(f, words)`` receives each frame's output words, in order, as they are computed
    (the timing does not depend on the pixels: frame f is read only then); ``words=False``
    computes none (the result's ``words`` is None: the caller takes them from
    :func:`~sim.cycle.frames.functional_words`, frame by frame). ``progress(frames)``
    hears, now and then while the event streams run, how many frames the sink has taken whole
    (:func:`.schedule.run_pass`). ``timings`` (a dict) receives
    the CPU seconds of the event streams and statistics (``engine_s``), the NNA's descriptors
    (``nna_kernels_s``) and the SVA's stream (``sva_kernels_s``). A run that stops raises the
    readable kernel's :class:`~sim.cycle.contract.RunStopped`, with the row instants reached by
    then (``row_times``) and the trace of ``window`` up to the stop (``trace``,
    ``outputs_in_window``)."""
    supply = FrameSupply.of(left, right)
    supply = camera_frames(supply, plan)  # every camera pair sees the stream
    t0 = time.process_time()
    per_frame = plan.shape[0] * plan.shape[1]  # the sink's words of a frame: one a pixel
    heard = None if progress is None else (lambda words: progress(words // per_frame))
    net, names = _pass(plan, sink_stall, _budget_instant(plan), True, progress=heard)
    t_end = INF
    q_s = int(net.ids[0]["sink_pop"])
    if net.state[0]["end"] == END_DONE:
        t_end = _last(net, q_s) * plan.domains["sva"].period_fs
    # an overflow before any stop
    buffers = buffer_report(plan, _windows(plan, net), _stage_peaks(plan, net))
    try:
        _raise_stop(plan, net, names, sink_stall, t_end)
    except RunStopped as stop:
        rows = net.rows.copy()
        rows[rows > stop.time_fs] = -1  # what the first pass computed beyond the stop
        stop.row_times = rows
        if window is not None:
            stop.trace, stop.outputs_in_window = _stop_trace(plan, sink_stall, window, supply,
                                                             net, stop)
        raise
    stats = _stats(plan, net, names, t_end)
    frame_fs = net.frame_fs.copy()
    report = cycle_report(plan, int(net.state[0]["first_pop"]), _last(net, q_s),
                          stats, buffers, frame_fs)
    rows = net.rows.copy()
    # the event net (its rings and statistics) is done with: let its memory go before the
    # frames' descriptors and words are made, so the two are not held at once
    del net
    t1 = time.process_time()
    traced = _window_frames(plan, frame_fs, window) if window is not None else range(0)
    kept_desc, kept_words = [], []
    nna_s = sva_s = 0.0
    last = None
    for f in range(int(np.count_nonzero(frame_fs[2] >= 0))):  # the frames the chip took
        if not words and f not in traced:
            continue
        left_f, right_f = supply.pair(int(frame_fs[2, f]))
        ta = time.process_time()
        desc = (compute_descriptor(left_f, plan.spec.nna),
                compute_descriptor(right_f, plan.spec.nna))
        tb = time.process_time()
        last = sva_stream(desc[0], desc[1], left_f, plan.spec.sva, plan.part_bits)
        nna_s += tb - ta
        sva_s += time.process_time() - tb
        if f in traced:
            kept_desc.append(np.stack(desc).astype(np.uint64))
            kept_words.append(last)
        if on_frame is not None and words:
            on_frame(int(frame_fs[2, f]), last)
    if timings is not None:
        timings.update(engine_s=t1 - t0, nna_kernels_s=nna_s, sva_kernels_s=sva_s)
    result = FrameResult(last if words else None, report, stats, rows, frame_fs)
    if window is not None:
        data = _trace_data(plan, kept_desc, kept_words, traced.start)
        result.trace, result.outputs_in_window = _trace(plan, sink_stall, window, t_end, data)
    return result
