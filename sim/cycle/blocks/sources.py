"""Frame sources (memory, camera) and the disparity sink of the readable cycle model.

Beats are tuples: a source pushes ``(f, x, y, pixel)`` -- frame f of the stream, in raster
order, frame after frame; the sink pops ``(f, x, y, word)``. A source feeds one FIFO per
submodule of its camera: each pixel goes to every FIFO whose tile takes it (the tile's input
region), to all of them in the same cycle (a joint push that waits until each has space).

Traced signals (:mod:`sim.cycle.plan`): ``status``, ``sent`` (pixels pushed); the sink's
``status``, ``count`` (words received) and ``valid`` (it popped in its last cycle).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from sim.cycle.clock import Block, ClockDomain
from sim.cycle.plan import STATUS_CODES, BlockPlan
from sim.cycle.rules import camera_cycle, memory_first_cycle


class _FrameSource(Block):
    """What both sources share: the frames (``image(f)``: frame f's image), the output FIFOs
    with their tiles, the pixel count, the cycle of each frame's first pixel."""

    def __init__(self, plan: BlockPlan, domain: ClockDomain, image: Callable[[int], np.ndarray],
                 shape: tuple[int, int], frames: int, outs):
        super().__init__(plan.name, domain)
        self.plan = plan
        self.image = image
        self.height, self.width = shape
        self.frames = frames
        self.outs = outs  # [(fifo, tile)]
        self.sent = 0
        self.first_cycles = np.full(frames, -1, np.int64)  # each frame's first pixel
        self._pushed = False
        self._cycle = 0
        self._frame = -1
        self._pixels = None

    def _targets(self, x: int, y: int) -> list:
        return [f for f, tile in self.outs if tile.takes_input(x, y)]

    def _push_pixel(self, f: int, x: int, y: int, targets) -> None:
        if f != self._frame:
            self._pixels, self._frame = self.image(f), f
        for fifo in targets:
            fifo.push((f, x, y, int(self._pixels[y, x])))
        self._pushed = True

    def commit(self) -> None:
        if self._pushed:
            if self.sent % (self.height * self.width) == 0:
                self.first_cycles[self.sent // (self.height * self.width)] = self._cycle
            self.sent += 1
            self._pushed = False

    def signal_values(self):
        return {"status": STATUS_CODES.get(self.status, 0), "sent": self.sent}


class MemorySource(_FrameSource):
    """Reads the frames from memory in raster order, one pixel (one byte) per beat, the next
    frame's first pixel right after the last one's.

    Port: the source FIFOs. Bandwidth: a token bucket filled at ``bytes_per_s``; pixel k (from
    0, over the stream) may leave from cycle :func:`~sim.cycle.rules.memory_first_cycle` on, at
    most one pixel per cycle. Activity: busy while pixels remain (waiting for bandwidth counts
    as busy: the transfer is under way), blocked when a target FIFO is full, idle once the last
    frame has left.
    """

    def __init__(self, plan: BlockPlan, domain: ClockDomain, image, shape, frames, outs):
        super().__init__(plan, domain, image, shape, frames, outs)
        self.freq_hz = round(domain.freq_hz)

    def evaluate(self, now_cycle: int) -> None:
        n = self.height * self.width
        self._cycle = now_cycle
        if self.sent >= self.frames * n:
            self.idle()
            return
        if now_cycle < memory_first_cycle(self.sent, self.freq_hz, self.plan.bytes_per_s):
            self.busy()
            return
        f, k = divmod(self.sent, n)
        y, x = divmod(k, self.width)
        targets = self._targets(x, y)
        full = next((fifo for fifo in targets if not fifo.can_push()), None)
        if full is not None:
            self.blocked(full)
            return
        self._push_pixel(f, x, y, targets)
        self.busy()


class CameraSource(_FrameSource):
    """A camera streaming its frames at its pixel clock, with blanking, from cycle 0.

    Pixel (x, y) of frame f arrives in cycle :func:`~sim.cycle.rules.camera_cycle` (lines of
    W + hblank clocks, frames of (H + vblank) lines, back to back). A camera cannot wait: a full
    FIFO when a pixel is due is recorded in ``overflow`` and the chip stops the run after the
    step (:class:`~sim.cycle.stops.CameraOverflow`). Activity: busy in the lines of its frames
    (horizontal blanking included), idle in the vertical blanking and after the last frame.
    """

    def __init__(self, plan: BlockPlan, domain: ClockDomain, image, shape, frames, outs):
        super().__init__(plan, domain, image, shape, frames, outs)
        # (camera, FIFO, x, row over the stream, cycle) of an overflow
        self.overflow: tuple[str, str, int, int, int] | None = None

    def evaluate(self, now_cycle: int) -> None:
        self._cycle = now_cycle
        f, c = divmod(now_cycle, self.plan.frame_clocks)
        line, col = divmod(c, self.plan.line_clocks)
        if f >= self.frames or line >= self.height:
            self.idle()
            return
        if col < self.width:
            assert camera_cycle(f, col, line, self.plan.line_clocks,
                                self.plan.frame_clocks) == now_cycle
            targets = self._targets(col, line)
            full = next((fifo for fifo in targets if not fifo.can_push()), None)
            if full is not None:
                self.overflow = (self.name, full.name, col, f * self.height + line, now_cycle)
            else:
                self._push_pixel(f, col, line, targets)
        self.busy()


class Sink(Block):
    """Collects the disparity words: pops one beat per cycle whenever one is visible.

    ``stall`` (optional): a function of the cycle returning True on cycles the sink refuses to
    pop (back-pressure tests; the plan's periodic pattern is one such function). Records the
    cycles of the first and last word, of the last word of every row of the first frame and of
    every frame; ``on_frame(f, words)`` (optional) receives each frame's words as it completes.
    """

    def __init__(self, name: str, domain: ClockDomain, inp, shape: tuple[int, int],
                 frames: int = 1, stall=None, on_frame=None):
        super().__init__(name, domain)
        self.inp = inp
        self.shape = shape
        self.words = np.full(shape, -1, np.int32)  # the frame being received (then the last)
        self.n = shape[0] * shape[1]
        self.total = frames * self.n
        self.width = shape[1]
        self.received = 0
        self.stall = stall
        self.on_frame = on_frame
        self.first_cycle: int | None = None
        self.last_cycle: int | None = None
        self.row_cycles = np.full(shape[0], -1, np.int64)  # cycle of each row's last pop
        self.frame_cycles = np.full(frames, -1, np.int64)  # cycle of each frame's last pop
        self.popped = False
        self._beat = None
        self._cycle = 0

    def evaluate(self, now_cycle: int) -> None:
        self._beat = None
        if self.received >= self.total:
            self.idle()
            return
        if self.stall is not None and self.stall(now_cycle):
            self.idle()
            return
        if not self.inp.can_pop():
            self.starved(self.inp)
            return
        self._beat = self.inp.pop()
        self._cycle = now_cycle
        self.busy()

    def commit(self) -> None:
        self.popped = self._beat is not None
        if self._beat is not None:
            f, x, y, word = self._beat
            if self.received % self.n == 0 and self.received > 0:
                self.words = np.full(self.shape, -1, np.int32)
            self.words[y, x] = word
            self.received += 1
            if self.first_cycle is None:
                self.first_cycle = self._cycle
            self.last_cycle = self._cycle
            if self.received <= self.n and self.received % self.width == 0:
                self.row_cycles[self.received // self.width - 1] = self._cycle
            if self.received % self.n == 0:
                self.frame_cycles[f] = self._cycle
                if self.on_frame is not None:
                    self.on_frame(f, self.words)
            self._beat = None

    @property
    def done(self) -> bool:
        return self.received >= self.total

    def signal_values(self):
        return {"status": STATUS_CODES.get(self.status, 0), "count": self.received,
                "valid": int(self.popped)}
