"""Frame sources (memory, camera) and the disparity sink of the readable cycle model.

A source pushes :class:`~sim.cycle.readable.beats.PixelBeat`\\ s -- in raster order, frame
after frame; the sink pops :class:`~sim.cycle.readable.beats.WordBeat`\\ s. A source feeds one
FIFO per submodule of its camera: each pixel goes to every FIFO whose submodule's tile takes it
(the tile's input region), to all of them in the same cycle (a joint push that waits until
each has space).

Traced signals (:mod:`sim.cycle.plan`): ``status``, ``sent`` (pixels pushed); the sink's
``status``, ``count`` (words received) and ``valid`` (it popped in its last cycle).

Compiled twins: ``sim/cycle/compiled/source.py`` (the sources, frame buffers, the DRAM
channel's reads) and ``sim/cycle/compiled/sink.py`` (the sink, the write-back).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from stereosim.sim.cycle.fifo.readable import Fifo
from stereosim.sim.cycle.fifo.rule import seen_from
from stereosim.sim.cycle.plan import BlockPlan, ChipPlan, DramPlan
from stereosim.sim.cycle.readable.beats import PixelBeat
from stereosim.sim.cycle.readable.blocks.base import ChipBlock
from stereosim.sim.cycle.rules import (
    burst_last,
    burst_of,
    camera_cycle,
    dram_read_ready_fs,
    dram_slot,
    dram_write_done_fs,
    first_edge_at,
    frame_buffer_admits,
    memory_first_cycle,
)


class _FrameSource(ChipBlock):
    """What both sources share: the frames (``image(f)``: frame f's image), the output FIFOs
    with the tiles of the submodules they feed, the pixel count, the cycle of each frame's
    first pixel."""

    def __init__(self, plan: ChipPlan, entry: BlockPlan, outputs: list[Fifo],
                 image: Callable[[int], np.ndarray]):
        super().__init__(plan, entry, outputs=outputs)
        self.image = image
        self.height, self.width = plan.shape
        self.outs = [(fifo, plan.block(plan.fifo(fifo.name).consumer).tile) for fifo in outputs]
        self.sent = 0
        self.first_cycles = np.full(self.frames, -1, np.int64)  # each frame's first pixel
        self.buffers: FrameBuffers | None = None  # a camera's frame buffers in DRAM
        self.dram: DramChannel | None = None  # the DRAM channel a memory source reads through
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
        beat = PixelBeat(f, x, y, int(self._pixels[y, x]))
        for fifo in targets:
            fifo.push(beat)
        self._pushed = True

    def commit(self) -> None:
        if self._pushed:
            n = self.height * self.width
            if self.sent % n == 0:
                self.first_cycles[self.sent // n] = self._cycle
            self.sent += 1
            fb = self.buffers
            if fb is not None and self.sent % n == 0:
                fb.read_end[self.entry.side].append(self._cycle * self.domain.period_fs)
            if self.dram is not None:
                self.dram.pushed(self.entry.side, self.sent - 1,
                                 self._cycle * self.domain.period_fs)
            self._pushed = False

    def signal_values(self):
        return {"status": self.status_code, "sent": self.sent}


class FrameBuffers:
    """The camera pairs' frame buffers in DRAM, shared by the cameras that write them and the
    two memory sources that read them (the readable kernel's; ``source.frame_buffers`` of the
    plan's configuration, that many per pair; the plan's ``pairs`` pairs sharing the chip frame
    by frame, camera frame f pair f % pairs's; the cameras' raster is ``camera_left``'s).

    The left camera decides at each frame's first pixel, from the committed state, whether
    its pair takes the frame (:func:`~sim.cycle.rules.frame_buffer_admits`: the pair's frame
    taken ``buffers`` before it, the later of the two readers' ends); a frame taken is written
    at the pixel clock, pixel (x, y) readable from the first NNA edge after its camera cycle.
    ``taken[g]``: the camera frame the g-th taken frame of the stream is; ``pair_taken[p]``:
    the stream's indices of pair p's; ``dropped``: the frames skipped; ``read_end[side][g]``:
    the instant a reader finished the g-th."""

    def __init__(self, plan: ChipPlan):
        source, cam = plan.cfg.source, plan.block("camera_left")
        self.count, self.buffers = plan.frames, source.frame_buffers
        self.drop = source.on_overflow == "drop_frame"
        self.line_clocks, self.frame_clocks = cam.line_clocks, cam.frame_clocks
        self.pairs = plan.pairs
        self.camera_period_fs = plan.domains["camera"].period_fs
        self.nna_period_fs = plan.domains["nna"].period_fs
        self.taken: list[int] = []
        self.pair_taken: list[list[int]] = [[] for _ in range(self.pairs)]
        self.dropped: list[int] = []
        self.decided = 0  # camera frames decided
        self.read_end: list[list[int]] = [[], []]

    def busy_until_fs(self, g: int) -> int:
        """When both readers had finished the g-th frame taken (-1: a reader has not)."""
        ends = [r[g] if g < len(r) else None for r in self.read_end]
        return -1 if None in ends else max(ends)

    def camera_cycle(self, f: int, x: int, y: int) -> int:
        """The camera cycle in which pixel (x, y) of camera frame f is written."""
        return camera_cycle(f, x, y, self.line_clocks, self.frame_clocks, self.pairs)

    def readable_cycle(self, f: int, x: int, y: int) -> int:
        """The first NNA cycle that may read pixel (x, y) of camera frame f."""
        return seen_from(self.camera_cycle(f, x, y), self.camera_period_fs,
                         self.nna_period_fs, 1)

    def take(self, f: int) -> None:
        """Camera frame f is the stream's next frame (and its pair's)."""
        self.pair_taken[f % self.pairs].append(len(self.taken))
        self.taken.append(f)

    @property
    def total(self) -> int | None:
        """Frames taken in all, once every camera frame is decided (else None)."""
        return len(self.taken) if self.decided == self.count else None


class DramChannel:
    """The DRAM channel's state in the readable kernel, shared by the two memory sources (their
    reads) and the sink (its write-back): :class:`~sim.cycle.plan.DramPlan`'s slots, each
    client's bursts served in turn by :func:`~sim.cycle.rules.dram_slot`.

    Reads: the stereo pair's burst b (pixels of both views, :func:`~sim.cycle.rules.burst_of`)
    is requested when both sources have sent the last pixel of burst b - prefetch (at 0 for
    the first ``prefetch``) and, reading a camera's ``frame_buffers``, the camera wrote the
    burst's last pixel; it is read in the next pair of read slots, and its pixels may leave
    from the first source edge at or after :func:`~sim.cycle.rules.dram_read_ready_fs`.
    Write-back: burst u of disparity words is requested when the sink took its last word and
    written in the next write slot; word j may be taken once burst ``u(j) - write_buffer``
    has been written (:func:`~sim.cycle.rules.dram_write_done_fs`, the first sink edge at or
    after). ``read_stalls[side]``, ``write_stalls``: the cycles a source or the sink waited.
    The channel is the plan's (``ChipPlan.dram``), the sources' clock the plan's source domain,
    the sink's the SVA's."""

    def __init__(self, plan: ChipPlan, frame_buffers: FrameBuffers | None = None):
        self.dram_plan: DramPlan = plan.dram
        self.n, self.width = plan.shape[0] * plan.shape[1], plan.shape[1]
        self.frame_buffers = frame_buffers
        self.source_period_fs = plan.domains[plan.source_domain].period_fs
        self.sink_period_fs = plan.domains["sva"].period_fs
        self.last_push: list[dict[int, int]] = [{}, {}]  # per side: burst -> its last push (fs)
        self.read_ready: list[int] = []  # per read burst: the first source cycle it is in
        self.read_slot = -1
        self.write_free: list[int] = []  # per write burst: the first sink cycle its slot frees
        self.write_slot = -1
        self.read_stalls = [0, 0]
        self.write_stalls = 0

    def pushed(self, side: int, k: int, t_fs: int) -> None:
        b, last = burst_of(k, self.n, self.dram_plan.read_pixels)
        if k == last:
            self.last_push[side][b] = t_fs

    def read_ready_cycle(self, k: int) -> int | None:
        """The first source cycle pixel k may leave (None: its burst is not requested yet)."""
        d = self.dram_plan
        b, _ = burst_of(k, self.n, d.read_pixels)
        while len(self.read_ready) <= b:
            r = len(self.read_ready)
            request = 0
            fb = self.frame_buffers
            if fb is not None:  # after the camera wrote the burst's last pixel
                g, i = divmod(burst_last(r, self.n, d.read_pixels), self.n)
                if g >= len(fb.taken):
                    return None
                y, x = divmod(i, self.width)
                request = fb.camera_cycle(fb.taken[g], x, y) * fb.camera_period_fs
            if r >= d.prefetch:
                ends = [self.last_push[s].get(r - d.prefetch) for s in (0, 1)]
                if None in ends:
                    return None
                request = max(request, *ends)
                for s in (0, 1):
                    del self.last_push[s][r - d.prefetch]
            self.read_slot = dram_slot(request, self.read_slot, d.slot_fs, d.round_slots,
                                       d.reads.first, 1)
            self.read_ready.append(first_edge_at(
                dram_read_ready_fs(self.read_slot, d.slot_fs, d.latency_fs),
                self.source_period_fs))
        return self.read_ready[b]

    def write_room(self, j: int, now_cycle: int) -> bool:
        """May the sink take word j (over the stream) in ``now_cycle``?"""
        u, _ = burst_of(j, self.n, self.dram_plan.write_words)
        v = u - self.dram_plan.write_buffer
        return v < 0 or self.write_free[v] <= now_cycle

    def took(self, j: int, now_cycle: int) -> None:
        """The sink took word j in ``now_cycle``: a full burst is requested."""
        d = self.dram_plan
        u, last = burst_of(j, self.n, d.write_words)
        if j == last:
            wb = d.write_back
            self.write_slot = dram_slot(now_cycle * self.sink_period_fs, self.write_slot,
                                        d.slot_fs, d.round_slots, wb.first, wb.count)
            assert len(self.write_free) == u
            self.write_free.append(first_edge_at(dram_write_done_fs(self.write_slot, d.slot_fs),
                                                 self.sink_period_fs))

    def stats(self) -> dict:
        """The cycles each client waited on the channel (the cycle report's ``dram``)."""
        return {"read_stall_cycles": list(self.read_stalls),
                "write_stall_cycles": self.write_stalls}


class MemorySource(_FrameSource):
    """Reads the frames from memory in raster order, one pixel (one byte) per beat, the next
    frame's first pixel right after the last one's.

    Ports: ``outputs`` = the source FIFOs (one per submodule of its camera). Bandwidth: a token
    bucket filled at ``bytes_per_s``; pixel k (from 0, over the stream) may leave from cycle
    :func:`~sim.cycle.rules.memory_first_cycle` on, at most one pixel per cycle -- or, through the
    DRAM channel (``dram``), once its burst is in (:class:`DramChannel`). Activity: busy while
    pixels remain (waiting for the token bucket counts as busy: the transfer is under way), starved
    while the frame buffers or the DRAM channel have not delivered the pixel, blocked when a target
    FIFO is full, idle once the last frame has left.
    """

    def __init__(self, plan: ChipPlan, entry: BlockPlan, outputs: list[Fifo], *, image,
                 buffers: FrameBuffers | None = None, dram: DramChannel | None = None):
        super().__init__(plan, entry, outputs, image)
        self.freq_hz = round(self.domain.freq_hz)
        self.buffers = buffers  # a camera's frame buffers it reads (None: frames in memory)
        self.dram = dram  # the DRAM channel it reads through (None: the token bucket)

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
        if self.dram is not None:
            ready = self.dram.read_ready_cycle(self.sent)
            if ready is None or now_cycle < ready:
                self.dram.read_stalls[self.entry.side] += 1
                self.starved("dram")  # its burst is not in the chip yet
                return
        elif now_cycle < memory_first_cycle(self.sent, self.freq_hz, self.entry.bytes_per_s):
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
      the run after the step (:class:`~sim.cycle.contract.CameraOverflow`).
    - Into frame buffers in DRAM (:class:`FrameBuffers`): the left camera decides at each
      frame's first pixel whether the pair takes the frame; a frame that finds no free buffer
      is dropped (``drop_frame``) or stops the run (``fb_overflow``). The memory sources read
      the frames taken. With ``sva.pairs`` = P the block stands for the P pairs' cameras of
      its side, each on its own raster (:func:`~sim.cycle.rules.camera_frame_start`).

    ``sent`` counts the pixels streamed. Activity: busy in the lines of its frames (horizontal
    blanking included), idle in the vertical blanking and after the last frame.
    """

    def __init__(self, plan: ChipPlan, entry: BlockPlan, outputs: list[Fifo], *, image,
                 buffers: FrameBuffers | None = None):
        super().__init__(plan, entry, outputs, image)
        self.buffers = buffers
        # (camera, FIFO, x, row over the stream, cycle) of an overflow
        self.overflow: tuple[str, str, int, int, int] | None = None
        # (camera, frame, the frame still read from its buffer, cycle): no free frame buffer
        self.fb_overflow: tuple[str, int, int, int] | None = None
        self._decision: tuple[str, int] | None = None

    def _decide(self, f: int, now_cycle: int) -> None:
        """Frame f's first pixel: take it if its pair's buffer is free, else drop it or
        stop."""
        fb = self.buffers
        mine = fb.pair_taken[f % fb.pairs]  # the stream's indices of the pair's frames
        g = len(mine)
        held = mine[g - fb.buffers] if g >= fb.buffers else -1  # holds the buffer it needs
        busy = fb.busy_until_fs(held) if held >= 0 else -1
        start = now_cycle * self.domain.period_fs
        if frame_buffer_admits(g, fb.buffers, busy if busy >= 0 else 1 << 62, start):
            self._decision = ("take", f)
        elif fb.drop:
            self._decision = ("drop", f)
        else:
            self.fb_overflow = (self.name, f, fb.taken[held], now_cycle)

    def _evaluate_buffered(self, now_cycle: int) -> None:
        """Into frame buffers: every pair's camera in the lines of a frame now streams (its
        pixel, outside the horizontal blanking) -- one raster per pair, pair p's p/P of a frame
        period late."""
        fb = self.buffers
        step = fb.frame_clocks // fb.pairs
        active = False
        for p in range(fb.pairs):
            fl, c = divmod(now_cycle - p * step, fb.frame_clocks)
            f = fl * fb.pairs + p  # the camera frame of the stream
            line, col = divmod(c, fb.line_clocks)
            if fl < 0 or f >= self.frames or line >= self.height:
                continue
            active = True
            if col < self.width:
                assert fb.camera_cycle(f, col, line) == now_cycle
                if self.entry.side == 0 and line == 0 and col == 0:
                    self._decide(f, now_cycle)
                self._pushed += 1  # streamed (into a buffer, or dropped)
        if active:
            self.busy()
        else:
            self.idle()

    def evaluate(self, now_cycle: int) -> None:
        self._cycle = now_cycle
        self._decision = None
        if self.buffers is not None:
            self._evaluate_buffered(now_cycle)
            return
        f, c = divmod(now_cycle, self.entry.frame_clocks)
        line, col = divmod(c, self.entry.line_clocks)
        if f >= self.frames or line >= self.height:
            self.idle()
            return
        if col < self.width:
            assert camera_cycle(f, col, line, self.entry.line_clocks,
                                self.entry.frame_clocks, 1) == now_cycle
            targets = self._targets(col, line)
            full = next((fifo for fifo in targets if not fifo.can_push()), None)
            if full is not None:
                self.overflow = (self.name, full.name, col, f * self.height + line, now_cycle)
            else:
                self._push_pixel(f, col, line, targets)
        self.busy()

    def commit(self) -> None:
        if self._decision is not None:
            kind, f = self._decision
            fb = self.buffers
            if kind == "take":
                fb.take(f)
            else:
                fb.dropped.append(f)
            fb.decided += 1
            self._decision = None
        if self.buffers is not None:
            self.sent += self._pushed  # pixels streamed by the pairs' cameras
            self._pushed = 0
            return
        super().commit()


class Sink(ChipBlock):
    """Collects the disparity words: pops one beat per cycle whenever one is visible (and,
    writing back through the DRAM channel ``dram``, its write buffer has room: else blocked).
    Port: ``inputs`` = [the SVA's FIFO].

    ``stall`` (optional): a function of the cycle returning True on cycles the sink refuses to
    pop (back-pressure tests; the plan's periodic pattern is one such function). Records the
    cycles of the first and last word, of the last word of every row of the first frame and of
    every frame; ``on_frame(f, words)`` (optional) receives each frame's words as it completes.
    """

    def __init__(self, plan: ChipPlan, entry: BlockPlan, inputs: list[Fifo], *, stall=None,
                 on_frame=None, dram: DramChannel | None = None):
        super().__init__(plan, entry, inputs=inputs)
        (self.inp,) = inputs
        self.dram = dram  # the DRAM channel it writes back through (None: an ideal sink)
        self.shape = shape = plan.shape
        self.words = np.full(shape, -1, np.int32)  # the frame being received (then the last)
        self.n = shape[0] * shape[1]
        self.total = self.frames * self.n
        self.width = shape[1]
        self.received = 0
        self.stall = stall
        self.on_frame = on_frame
        self.first_cycle: int | None = None
        self.last_cycle: int | None = None
        self.row_cycles = np.full(shape[0], -1, np.int64)  # cycle of each row's last pop
        self.frame_cycles = np.full(self.frames, -1, np.int64)  # cycle of each frame's last pop
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
        if self.dram is not None and not self.dram.write_room(self.received, now_cycle):
            self.dram.write_stalls += 1
            self.blocked("dram")  # the write buffer is full
            return
        self._beat = self.inp.pop()
        self._cycle = now_cycle
        self.busy()

    def commit(self) -> None:
        self.popped = self._beat is not None
        beat = self._beat
        if beat is not None:
            if self.received % self.n == 0 and self.received > 0:
                self.words = np.full(self.shape, -1, np.int32)
            self.words[beat.y, beat.x] = beat.word
            if self.dram is not None:
                self.dram.took(self.received, self._cycle)
            self.received += 1
            if self.first_cycle is None:
                self.first_cycle = self._cycle
            self.last_cycle = self._cycle
            if self.received <= self.n and self.received % self.width == 0:
                self.row_cycles[self.received // self.width - 1] = self._cycle
            if self.received % self.n == 0:
                self.frame_cycles[beat.frame] = self._cycle
                if self.on_frame is not None:
                    self.on_frame(beat.frame, self.words)
            self._beat = None

    @property
    def done(self) -> bool:
        return self.received >= self.total

    def signal_values(self):
        return {"status": self.status_code, "count": self.received, "valid": int(self.popped)}
