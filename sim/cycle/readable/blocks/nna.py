"""The NNA submodule and the merge of split frames as clocked blocks of the readable kernel.

One submodule turns one camera's pixel stream (of its tile) into its descriptor stream. It has
two halves that work in the same cycle:

- **Line buffer** (input): pops at most one pixel per cycle into a buffer of ``rows`` image
  rows, while the row arriving fits beside the rows the next output row still reads
  (:func:`~sim.cycle.rules.nna_rows_started_before_input`). With rows = 9 (the 9x9 window) a new
  row waits until the window has moved on; with 10 it arrives while the window computes.
- **MAC array** (output): output row y may start once input row
  :func:`~sim.cycle.rules.nna_last_input_row` (min(y + h, H - 1), the replicate border) is
  complete. Each descriptor occupies the array for ``cycles`` = ceil(K*K*C / macs) cycles
  (census: 1) and is pushed in its last cycle; if ``out`` is full the finished descriptor is
  held (blocked) and the next one starts the cycle after the push. Without stalls the
  initiation interval is ``cycles``.

Latency of the first descriptor, with the input arriving one pixel per cycle from cycle a (first
pop) and nothing else stalling: row min(h, H - 1) is complete after its last pixel is popped in
cycle a + min(h + 1, H) W - 1, the row may start in the next cycle, and the descriptor is pushed
``cycles - 1`` cycles later.

Beats: in ``(f, x, y, pixel)``, out ``(f, x, y, descriptor, pixel)`` -- f the frame of the
stream (the pixel rides along for the SVA's adaptive P2). Data: the descriptors of a row are computed, when its first descriptor is
pushed, from the pixels this line buffer actually received (the functional kernel applied to
the received rows max(0, y - h) .. min(H - 1, y + h)), so any mistake in what reached the buffer
shows in the bit-exactness tests.

Traced signals (:mod:`sim.cycle.plan`): ``status``; ``line_buffer.row_in`` (the image row being
received), ``line_buffer.fill`` (rows held for the next output row), ``mac.phase`` (MAC cycles
spent on the current descriptor; ``cycles`` while a finished one waits), ``mac.row`` /
``mac.col`` (the next descriptor), ``out.valid`` (pushed in its last cycle) and
``out.descriptor`` (the last pushed).
"""

from __future__ import annotations

import numpy as np

from stereosim.nna.descriptor import compute_descriptor
from stereosim.sim.config import NnaConfig
from stereosim.sim.cycle.readable.clock import Block
from stereosim.sim.cycle.rules import ClockDomain
from stereosim.sim.cycle.plan import STATUS_CODES, BlockPlan
from stereosim.sim.cycle.rules import frame_row, nna_last_input_row, nna_rows_started_before_input


class NnaSubmodule(Block):
    """One NNA submodule serving the tile of its plan (the whole frame, or a column tile / row
    band of it) over a stream of ``frames`` frames: it receives the tile's input region of
    each frame in raster order, frame after frame, and emits the tile's output region in raster
    order; rows and columns below are those of the tile, the image borders (replicate) stay
    those of each frame. Counters run over the stream: input row r of the tile is row
    r % in_rows of frame r // in_rows."""

    def __init__(self, plan: BlockPlan, domain: ClockDomain, shape: tuple[int, int], inp, out,
                 cfg: NnaConfig, frames: int = 1):
        super().__init__(plan.name, domain)
        self.image_height, self.image_width = shape
        self.tile = tile = plan.tile
        self.height, self.width = tile.shape  # the output region
        self.in_rows, self.in_width = tile.in_shape
        self.frames = frames
        self.inp, self.out, self.cfg = inp, out, cfg
        self.rows = plan.rows
        self.half = plan.half
        self.cycles_per_descriptor = plan.cycles
        self.pixels: dict[int, np.ndarray] = {}  # per frame in flight: what the buffer received
        self.received = 0  # pixels popped so far (raster order of the input regions)
        self.emitted = 0  # descriptors pushed so far (raster order of the output regions)
        self.phase = 0  # MAC cycles spent on the current descriptor
        self.row_cycles = np.full(self.in_rows, -1, np.int64)  # frame 0: each input row done
        # the line buffer's window (sim.cycle.buffers): the cycle each input row started to
        # enter, the cycle each output row's last descriptor was pushed (rows over the stream)
        self.rows_entered = np.full(frames * self.in_rows + 1, -1, np.int64)
        self.rows_done = np.full(frames * self.height + 1, -1, np.int64)
        self.pushed = False
        self.last_descriptor = 0
        self._desc_row: np.ndarray | None = None
        self._desc_key = (-1, -1)
        self._beat_in = None
        self._push = None
        self._phase_next = 0
        self._cycle = 0

    def _rows_complete(self, f: int) -> int:
        """Input rows of frame f the line buffer has received whole."""
        n_in = self.in_rows * self.in_width
        return min(self.in_rows, max(0, self.received - f * n_in) // self.in_width)

    def _row_ready(self, f: int, y: int) -> bool:
        """Image row y of frame f may start: its last input row is in."""
        last_in = self.tile.in_y0 + self._rows_complete(f) - 1
        return last_in >= nna_last_input_row(y, self.half, self.image_height)

    def _room_for_input(self) -> bool:
        r = self.received // self.in_width
        need = nna_rows_started_before_input(r, self.rows, self.half, self.tile.top_halo,
                                             self.height, self.in_rows)
        return self.emitted // self.width >= need

    def _descriptors_of_row(self, f: int, y: int) -> np.ndarray:
        """Descriptors of image row y of frame f over the tile's columns, from the received
        pixels."""
        if self._desc_key != (f, y):
            t = self.tile
            lo = max(t.in_y0, y - self.half)
            hi = min(t.in_y1, y + self.half + 1)
            window = self.pixels[f][lo:hi, t.in_x0:t.in_x1]
            row = compute_descriptor(np.ascontiguousarray(window), self.cfg)[y - lo]
            self._desc_row = row[t.x0 - t.in_x0:t.x1 - t.in_x0].copy()
            self._desc_key = (f, y)
        return self._desc_row

    def evaluate(self, now_cycle: int) -> None:
        n = self.height * self.width
        n_in = self.in_rows * self.in_width
        self._cycle = now_cycle
        moved = False
        # line buffer: one pixel per cycle while there is room
        if self.received < self.frames * n_in and self.inp.can_pop() and self._room_for_input():
            self._beat_in = self.inp.pop()
            if self.received % self.in_width == 0:
                self.rows_entered[self.received // self.in_width] = now_cycle
            moved = True
        # MAC array
        self._phase_next = self.phase
        self._push = None
        mac_wait = None
        cpd = self.cycles_per_descriptor
        if self.emitted < self.frames * n:
            f, j = divmod(self.emitted, n)
            y, x = divmod(j, self.width)
            y += self.tile.y0
            if self.phase == 0 and not self._row_ready(f, y):
                mac_wait = "starved"
            else:
                worked = self.phase < cpd
                if self.phase + 1 >= cpd:
                    if self.out.can_push():
                        desc = int(self._descriptors_of_row(f, y)[x])
                        x += self.tile.x0
                        self.out.push((f, x, y, desc, int(self.pixels[f][y, x])))
                        self._push = desc
                        self._phase_next = 0
                        moved = True
                    else:
                        self._phase_next = cpd
                        mac_wait = "blocked" if not worked else None
                        moved = moved or worked
                else:
                    self._phase_next = self.phase + 1
                    moved = True
        if moved:
            self.busy()
        elif mac_wait == "blocked":
            self.blocked(self.out)
        elif self.emitted < self.frames * n or self.received < self.frames * n_in:
            self.starved(self.inp)
        else:
            self.idle()

    def commit(self) -> None:
        if self._beat_in is not None:
            f, x, y, value = self._beat_in
            if f not in self.pixels:
                self.pixels[f] = np.zeros((self.image_height, self.image_width), np.uint8)
            self.pixels[f][y, x] = value
            self.received += 1
            if self.received <= self.in_rows * self.in_width and (
                    self.received % self.in_width == 0):
                self.row_cycles[self.received // self.in_width - 1] = self._cycle
            self._beat_in = None
        self.pushed = self._push is not None
        if self._push is not None:
            self.emitted += 1
            if self.emitted % self.width == 0:
                self.rows_done[self.emitted // self.width - 1] = self._cycle
            n = self.height * self.width
            if self.emitted % n == 0:
                self.pixels.pop(self.emitted // n - 1, None)  # the frame has left
            self.last_descriptor = self._push
            self._push = None
        self.phase = self._phase_next

    def signal_values(self):
        t = self.tile
        # the row being received and the next output row, within their frames (one past the
        # last row once the stream is through)
        f_in, r_in = frame_row(self.received // self.in_width, self.in_rows, self.frames)
        f_out, r_out = frame_row(self.emitted // self.width, self.height, self.frames)
        y_out = t.y0 + r_out
        oldest = f_out * self.in_rows + max(0, y_out - self.half - t.in_y0)
        return {
            "status": STATUS_CODES.get(self.status, 0),
            "line_buffer.row_in": t.in_y0 + r_in,
            "line_buffer.fill": max(0, f_in * self.in_rows + r_in - oldest),
            "mac.phase": self.phase,
            "mac.row": y_out,
            "mac.col": t.x0 + self.emitted % self.width,
            "out.valid": int(self.pushed),
            "out.descriptor": self.last_descriptor,
        }


class Merge(Block):
    """Reassembles a camera's descriptor stream from its submodules' tiles, in raster order.

    Ports: ``inputs`` (one FIFO per tile), ``out``. Each cycle it moves the next descriptor in
    raster order (from the tile that owns it) to ``out``: pop and push in the same cycle, so one
    beat per cycle at most; starved on that tile's FIFO, blocked on ``out``. With row bands it
    drains band after band, so a later band's output waits in its FIFO meanwhile. Traced:
    ``status``, ``count`` (descriptors moved), ``out.valid``.
    """

    def __init__(self, plan: BlockPlan, domain: ClockDomain, shape: tuple[int, int], inputs,
                 tiles, out, frames: int = 1):
        super().__init__(plan.name, domain)
        self.height, self.width = shape
        self.frames = frames
        self.inputs, self.tiles, self.out = inputs, tiles, out
        self.moved = 0
        self.pushed = False
        self._push = False

    def _owner(self, x: int, y: int) -> int:
        return next(i for i, t in enumerate(self.tiles) if t.owns(x, y))

    def evaluate(self, now_cycle: int) -> None:
        self._push = False
        n = self.height * self.width
        if self.moved >= self.frames * n:
            self.idle()
            return
        y, x = divmod(self.moved % n, self.width)
        src = self.inputs[self._owner(x, y)]
        if not src.can_pop():
            self.starved(src)
            return
        if not self.out.can_push():
            self.blocked(self.out)
            return
        self.out.push(src.pop())
        self._push = True
        self.busy()

    def commit(self) -> None:
        self.pushed = self._push
        if self._push:
            self.moved += 1
            self._push = False

    def signal_values(self):
        return {"status": STATUS_CODES.get(self.status, 0), "count": self.moved,
                "out.valid": int(self.pushed)}
