"""The readable kernel's chip: the plan instantiated as clocked blocks and FIFOs, run edge by
edge on the two-phase kernel (:mod:`sim.cycle.readable.kernel`). It is the specification every other
engine is held to (docs/clock-kernel.md, docs/architecture.md).

:func:`build_chip` builds the chip of a plan for a pair (or a stream of pairs) and
:meth:`Chip.run` runs it to the end; :func:`run_readable`, the dispatcher's entry
(:mod:`sim.cycle.simulate`), does both and can record a trace window.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from stereosim.core.config import ChipConfig
from stereosim.core.errors import UserError
from stereosim.core.progress import poller, progress_bar
from stereosim.sim.cycle.buffers import buffer_report, windows_of
from stereosim.sim.cycle.contract import (
    CameraOverflow,
    FrameBufferFull,
    FrameResult,
    RunStopped,
    frame_buffer_message,
    overflow_message,
    trace_clocks,
    trace_signals,
)
from stereosim.sim.cycle.fifo.readable import Fifo
from stereosim.sim.cycle.frames import FrameSupply, camera_frames
from stereosim.sim.cycle.plan import ChipPlan, build_plan
from stereosim.sim.cycle.readable.blocks.nna import Merge, NnaSubmodule
from stereosim.sim.cycle.readable.blocks.sources import (
    CameraSource,
    DramChannel,
    FrameBuffers,
    MemorySource,
    Sink,
)
from stereosim.sim.cycle.readable.blocks.sva import SvaBlock
from stereosim.sim.cycle.readable.kernel import Simulator
from stereosim.sim.cycle.report import cycle_report
from stereosim.sim.cycle.rules import camera_frame_start, sink_may_pop, sink_pattern
from stereosim.traces.log import TraceRecorder


class Chip:
    """The blocks, FIFOs and domains of one frame's simulation (built by :func:`build_chip`)."""

    def __init__(self, plan: ChipPlan, sim: Simulator, domains: dict, fifos: dict,
                 blocks: dict, frame_buffers: FrameBuffers | None = None,
                 dram: DramChannel | None = None):
        self.plan = plan
        self.dram = dram
        self.sim = sim
        self.domains = domains
        self.fifos = fifos
        self.blocks = blocks
        self.sink: Sink = blocks["sink"]
        self.frame_buffers = frame_buffers
        self.cameras = [b for b in blocks.values() if isinstance(b, CameraSource)]

    def done(self) -> bool:
        """The run's until condition: the sink holds the frames (with frame buffers: the frames
        taken, once every camera frame is decided). A camera that overflowed in the step just
        run stops the run here, after the step, naming every camera that did."""
        over = [cam.overflow for cam in self.cameras if cam.overflow is not None]
        if over:
            raise self.sim.stop(CameraOverflow, overflow_message(over, self.plan.shape[0],
                                                                 self.plan.frames))
        fb_over = next((cam.fb_overflow for cam in self.cameras if cam.fb_overflow), None)
        if fb_over is not None:
            raise self.sim.stop(FrameBufferFull, frame_buffer_message(*fb_over, self.plan.cfg))
        fb = self.frame_buffers
        if fb is None:
            return self.sink.done
        total = fb.total
        return total is not None and self.sink.received >= total * self.plan.shape[0] * \
            self.plan.shape[1]

    def window_rows(self) -> np.ndarray:
        """The row windows' instants (rows counted over the stream), in the order of
        :func:`sim.cycle.buffers.tracked`: per NNA submodule (plan order) and per layer of it
        the cycle each input row started to enter its line buffer and each output row of the
        layer was done, then the same for the SVA (an output row is done with its rows when
        its last word is issued)."""
        windows = [w for b in self.plan.blocks_of("nna")
                   for w in self.blocks[b.name].row_windows()]
        windows.append(self.blocks["sva"].row_window())
        occ = np.full((2 * len(windows), self.plan.frames * self.plan.shape[0] + 1), -1,
                      np.int64)
        for t, (entered, done) in enumerate(windows):
            occ[2 * t, :len(entered)] = entered
            occ[2 * t + 1, :len(done)] = done
        return occ

    def row_times(self) -> np.ndarray:
        """(2, H + 1) instants (fs): row r of [0] is when the left NNA's line buffers have
        received image rows 0 .. r - 1 (every left submodule whose input holds row r - 1 has
        it), row r of [1] when the sink holds r rows; 0 for r = 0, -1 where not reached."""
        h = self.plan.shape[0]
        out = np.full((2, h + 1), -1, np.int64)
        out[:, 0] = 0
        p_nna = self.plan.domains["nna"].period_fs
        for y in range(h):
            cycles = []
            for b in self.plan.blocks:
                if b.kind == "nna" and b.side == 0 and b.tile.in_y0 <= y < b.tile.in_y1:
                    line_buffer = self.blocks[b.name].line_buffer
                    cycles.append(int(line_buffer.row_cycles[y - b.tile.in_y0]))
            if min(cycles) >= 0:
                out[0, y + 1] = max(cycles) * p_nna
        sink = self.sink.row_cycles
        done = sink >= 0
        out[1, 1:][done] = sink[done] * self.plan.domains["sva"].period_fs
        return out

    def frame_times(self) -> np.ndarray:
        """(3, frames), per frame of the stream the chip took (every frame, but for a camera's
        dropped ones): [0] the instant (fs) of its first pixel -- leaving the left memory
        source, or a camera's --, [1] of its last word reaching the sink, [2] the input frame it
        is; -1 where not reached."""
        plan = self.plan
        out = np.full((3, plan.frames), -1, np.int64)
        fb = self.frame_buffers
        if fb is not None:
            taken = np.array(fb.taken, np.int64)
            cam = plan.block("camera_left")
            out[2, :len(taken)] = taken
            starts = [camera_frame_start(f, cam.frame_clocks, plan.pairs) for f in fb.taken]
            out[0, :len(taken)] = np.array(starts, np.int64) * plan.domains["camera"].period_fs
        else:
            src = next(b for b in plan.blocks if b.kind in ("memory", "camera") and b.side == 0)
            first = self.blocks[src.name].first_cycles
            out[0][first >= 0] = first[first >= 0] * plan.domains[src.domain].period_fs
            out[2] = np.arange(plan.frames)
        last = self.sink.frame_cycles
        out[1][last >= 0] = last[last >= 0] * plan.domains["sva"].period_fs
        return out

    def run(self) -> tuple[dict, dict]:
        """Run the chip to the end of the stream: (statistics, cycle report). A row window that
        overflowed raises BufferOverflow, before any stop the run ended in."""
        plan, sink = self.plan, self.sink
        sva = self.blocks["sva"]
        bar = progress_bar(sink.total // sink.width, "readable engine", "row")
        try:
            stats = self.sim.run(self.done, budget_cycles=plan.budget,
                                 on_progress=poller(bar, lambda: sink.received // sink.width),
                                 budget_remedy=plan.budget_remedy,
                                 budget_head=plan.budget_head,
                                 watchdog_cycles=plan.watchdog_cycles,
                                 watchdog_remedy=plan.watchdog_remedy)
        except UserError:
            buffer_report(plan, windows_of(plan, self.window_rows()), sva.stage_peaks())
            raise
        finally:
            bar.close()
        buffers = buffer_report(plan, windows_of(plan, self.window_rows()), sva.stage_peaks())
        if len(plan.blocks_of("nna")[0].layers) > 1:  # the layer pipeline's own counts
            stats["nna_layers"] = {b.name: self.blocks[b.name].layer_stats()
                                   for b in plan.blocks_of("nna")}
        if self.dram is not None:
            stats["dram"] = self.dram.stats()
        return stats, cycle_report(plan, sink.first_cycle, sink.last_cycle, stats, buffers,
                                   self.frame_times())


def _stall_function(sink_stall) -> Callable | None:
    """The sink's stall: a function of the cycle (True: refuse to pop), or a pattern both
    engines take (:func:`~sim.cycle.rules.sink_pattern`: a periodic ``(period, allowed_phase)``
    or a script of 0/1, one a cycle, repeated)."""
    if sink_stall is None or callable(sink_stall):
        return sink_stall
    allowed = sink_pattern(sink_stall)
    return lambda c: not sink_may_pop(c, allowed)


def _view(supply: FrameSupply, side: int) -> Callable[[int], np.ndarray]:
    """One camera's frames: frame f's image of ``side`` (0 left, 1 right)."""
    return lambda f: supply.pair(f)[side]


def build_chip(left, right, cfg: ChipConfig | ChipPlan, *, order_seed=None, sink_stall=None,
               trace=None, on_frame=None, trace_end_fs=None) -> Chip:
    """The readable chip of ``cfg`` (or of a plan) for this pair -- or stream of pairs: (N, H,
    W) stacks or a :class:`~sim.cycle.frames.FrameSupply`, whose count a plan must have.
    ``on_frame(f, words)`` receives each frame's output words as the sink completes it;
    ``trace`` (a :class:`~sim.cycle.readable.kernel.Simulator` trace hook) sees no step at or after
    ``trace_end_fs``. The chip creates the plan's domains, FIFOs and the state the blocks share
    (frame buffers, DRAM channel) and hands each block its entry and its ports' FIFOs."""
    supply = FrameSupply.of(left, right)
    plan = cfg if isinstance(cfg, ChipPlan) else build_plan(cfg, supply.shape, supply.count)
    supply = camera_frames(supply, plan)  # every camera pair sees the stream
    sim = Simulator(order_seed=order_seed, trace=trace, trace_end_fs=trace_end_fs)
    domains = {name: sim.add_domain(d.clock()) for name, d in plan.domains.items()}
    fifos = {}
    for f in plan.fifos:
        fifos[f.name] = sim.add_fifo(Fifo(f.name, f.depth, f.width_bits, f.latency_cycles,
                                          src=domains[f.src], dst=domains[f.dst],
                                          sync_cycles=f.sync_cycles, handshake_signals=True))
    fb = FrameBuffers(plan) if plan.frame_buffered else None
    if fb is not None and on_frame is not None:  # the sink counts the frames taken: give the
        taken_on_frame = on_frame  # camera's

        def on_frame(g, words):
            taken_on_frame(fb.taken[g], words)
    dram = DramChannel(plan, fb) if plan.dram is not None else None
    blocks = {}
    for entry in plan.blocks:
        ins = [fifos[name] for name in entry.inputs]
        outs = [fifos[name] for name in entry.outputs]
        kind = entry.kind
        if kind in ("memory", "camera"):
            image = _view(supply, entry.side)
            if kind == "camera":
                block = CameraSource(plan, entry, outs, image=image, buffers=fb)
            else:
                block = MemorySource(plan, entry, outs, image=image, buffers=fb, dram=dram)
        elif kind == "nna":
            block = NnaSubmodule(plan, entry, ins, outs)
        elif kind == "merge":
            block = Merge(plan, entry, ins, outs)
        elif kind == "sva":
            block = SvaBlock(plan, entry, ins, outs)
        else:
            block = Sink(plan, entry, ins, stall=_stall_function(sink_stall), on_frame=on_frame,
                         dram=dram)
        blocks[entry.name] = sim.add_block(block)
    return Chip(plan, sim, domains, fifos, blocks, fb, dram)


# ---- the dispatcher's entry: the same frame, optionally with a trace window ---------------------


class _WindowCounter:
    """A trace hook around a recorder that also counts the words the SVA pushed into the
    sink's FIFO during the window (after the steps before it, and up to its end)."""

    def __init__(self, recorder: TraceRecorder, fifo: Fifo, start_fs: int, end_fs: int):
        self.recorder, self.fifo = recorder, fifo
        self.start_fs, self.end_fs = start_fs, end_fs
        self.before = self.until = None
        self.started = False

    def __call__(self, time_fs, cycles, changes):
        pushes = self.fifo.pushes
        if time_fs < self.start_fs:
            self.before = pushes
        elif time_fs < self.end_fs:
            self.started = True
            self.until = pushes
        self.recorder(time_fs, cycles, changes)


def run_readable(plan: ChipPlan, left, right=None, *, sink_stall=None,
                 window: tuple[int, int] | None = None, order_seed=None,
                 on_frame=None) -> FrameResult:
    """One frame or a stream (the plan's) on the readable kernel; ``window`` = (start_fs,
    end_fs) records every signal of the plan in it (the trace ends one femtosecond after the
    run's last step at the latest). ``trace`` is None when the window starts after the run
    ended. ``on_frame(f, words)`` receives each frame's words as it completes. A run that
    stops raises its :class:`~sim.cycle.contract.RunStopped` with the row instants reached by
    then (``row_times``) and the trace of the window up to the stop (``trace``,
    ``outputs_in_window``)."""
    hook = None
    if window is not None:
        names = [f"{s.owner}.{s.key}" for s in plan.signals]
        recorder = TraceRecorder(trace_signals(plan), trace_clocks(plan), names=names,
                                 start_fs=window[0], end_fs=window[1])
        hook = _WindowCounter(recorder, None, *window)
    chip = build_chip(left, right, plan, order_seed=order_seed, sink_stall=sink_stall,
                      trace=hook, on_frame=on_frame,
                      trace_end_fs=None if window is None else window[1])
    if hook is not None:
        hook.fifo = chip.fifos["sva_to_sink"]
    try:
        stats, report = chip.run()
    except RunStopped as stop:
        stop.row_times = chip.row_times()
        if hook is not None:
            stop.trace, stop.outputs_in_window = _window_trace(hook, window, stop.time_fs)
        raise
    result = FrameResult(chip.sink.words.copy(), report, stats, chip.row_times(),
                         chip.frame_times())
    if hook is not None:
        result.trace, result.outputs_in_window = _window_trace(hook, window,
                                                               stats["end_time_fs"])
    return result


def _window_trace(hook: _WindowCounter, window: tuple[int, int], last_fs: int):
    """The recorded trace of ``window`` up to the run's last step at ``last_fs`` (one
    femtosecond after it at the latest) and the words pushed in it; (None, 0) when the window
    starts after that step."""
    if not hook.started:
        return None, 0
    end = min(window[1], last_fs + 1)
    return hook.recorder.log(end), (hook.until or 0) - (hook.before or 0)
