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
from sim.cycle.rules import camera_cycle, frame_buffer_admits, memory_first_cycle, seen_from


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
        self.buffers: FrameBuffers | None = None  # a camera's frame buffers in DRAM
        self._pushed = False
        self._cycle = 0
        self._frame = -1
        self._pixels = None

    def _targets(self, x: int, y: int) -> list:
        return [f for f, tile in self.outs if tile.takes_input(x, y)]

    def _push_pixel(self, f: int, x: int, y: int, targets) -> None:
        if f != self._frame:  # (f: the frame of the stream; its camera frame if buffered)
            source = f if self.buffers is None else self.buffers.taken[f]
            self._pixels, self._frame = self.image(source), f
        for fifo in targets:
            fifo.push((f, x, y, int(self._pixels[y, x])))
        self._pushed = True

    def commit(self) -> None:
        if self._pushed:
            n = self.height * self.width
            if self.sent % n == 0:
                self.first_cycles[self.sent // n] = self._cycle
            self.sent += 1
            fb = self.buffers
            if fb is not None and self.sent % n == 0:
                fb.read_end[self.plan.side].append(self._cycle * self.domain.period_fs)
            self._pushed = False

    def signal_values(self):
        return {"status": STATUS_CODES.get(self.status, 0), "sent": self.sent}


class FrameBuffers:
    """A camera pair's frame buffers in DRAM, shared by the two cameras that write them and the
    two memory sources that read them (the readable kernel's; the plan's ``frame_buffers``).

    The left camera decides at each frame's first pixel, from the committed state, whether the
    pair takes the frame (:func:`~sim.cycle.rules.frame_buffer_admits`, the later of the two
    readers' ends); a frame taken is written at the pixel clock, pixel (x, y) readable from the
    first NNA edge after its camera cycle. ``taken[g]``: the camera frame the g-th taken frame
    is; ``dropped``: the frames skipped; ``read_end[side][g]``: the instant a reader finished
    the g-th."""

    def __init__(self, count: int, buffers: int, drop: bool, line_clocks: int,
                 frame_clocks: int, camera_period_fs: int, nna_period_fs: int):
        self.count, self.buffers, self.drop = count, buffers, drop
        self.line_clocks, self.frame_clocks = line_clocks, frame_clocks
        self.camera_period_fs, self.nna_period_fs = camera_period_fs, nna_period_fs
        self.taken: list[int] = []
        self.dropped: list[int] = []
        self.decided = 0  # camera frames decided
        self.read_end: list[list[int]] = [[], []]

    def busy_until_fs(self, g: int) -> int:
        """When both readers had finished the g-th frame taken (-1: a reader has not)."""
        ends = [r[g] if g < len(r) else None for r in self.read_end]
        return -1 if None in ends else max(ends)

    def readable_cycle(self, f: int, x: int, y: int) -> int:
        """The first NNA cycle that may read pixel (x, y) of camera frame f."""
        c = camera_cycle(f, x, y, self.line_clocks, self.frame_clocks)
        return seen_from(c, self.camera_period_fs, self.nna_period_fs, 1)

    @property
    def total(self) -> int | None:
        """Frames taken in all, once every camera frame is decided (else None)."""
        return len(self.taken) if self.decided == self.count else None


class MemorySource(_FrameSource):
    """Reads the frames from memory in raster order, one pixel (one byte) per beat, the next
    frame's first pixel right after the last one's.

    Port: the source FIFOs. Bandwidth: a token bucket filled at ``bytes_per_s``; pixel k (from
    0, over the stream) may leave from cycle :func:`~sim.cycle.rules.memory_first_cycle` on, at
    most one pixel per cycle. Activity: busy while pixels remain (waiting for bandwidth counts
    as busy: the transfer is under way), blocked when a target FIFO is full, idle once the last
    frame has left.
    """

    def __init__(self, plan: BlockPlan, domain: ClockDomain, image, shape, frames, outs,
                 buffers: FrameBuffers | None = None):
        super().__init__(plan, domain, image, shape, frames, outs)
        self.freq_hz = round(domain.freq_hz)
        self.buffers = buffers  # a camera's frame buffers it reads (None: frames in memory)

    def evaluate(self, now_cycle: int) -> None:
        n = self.height * self.width
        self._cycle = now_cycle
        fb = self.buffers
        total = self.frames if fb is None or fb.total is None else fb.total
        if self.sent >= total * n:
            self.idle()
            return
        f, k = divmod(self.sent, n)
        y, x = divmod(k, self.width)
        if fb is not None and (f >= len(fb.taken)
                               or now_cycle < fb.readable_cycle(fb.taken[f], x, y)):
            self.starved("frame buffers")  # the camera has not written the pixel yet
            return
        if now_cycle < memory_first_cycle(self.sent, self.freq_hz, self.plan.bytes_per_s):
            self.busy()
            return
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
    W + hblank clocks, frames of (H + vblank) lines, back to back). A camera cannot wait.

    - Straight into the NNA (no ``buffers``): each pixel is pushed into the source FIFOs as it
      arrives; a full FIFO when a pixel is due is recorded in ``overflow`` and the chip stops
      the run after the step (:class:`~sim.cycle.stops.CameraOverflow`).
    - Into frame buffers in DRAM (:class:`FrameBuffers`): the left camera decides at each
      frame's first pixel whether the pair takes the frame; a frame that finds no free buffer
      is dropped (``drop_frame``) or stops the run (``fb_overflow``). The memory sources read
      the frames taken.

    ``sent`` counts the pixels streamed. Activity: busy in the lines of its frames (horizontal
    blanking included), idle in the vertical blanking and after the last frame.
    """

    def __init__(self, plan: BlockPlan, domain: ClockDomain, image, shape, frames, outs,
                 buffers: FrameBuffers | None = None):
        super().__init__(plan, domain, image, shape, frames, outs)
        self.buffers = buffers
        # (camera, FIFO, x, row over the stream, cycle) of an overflow
        self.overflow: tuple[str, str, int, int, int] | None = None
        # (camera, frame, the frame still read from its buffer, cycle): no free frame buffer
        self.fb_overflow: tuple[str, int, int, int] | None = None
        self._decision: tuple[str, int] | None = None

    def _decide(self, f: int, now_cycle: int) -> None:
        """Frame f's first pixel: take it if a buffer is free, else drop it or stop."""
        fb = self.buffers
        g = len(fb.taken)
        busy = fb.busy_until_fs(g - fb.buffers) if g >= fb.buffers else -1
        start = now_cycle * self.domain.period_fs
        if frame_buffer_admits(g, fb.buffers, busy if busy >= 0 else 1 << 62, start):
            self._decision = ("take", f)
        elif fb.drop:
            self._decision = ("drop", f)
        else:
            self.fb_overflow = (self.name, f, fb.taken[g - fb.buffers], now_cycle)

    def evaluate(self, now_cycle: int) -> None:
        self._cycle = now_cycle
        self._decision = None
        f, c = divmod(now_cycle, self.plan.frame_clocks)
        line, col = divmod(c, self.plan.line_clocks)
        if f >= self.frames or line >= self.height:
            self.idle()
            return
        if col < self.width:
            assert camera_cycle(f, col, line, self.plan.line_clocks,
                                self.plan.frame_clocks) == now_cycle
            if self.buffers is not None:
                if self.plan.side == 0 and line == 0 and col == 0:
                    self._decide(f, now_cycle)
                self._pushed = True  # streamed (into a buffer, or dropped)
            else:
                targets = self._targets(col, line)
                full = next((fifo for fifo in targets if not fifo.can_push()), None)
                if full is not None:
                    self.overflow = (self.name, full.name, col, f * self.height + line,
                                     now_cycle)
                else:
                    self._push_pixel(f, col, line, targets)
        self.busy()

    def commit(self) -> None:
        if self._decision is not None:
            kind, f = self._decision
            fb = self.buffers
            (fb.taken if kind == "take" else fb.dropped).append(f)
            fb.decided += 1
            self._decision = None
        if self.buffers is not None:
            if self._pushed:
                self.sent += 1
                self._pushed = False
            return
        super().commit()


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
