"""The contract between the two cycle engines: what a run of the chip produces, whichever
engine ran it, defined once so that neither engine owns it.

- the result of a frame or a stream (:class:`FrameResult`) and the trace's signal and clock
  lists the plan gives (:func:`trace_signals`, :func:`trace_clocks`);
- the statistics both count: a block's cycles by activity (:data:`ACTIVITIES`,
  :func:`activity_counts`; a FIFO's counts are the FIFO primitive's,
  :func:`sim.cycle.fifo.counts.fifo_counts`) and the kernel's steps (one per distinct clock edge
  instant, :func:`count_instants`);
- how a run stops early, as both report it: a deadlock (:class:`DeadlockError`) and an
  exhausted cycle budget (:class:`BudgetExceeded`: the user's ``--max-cycles``, a stop asked
  for, or the automatic budget's safety net, :attr:`ChipPlan.budget_reason`) are the
  kernel's; a camera overflow is the chip's: a camera cannot wait, so a full FIFO when a pixel
  is due stops the run (:class:`CameraOverflow`), and so does a frame that finds no free frame
  buffer (:class:`FrameBufferFull`). Every camera that overflows in the same step is named (the step
  completes first, so the order in which the blocks evaluate cannot change the message). Each
  is a :class:`RunStopped` carrying the state of every FIFO and block after the last step the
  run executed, with its one-line message (:func:`stop_message` and the tails below), and
  :func:`stop_report` makes that state the ``stopped`` section of the report a stopped run
  publishes (docs/reliability.md).

The readable kernel (:mod:`sim.cycle.readable`) and the compiled engine
(:mod:`sim.cycle.compiled`) import this module and never each other; the chip plan imports
neither.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stereosim.core.errors import UserError
from stereosim.sim.cycle.plan import ChipPlan
from stereosim.traces.log import Clock, Signal, TraceLog

ACTIVITIES = ("busy", "starved", "blocked", "idle")


class RunStopped(UserError):
    """A run stopped before its ``until`` condition held; carries the state of the chip.

    Attributes: ``time_fs`` (instant of the last executed step), ``cycles`` (cycles run per
    domain), ``fifos`` (name -> ``{"occupancy", "depth"}``), ``blocks`` (name -> ``{"status",
    "waiting_on"}`` where ``waiting_on`` is ``(fifo_name, "empty" | "full")`` or ``None``).
    A chip's run fills in more on the way up (None until then): ``row_times`` (the row
    instants reached, as :meth:`sim.cycle.readable.chip.Chip.row_times`), ``trace`` (the
    :class:`~traces.log.TraceLog` of a traced run, up to the stop) with ``outputs_in_window``,
    ``engine`` (the cycle engine that ran) and, from :func:`stereosim.run`, ``report`` (the
    stopped run's report, its ``stopped`` section from :func:`sim.cycle.contract.stop_report`).
    """

    def __init__(self, message: str, *, time_fs: int, cycles: dict, fifos: dict, blocks: dict):
        super().__init__(message)
        self.time_fs = time_fs
        self.cycles = cycles
        self.fifos = fifos
        self.blocks = blocks
        self.row_times = None
        self.trace = None
        self.outputs_in_window = 0
        self.engine: str | None = None
        self.report: dict | None = None
        self.plan = None  # a stream's ChipPlan and FrameSupply, from stereosim.run_stream
        self.supply = None


class DeadlockError(RunStopped):
    """No FIFO moved and no block was busy for ``watchdog_cycles`` periods of the slowest clock."""


class BudgetExceeded(RunStopped):
    """A clock domain would have run more cycles than the run's budget allows."""


# the full FIFOs a stop's line names (every FIFO's state is on the exception)
STOP_LINE_FIFOS = 6


def time_text(t_fs: int) -> str:
    """An instant as a stop's line gives it: microseconds to the picosecond."""
    return f"{t_fs / 1e9:.6f} us"


def stop_message(head: str, now_fs: int, cycles: dict[str, int], fifos: dict[str, dict],
                 blocks: dict[str, dict], tail: str) -> str:
    """The one-line message of a :class:`RunStopped` (both cycle engines build it here): the
    reason, the instant and the cycles run per domain (``cycles`` in domain order), the FIFOs
    that matter -- the full ones, each of which holds its producer back (``fifos``: name ->
    {"occupancy", "depth"}, in the chip's order; the first :data:`STOP_LINE_FIFOS`) -- the
    blocks waiting on something that is not a FIFO (the DRAM channel, the frame buffers), and
    ``tail``. Every FIFO's and block's state is on the exception, not in the line."""
    full = [f"{name} {st['occupancy']}/{st['depth']}" for name, st in fifos.items()
            if st["occupancy"] >= st["depth"]]
    shown = ", ".join(full[:STOP_LINE_FIFOS])
    if len(full) > STOP_LINE_FIFOS:
        shown += f" and {len(full) - STOP_LINE_FIFOS} more"
    words = [f"full FIFOs: {shown}" if full else "no FIFO is full"]
    words += [f"{name} {st['status']} on {st['waiting_on'][0]}" for name, st in blocks.items()
              if st["waiting_on"] is not None and st["waiting_on"][0] not in fifos]
    cyc = ", ".join(f"{d} {n}" for d, n in cycles.items())
    return f"{head} at {time_text(now_fs)} (cycles run: {cyc}): {'; '.join(words)}; {tail}"


#: How the line of a :class:`BudgetExceeded` begins when no plan says otherwise (a bare
#: kernel run; the chip's runs give :attr:`~sim.cycle.plan.ChipPlan.budget_head`).
BUDGET_HEAD = "cycle budget exceeded"


def budget_message(domain: str, limit: int, remedy: str | None = None) -> str:
    """The tail of a :class:`BudgetExceeded` (both cycle engines). The chip's runs give
    ``remedy`` (:attr:`~sim.cycle.plan.ChipPlan.budget_remedy`); a bare kernel run says
    which argument to change."""
    if remedy is None:
        return (f"{domain} ran its budget of {limit} cycles before the until condition held: "
                "raise budget_cycles or check the until condition")
    return f"{domain} reached {limit} cycles before the run completed: {remedy}"


def activity_counts(busy: int, starved: int, blocked: int, idle: int) -> dict[str, int]:
    """A block's cycles by activity, as every engine reports them (sorted keys)."""
    return {"blocked": int(blocked), "busy": int(busy), "idle": int(idle),
            "starved": int(starved)}


def watchdog_message(quiet_fs: int, p_max_fs: int, remedy: str | None = None) -> str:
    """The tail of the watchdog's :class:`DeadlockError` (shared by both cycle engines). The
    chip's runs give ``remedy`` (:attr:`~sim.cycle.plan.ChipPlan.watchdog_remedy`: which limit
    fired and how to raise it)."""
    if remedy is None:
        remedy = "deepen a FIFO or change what a block waits for"
    return (f"no FIFO moved and no block was busy for {time_text(quiet_fs)} "
            f"({quiet_fs // p_max_fs} periods of the slowest clock): {remedy}")


def count_instants(edges: list[tuple[int, int, int]]) -> int:
    """Number of distinct instants among clock edges: ``edges`` lists per domain
    ``(phase_fs, period_fs, n)`` for its first ``n`` edges ``phase + k * period``, k < n.

    The kernel runs one step per instant, so this is :attr:`Simulator.steps` after every
    domain ran ``n`` cycles. Inclusion-exclusion over the sets of domains whose edges coincide:
    the common instants of a set solve ``t = phase_d (mod period_d)`` for each member (Chinese
    remainder theorem) and lie below every member's last edge.
    """
    edges = [(ph, per, n) for ph, per, n in edges if n > 0]
    total = 0
    for mask in range(1, 1 << len(edges)):
        members = [edges[i] for i in range(len(edges)) if mask >> i & 1]
        r, m = 0, 1  # t = r (mod m)
        feasible = True
        for ph, per, _ in members:
            g = math.gcd(m, per)
            if (ph - r) % g:
                feasible = False
                break
            # r + m * k = ph (mod per)  ->  k = (ph - r) / g * inv(m / g) (mod per / g)
            k = (ph - r) // g * pow(m // g, -1, per // g) % (per // g)
            r, m = r + m * k, m * per // g
            r %= m
        if not feasible:
            continue
        lo = max(ph for ph, _, _ in members)
        hi = min(ph + (n - 1) * per for ph, per, n in members)
        if hi < lo:
            continue
        first = r + -(-(lo - r) // m) * m  # the first solution >= lo
        count = 0 if first > hi else (hi - first) // m + 1
        total += count if len(members) % 2 else -count
    return total


class CameraOverflow(RunStopped):
    """A camera cannot stall: its FIFO was full when a pixel arrived."""


class FrameBufferFull(CameraOverflow):
    """A camera's frame found no free frame buffer (``source.on_overflow = "error"``)."""


def stop_reason(stop: RunStopped, plan: ChipPlan) -> str:
    """What stopped the run, as the report names it: ``max_cycles`` (``sim.max_cycles``, the
    stop the user asked for), ``cycle_budget`` (the automatic budget), ``time_limit`` (either,
    capped to the longest run the engines simulate: :attr:`ChipPlan.budget_reason`),
    ``deadlock`` (the watchdog), ``camera_overflow`` or ``frame_buffer_overflow``."""
    if isinstance(stop, BudgetExceeded):
        return plan.budget_reason
    if isinstance(stop, DeadlockError):
        return "deadlock"
    if isinstance(stop, FrameBufferFull):
        return "frame_buffer_overflow"
    if isinstance(stop, CameraOverflow):
        return "camera_overflow"
    raise TypeError(f"not a stop of the chip: {type(stop).__name__}")


def stop_report(stop: RunStopped, plan: ChipPlan) -> dict:
    """The ``stopped`` section of a stopped run's report: the reason, the message, the instant
    of the last executed step, the cycles each clock domain ran, every FIFO's occupancy (with
    its producer and consumer) and every block's activity in its last cycle with what it waits
    on -- a FIFO, and the block at its other end (who waits on whom), or the DRAM channel or
    the frame buffers. Both engines give the same state, so the same section."""
    fifos = {}
    for f in plan.fifos:
        st = stop.fifos[f.name]
        occ, depth = st["occupancy"], st["depth"]
        state = "full" if occ >= depth else "empty" if occ == 0 else "partly full"
        fifos[f.name] = {"occupancy": occ, "depth": depth, "state": state,
                         "producer": f.producer, "consumer": f.consumer}
    blocks = {}
    for b in plan.blocks:
        st = stop.blocks[b.name]
        entry = {"status": st["status"], "waiting_on": None, "waiting_for": None,
                 "waiting_on_block": None}
        if st["waiting_on"] is not None:
            name, kind = st["waiting_on"]
            entry["waiting_on"] = name
            entry["waiting_for"] = "space" if kind == "full" else "data"
            if name in fifos:
                other = fifos[name]["consumer" if kind == "full" else "producer"]
                entry["waiting_on_block"] = other
        blocks[b.name] = entry
    return {"reason": stop_reason(stop, plan), "message": str(stop),
            "time_fs": int(stop.time_fs), "time_us": stop.time_fs / 1e9,
            "cycles": dict(stop.cycles), "fifos": fifos, "blocks": blocks}


def overflow_message(overflows: list[tuple[str, str, int, int, int]], height: int = 0,
                     frames: int = 1) -> str:
    """The one-line message of a :class:`CameraOverflow`: ``overflows`` lists, in the chip's
    block order, ``(camera, fifo, x, y, cycle)`` for every camera that overflowed in the step,
    y the row over the stream of ``frames`` frames of ``height`` rows (the message names the
    frame of a stream)."""
    def pixel(x, y):
        if frames > 1:
            return f"pixel ({x}, {y % height}) of frame {y // height}"
        return f"pixel ({x}, {y})"

    what = "; ".join(f"camera '{cam}' overflowed FIFO {fifo} at {pixel(x, y)}, cycle {cycle}"
                     for cam, fifo, x, y, cycle in overflows)
    return (f"{what}: the NNA does not keep up with the camera; use a slower camera, more NNA "
            "throughput (clocks.nna_mhz, nna.macs) or a deeper fifo.source_to_nna_depth")


def frame_buffer_message(camera: str, frame: int, busy_frame: int, cycle: int, cfg) -> str:
    """The one-line message of a camera whose frame found no free frame buffer (``on_overflow
    = "error"``): ``busy_frame`` is still being read from the buffer it would take (camera
    frames of the stream; with ``sva.pairs`` > 1, frame f is pair f % pairs's)."""
    source, pairs = cfg.source, cfg.sva.pairs
    pair = f" of pair {frame % pairs} (its frame {frame // pairs})" if pairs > 1 else ""
    return (f"camera '{camera}' found no free frame buffer for frame {frame}{pair}, cycle "
            f"{cycle}: the NNA still reads frame {busy_frame} from the buffer it needs "
            f"({source.frame_buffers} buffer(s){' per pair' if pairs > 1 else ''}); "
            "drop such frames (source.on_overflow=drop_frame), add buffers "
            "(source.frame_buffers) or more NNA throughput (nna.stereo_submodules, clocks.nna_mhz)")


@dataclass
class FrameResult:
    """What a cycle engine returns for one frame or a stream: the (last) frame's output words,
    the cycle report, the kernel statistics, the first frame's row instants
    (:meth:`Chip.row_times`), each frame's first-input and last-output instants
    (:meth:`Chip.frame_times`) and, for a traced run, the trace of the window with the words
    the SVA pushed in it."""

    words: np.ndarray
    report: dict
    stats: dict
    row_times: np.ndarray
    frame_times: np.ndarray | None = None
    trace: TraceLog | None = None
    outputs_in_window: int = 0


def trace_signals(plan: ChipPlan) -> list[Signal]:
    """The signals a trace of ``plan`` records (path, width, clock domain), as both engines
    record them."""
    return [Signal(s.path, s.width, s.domain) for s in plan.signals]


def trace_clocks(plan: ChipPlan) -> list[Clock]:
    """The clocks of a trace of ``plan`` (name, period, first edge at t = 0)."""
    return [Clock(d.name, d.period_fs, 0) for d in plan.domains.values()]
