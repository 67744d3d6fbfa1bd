"""The NNA submodule as a clocked block of the cycle model.

One submodule turns one camera's pixel stream into its descriptor stream. It has two halves that
work in the same cycle:

- **Line buffer** (input): pops at most one pixel per cycle into a buffer of ``rows`` image rows.
  The row being received, y_in, must fit beside the rows still needed: the next output row
  y_out reads input rows y_out - 4 .. y_out + 4 (clamped), so the buffer holds
  y_in - max(0, y_out - 4) + 1 <= rows rows. With rows = 9 a new row waits until the window has
  moved on; with 10 it arrives while the window computes.
- **MAC array** (output): output row y may start once input row min(y + 4, H - 1) is complete
  (the replicate border: row 0 needs rows 0..4; "4" is the window's half height h, 4 for the
  9x9 layer, 1 for the default 11x3 census). Each descriptor occupies the array for
  ``cycles_per_descriptor`` = ceil(K*K*C / macs) cycles (census: 1) and is pushed in its last
  cycle; if ``out`` is full the finished descriptor is held (blocked) and the next one starts
  the cycle after the push. Without stalls the initiation interval is cycles_per_descriptor.

Latency of the first descriptor, with the input arriving one pixel per cycle from cycle a
(first pop) and nothing else stalling: row min(4, H - 1) is complete after its last pixel is
popped in cycle a + min(5, H) * W - 1, the row may start in the next cycle, and the descriptor
is pushed cycles_per_descriptor - 1 cycles later.

Beats: in ``(x, y, pixel)``, out ``(x, y, descriptor, pixel)`` (the pixel rides along for the
SVA's adaptive P2). Data: the descriptors of a row are computed, when its first descriptor is
pushed, from the pixels this line buffer actually received (the functional kernel applied to the
received rows max(0, y-4) .. min(H-1, y+4)), so any mistake in what reached the buffer shows in
the bit-exactness tests.
"""

from __future__ import annotations

import numpy as np

from nna.descriptor import compute_descriptor
from nna.geometry import Tile, check_line_buffer, cycles_per_descriptor, half_window
from sim.config import NnaConfig
from sim.cycle.clock import Block, ClockDomain


class NnaSubmodule(Block):
    """One NNA submodule (see the module docstring for ports, latency and initiation interval).

    With a ``tile`` it serves part of the frame: it receives the tile's input region in raster
    order and emits the tile's output region in raster order; rows and columns below are then
    those of the tile, the image borders (replicate) stay those of the whole frame.
    """

    def __init__(self, name: str, domain: ClockDomain, shape: tuple[int, int], inp, out,
                 cfg: NnaConfig, tile: Tile | None = None):
        super().__init__(name, domain)
        self.image_height, self.image_width = shape
        if tile is None:
            tile = Tile(0, shape[1], 0, shape[0], 0, shape[1], 0, shape[0])
        self.tile = tile
        self.height, self.width = tile.shape  # the output region
        self.in_width = tile.in_x1 - tile.in_x0
        self.in_rows = tile.in_y1 - tile.in_y0
        self.inp, self.out, self.cfg = inp, out, cfg
        self.rows = cfg.line_buffer_rows
        self.half = half_window(cfg)
        check_line_buffer(cfg)
        self.cycles_per_descriptor = cycles_per_descriptor(cfg)
        self.pixels = np.zeros(shape, np.uint8)  # what the line buffer received (image coords)
        self.received = 0  # pixels popped so far (raster order)
        self.emitted = 0  # descriptors pushed so far (raster order)
        self.phase = 0  # MAC cycles spent on the current descriptor
        self._desc_row: np.ndarray | None = None
        self._desc_y = -1
        self._beat_in = None
        self._pushed = False
        self._phase_next = 0

    def _rows_complete(self) -> int:
        return self.received // self.in_width

    def _row_ready(self, y: int) -> bool:
        """Image row y's descriptors may start: input rows up to min(y + h, H - 1) are in."""
        last_in = self.tile.in_y0 + self._rows_complete() - 1
        return last_in >= min(y + self.half, self.image_height - 1)

    def _room_for_input(self) -> bool:
        y_in = self.tile.in_y0 + self.received // self.in_width
        y_out = self.tile.y0 + self.emitted // self.width
        if y_out >= self.tile.y1:
            return True
        return y_in - max(self.tile.in_y0, y_out - self.half) + 1 <= self.rows

    def _descriptors_of_row(self, y: int) -> np.ndarray:
        """Descriptors of image row y over the tile's columns, from the received pixels."""
        if self._desc_y != y:
            t = self.tile
            lo = max(t.in_y0, y - self.half)
            hi = min(t.in_y1, y + self.half + 1)
            window = self.pixels[lo:hi, t.in_x0:t.in_x1]
            row = compute_descriptor(np.ascontiguousarray(window), self.cfg)[y - lo]
            self._desc_row = row[t.x0 - t.in_x0:t.x1 - t.in_x0].copy()
            self._desc_y = y
        return self._desc_row

    def evaluate(self, now_cycle: int) -> None:
        n = self.height * self.width
        n_in = self.in_rows * self.in_width
        moved = False
        # line buffer: one pixel per cycle while there is room
        if self.received < n_in and self.inp.can_pop() and self._room_for_input():
            self._beat_in = self.inp.pop()
            moved = True
        # MAC array
        self._phase_next = self.phase
        self._pushed = False
        mac_wait = None
        if self.emitted < n:
            y, x = divmod(self.emitted, self.width)
            y += self.tile.y0
            if self.phase == 0 and not self._row_ready(y):
                mac_wait = "starved"
            else:
                worked = self.phase < self.cycles_per_descriptor
                if self.phase + 1 >= self.cycles_per_descriptor:
                    if self.out.can_push():
                        desc = self._descriptors_of_row(y)[x]
                        x += self.tile.x0
                        self.out.push((x, y, int(desc), int(self.pixels[y, x])))
                        self._pushed = True
                        self._phase_next = 0
                        moved = True
                    else:
                        self._phase_next = self.cycles_per_descriptor
                        mac_wait = "blocked" if not worked else None
                        moved = moved or worked
                else:
                    self._phase_next = self.phase + 1
                    moved = True
        if moved:
            self.busy()
        elif mac_wait == "blocked":
            self.blocked(self.out)
        elif self.emitted < n or self.received < n_in:
            self.starved(self.inp)
        else:
            self.idle()

    def commit(self) -> None:
        if self._beat_in is not None:
            x, y, value = self._beat_in
            self.pixels[y, x] = value
            self.received += 1
            self._beat_in = None
        if self._pushed:
            self.emitted += 1
            self._pushed = False
        self.phase = self._phase_next

    def work_cycles(self) -> int:
        """MAC-array cycles: cycles_per_descriptor for every descriptor emitted."""
        return self.emitted * self.cycles_per_descriptor

    def signals(self):
        return [("rows_in", 16), ("descriptors_out", 32), ("mac_phase", 16)]

    def signal_values(self):
        return {
            "rows_in": self._rows_complete(),
            "descriptors_out": self.emitted,
            "mac_phase": self.phase,
        }


class Merge(Block):
    """Reassembles a camera's descriptor stream from its submodules' tiles, in raster order.

    Ports: ``inputs`` (one FIFO per tile), ``out``. Each cycle it moves the next descriptor in
    raster order (from the tile that owns it) to ``out``: pop and push in the same cycle, so one
    beat per cycle at most; starved on that tile's FIFO, blocked on ``out``. With row bands it
    drains band after band, so a later band's output waits in its FIFO meanwhile.
    """

    def __init__(self, name: str, domain: ClockDomain, shape: tuple[int, int], inputs, tiles,
                 out):
        super().__init__(name, domain)
        self.height, self.width = shape
        self.inputs, self.tiles, self.out = inputs, tiles, out
        self.moved = 0
        self._pushed = False

    def _owner(self, x: int, y: int) -> int:
        for i, t in enumerate(self.tiles):
            if t.x0 <= x < t.x1 and t.y0 <= y < t.y1:
                return i
        raise AssertionError(f"no tile owns pixel ({x}, {y})")

    def evaluate(self, now_cycle: int) -> None:
        if self.moved >= self.height * self.width:
            self.idle()
            return
        y, x = divmod(self.moved, self.width)
        src = self.inputs[self._owner(x, y)]
        if not src.can_pop():
            self.starved(src)
            return
        if not self.out.can_push():
            self.blocked(self.out)
            return
        self.out.push(src.pop())
        self._pushed = True
        self.busy()

    def commit(self) -> None:
        if self._pushed:
            self.moved += 1
            self._pushed = False

    def work_cycles(self) -> int:
        return self.moved

    def signals(self):
        return [("descriptors_out", 32)]

    def signal_values(self):
        return {"descriptors_out": self.moved}
