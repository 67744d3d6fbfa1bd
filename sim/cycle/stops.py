"""How a run of the chip can stop early, as both cycle engines report it.

A deadlock (:class:`~sim.cycle.clock.DeadlockError`) and an exhausted cycle budget
(:class:`~sim.cycle.clock.BudgetExceeded`) are the kernel's; a camera overflow is the chip's: a
camera cannot wait, so a full FIFO when a pixel is due stops the run (:class:`CameraOverflow`),
and so does a frame that finds no free frame buffer (:class:`FrameBufferFull`). Every camera
that overflows in the same step is named (the step completes first, so the order in which the
blocks evaluate cannot change the message). Each of them is a
:class:`~sim.cycle.clock.RunStopped` carrying the state of every FIFO and block after the last
step the run executed, and :func:`stop_report` makes that state the ``stopped`` section of the
report a stopped run publishes (docs/reliability.md).
"""

from __future__ import annotations

from stereosim.sim.cycle.clock import BudgetExceeded, DeadlockError, RunStopped
from stereosim.sim.cycle.plan import ChipPlan


class CameraOverflow(RunStopped):
    """A camera cannot stall: its FIFO was full when a pixel arrived."""


class FrameBufferFull(CameraOverflow):
    """A camera's frame found no free frame buffer (``source.on_overflow = "error"``)."""


def stop_reason(stop: RunStopped, plan: ChipPlan) -> str:
    """What stopped the run, as the report names it: ``max_cycles`` (``sim.max_cycles``),
    ``cycle_budget`` (the automatic budget), ``deadlock`` (the watchdog), ``camera_overflow``
    or ``frame_buffer_overflow``."""
    if isinstance(stop, BudgetExceeded):
        return "max_cycles" if plan.cfg.sim.max_cycles else "cycle_budget"
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
            f"({source.frame_buffers} buffer(s){' per pair' if pairs > 1 else ''}); drop such frames "
            "(source.on_overflow=drop_frame), add buffers (source.frame_buffers) or more NNA "
            "throughput (nna.stereo_submodules, clocks.nna_mhz)")
