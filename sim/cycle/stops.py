"""How a run of the chip can stop early, as both cycle engines report it.

A deadlock (:class:`~sim.cycle.clock.DeadlockError`) and an exhausted cycle budget
(:class:`~sim.cycle.clock.BudgetExceeded`) are the kernel's; a camera overflow is the chip's: a
camera cannot wait, so a full FIFO when a pixel is due stops the run. Every camera that
overflows in the same step is named (the step completes first, so the order in which the
blocks evaluate cannot change the message).
"""

from __future__ import annotations

from stereosim.sim.errors import UserError


class CameraOverflow(UserError):
    """A camera cannot stall: its FIFO was full when a pixel arrived."""


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
