"""Frame sources (memory, camera) and the disparity sink of the readable cycle model.

Beats are tuples: a source pushes ``(x, y, pixel)`` in raster order; the sink pops
``(x, y, word)``. A source feeds one FIFO per submodule of its camera: each pixel goes to every
FIFO whose tile takes it (the tile's input region), to all of them in the same cycle (a joint
push that waits until each has space).

Traced signals (:mod:`sim.cycle.plan`): ``status``, ``sent`` (pixels pushed); the sink's
``status``, ``count`` (words received) and ``valid`` (it popped in its last cycle).
"""

from __future__ import annotations

import numpy as np

from sim.cycle.clock import Block, ClockDomain
from sim.cycle.plan import STATUS_CODES, BlockPlan
from sim.cycle.rules import camera_cycle, memory_first_cycle


class _FrameSource(Block):
    """What both sources share: the frame, the output FIFOs with their tiles, the pixel
    count."""

    def __init__(self, plan: BlockPlan, domain: ClockDomain, image: np.ndarray, outs):
        super().__init__(plan.name, domain)
        self.plan = plan
        self.image = image
        self.outs = outs  # [(fifo, tile)]
        self.sent = 0
        self._pushed = False

    def _targets(self, x: int, y: int) -> list:
        return [f for f, tile in self.outs if tile.takes_input(x, y)]

    def _push_pixel(self, x: int, y: int, targets) -> None:
        for f in targets:
            f.push((x, y, int(self.image[y, x])))
        self._pushed = True

    def commit(self) -> None:
        if self._pushed:
            self.sent += 1
            self._pushed = False

    def signal_values(self):
        return {"status": STATUS_CODES.get(self.status, 0), "sent": self.sent}


class MemorySource(_FrameSource):
    """Reads one frame from memory in raster order, one pixel (one byte) per beat.

    Port: the source FIFOs. Bandwidth: a token bucket filled at ``bytes_per_s``; pixel k (from
    0) may leave from cycle :func:`~sim.cycle.rules.memory_first_cycle` on, at most one pixel
    per cycle. Activity: busy while pixels remain (waiting for bandwidth counts as busy: the
    transfer is under way), blocked when a target FIFO is full, idle once the frame has left.
    """

    def __init__(self, plan: BlockPlan, domain: ClockDomain, image: np.ndarray, outs):
        super().__init__(plan, domain, image, outs)
        self.freq_hz = round(domain.freq_hz)

    def evaluate(self, now_cycle: int) -> None:
        h, w = self.image.shape
        if self.sent >= h * w:
            self.idle()
            return
        if now_cycle < memory_first_cycle(self.sent, self.freq_hz, self.plan.bytes_per_s):
            self.busy()
            return
        y, x = divmod(self.sent, w)
        targets = self._targets(x, y)
        full = next((f for f in targets if not f.can_push()), None)
        if full is not None:
            self.blocked(full)
            return
        self._push_pixel(x, y, targets)
        self.busy()


class CameraSource(_FrameSource):
    """A camera streaming one frame at its pixel clock, with blanking, from cycle 0.

    Pixel (x, y) arrives in cycle :func:`~sim.cycle.rules.camera_cycle` (lines of W + hblank
    clocks); the vertical blanking after the last line belongs to the next frame. A camera
    cannot wait: a full FIFO when a pixel is due is recorded in ``overflow`` and the chip stops
    the run after the step (:class:`~sim.cycle.stops.CameraOverflow`). Activity: busy from the
    first to the last line's end (horizontal blanking included), idle after.
    """

    def __init__(self, plan: BlockPlan, domain: ClockDomain, image: np.ndarray, outs):
        super().__init__(plan, domain, image, outs)
        self.overflow: tuple[str, str, int, int, int] | None = None

    def evaluate(self, now_cycle: int) -> None:
        h, w = self.image.shape
        line, col = divmod(now_cycle, self.plan.line_clocks)
        if line >= h:
            self.idle()
            return
        if col < w:
            assert camera_cycle(col, line, self.plan.line_clocks) == now_cycle
            targets = self._targets(col, line)
            full = next((f for f in targets if not f.can_push()), None)
            if full is not None:
                self.overflow = (self.name, full.name, col, line, now_cycle)
            else:
                self._push_pixel(col, line, targets)
        self.busy()


class Sink(Block):
    """Collects the disparity words: pops one beat per cycle whenever one is visible.

    ``stall`` (optional): a function of the cycle returning True on cycles the sink refuses to
    pop (back-pressure tests; the plan's periodic pattern is one such function). Records the
    cycles of the first and last word and of the last word of every row.
    """

    def __init__(self, name: str, domain: ClockDomain, inp, shape: tuple[int, int], stall=None):
        super().__init__(name, domain)
        self.inp = inp
        self.words = np.full(shape, -1, np.int32)
        self.total = shape[0] * shape[1]
        self.width = shape[1]
        self.received = 0
        self.stall = stall
        self.first_cycle: int | None = None
        self.last_cycle: int | None = None
        self.row_cycles = np.full(shape[0], -1, np.int64)  # cycle of each row's last pop
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
            x, y, word = self._beat
            self.words[y, x] = word
            self.received += 1
            if self.first_cycle is None:
                self.first_cycle = self._cycle
            self.last_cycle = self._cycle
            if self.received % self.width == 0:
                self.row_cycles[self.received // self.width - 1] = self._cycle
            self._beat = None

    @property
    def done(self) -> bool:
        return self.received >= self.total

    def signal_values(self):
        return {"status": STATUS_CODES.get(self.status, 0), "count": self.received,
                "valid": int(self.popped)}
