"""Frame sources (memory, camera) and the disparity sink of the cycle model.

Beats are tuples: a source pushes ``(x, y, pixel)`` in raster order; the sink pops
``(x, y, word)``. A source feeds one FIFO, or several when a camera's frame is split over
several NNA submodules: then each pixel goes to every FIFO whose region (``Tile`` input range)
holds it, to all of them in the same cycle (a joint push that waits until each has space).
"""

from __future__ import annotations

import numpy as np

from sim.cycle.clock import Block, ClockDomain
from sim.errors import UserError


class CameraOverflow(UserError):
    """A camera cannot stall: its FIFO was full when a pixel arrived."""


def _as_outputs(out) -> list:
    """``out``: one FIFO, or a list of (FIFO, tile) pairs (tile: the region it takes)."""
    if isinstance(out, list):
        return out
    return [(out, None)]


def _targets(outs, x: int, y: int) -> list:
    return [f for f, tile in outs if tile is None or tile.takes_input(x, y)]


class _FrameSource(Block):
    """What both sources share: the frame, the output FIFO(s), the pixel count."""

    def __init__(self, name: str, domain: ClockDomain, image: np.ndarray, out):
        super().__init__(name, domain)
        self.image = image
        self.outs = _as_outputs(out)
        self.sent = 0
        self._pushed = False

    def _push_pixel(self, x: int, y: int, targets) -> None:
        for f in targets:
            f.push((x, y, int(self.image[y, x])))
        self._pushed = True

    def commit(self) -> None:
        if self._pushed:
            self.sent += 1
            self._pushed = False

    def work_cycles(self) -> int:
        """Cycles the port was transferring (pushing, or waiting for bandwidth/the raster)."""
        return self.activity["busy"]

    def signals(self):
        return [("pixels_sent", 32)]

    def signal_values(self):
        return {"pixels_sent": self.sent}


class MemorySource(_FrameSource):
    """Reads one frame from memory in raster order, one pixel (one byte) per beat.

    Port: ``out`` (pixels). Bandwidth: a token bucket filled at ``bytes_per_s``; pixel k (from 0)
    may leave in cycle c only if ``(k + 1) * freq_hz <= (c + 1) * bytes_per_s``, and at most one
    pixel leaves per cycle. With ``bytes_per_s >= freq_hz`` pixel k leaves in cycle k unless the
    FIFO is full. Activity: busy while pixels remain (waiting for bandwidth counts as busy: the
    transfer is under way), blocked when ``out`` is full, idle once the frame has left.
    """

    def __init__(self, name: str, domain: ClockDomain, image: np.ndarray, out, bytes_per_s: int):
        super().__init__(name, domain, image, out)
        self.freq_hz = round(domain.freq_hz)
        self.bytes_per_s = int(bytes_per_s)

    def evaluate(self, now_cycle: int) -> None:
        h, w = self.image.shape
        if self.sent >= h * w:
            self.idle()
            return
        if (self.sent + 1) * self.freq_hz > (now_cycle + 1) * self.bytes_per_s:
            self.busy()
            return
        y, x = divmod(self.sent, w)
        targets = _targets(self.outs, x, y)
        full = next((f for f in targets if not f.can_push()), None)
        if full is not None:
            self.blocked(full)
            return
        self._push_pixel(x, y, targets)
        self.busy()


class CameraSource(_FrameSource):
    """A camera streaming one frame at its pixel clock, with blanking, from cycle 0.

    Cycle c is line ``c // (W + hblank)``, column ``c % (W + hblank)``; columns < W of lines < H
    are active and push pixel (column, line). The frame lasts until the last active pixel; the
    vertical blanking that follows belongs to the next frame. A camera cannot wait: a full FIFO
    when a pixel is due raises :class:`CameraOverflow` naming the rates. Activity: busy from the
    first to the last line's end (horizontal blanking included), idle after. Its work per frame
    is its whole raster, ``(H + vblank) (W + hblank)`` pixel clocks: a camera delivers frames no
    faster than that, whatever the chip does.
    """

    def __init__(self, name: str, domain: ClockDomain, image: np.ndarray, out, hblank: int,
                 vblank: int = 0):
        super().__init__(name, domain, image, out)
        self.line_clocks = image.shape[1] + hblank
        self.frame_clocks = (image.shape[0] + vblank) * self.line_clocks

    def work_cycles(self) -> int:
        """The camera's frame period in pixel clocks, vertical blanking included."""
        return self.frame_clocks

    def evaluate(self, now_cycle: int) -> None:
        h, w = self.image.shape
        line, col = divmod(now_cycle, self.line_clocks)
        if line >= h:
            self.idle()
            return
        if col < w:
            targets = _targets(self.outs, col, line)
            full = next((f for f in targets if not f.can_push()), None)
            if full is not None:
                raise CameraOverflow(
                    f"camera '{self.name}' overflowed FIFO {full.name} at pixel ({col}, "
                    f"{line}), cycle {now_cycle}: the NNA does not keep up with the camera; use a "
                    "slower camera, more NNA throughput (clocks.nna_mhz, nna.macs) or a deeper "
                    "fifo.source_to_nna_depth"
                )
            self._push_pixel(col, line, targets)
        self.busy()


class Sink(Block):
    """Collects the disparity words: pops one beat per cycle whenever one is visible.

    ``stall`` (optional): a function of the cycle returning True on cycles the sink refuses to
    pop (back-pressure tests). Records the femtosecond times of the first and last word.
    """

    def __init__(self, name: str, domain: ClockDomain, inp, shape: tuple[int, int], stall=None):
        super().__init__(name, domain)
        self.inp = inp
        self.words = np.full(shape, -1, np.int32)
        self.total = shape[0] * shape[1]
        self.received = 0
        self.stall = stall
        self.first_cycle: int | None = None
        self.last_cycle: int | None = None
        self._beat = None
        self._cycle = 0

    def evaluate(self, now_cycle: int) -> None:
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
        if self._beat is not None:
            x, y, word = self._beat
            self.words[y, x] = word
            self.received += 1
            if self.first_cycle is None:
                self.first_cycle = self._cycle
            self.last_cycle = self._cycle
            self._beat = None

    def work_cycles(self) -> int:
        return self.received

    @property
    def done(self) -> bool:
        return self.received >= self.total
